"""Compiled (Numba) kernels of the projection (``pfm_psi``) and point-mass filters' hot paths.

At 21 x 21 modes or a 101 x 101 grid the filters' arithmetic is small; in numpy the time per
step is the overhead of a few hundred small calls. These kernels fuse the steps of the common
case (two gridded states, a terrain-depth measurement, a drift independent of the position:
the TAN model of seed 000) into a handful of compiled calls:

- :func:`terrain_depth`: the bathymetry B-spline on a tensor grid (separable, 4 + 4 taps; its
  weights :func:`uwcosim.core.bspline.cell_weights`);
- :func:`to_grid2` / :func:`from_grid2` (in :mod:`uwcosim.filters.grid.projection_grid`,
  re-exported here): the series <-> grid quadratures of
  :mod:`uwcosim.filters.projection_ops` with the Hermitian symmetry of the series and the
  ``n <-> M - n`` symmetry of the quadrature points folded (a quarter of the products of the
  plain transforms), as BLAS matrix products;
- :func:`bayes_terms` / :func:`bayes_posterior` / :func:`posterior_coefficients`: the Bayes
  product, its moments and the re-projection of ``ProjectionFilter.update``;
- in :mod:`uwcosim.filters.projection_kalman`: :func:`shift_decay`, the prediction (exact
  re-projection and Gaussian decay) of ``predict``, and the conditional Kalman filter of the
  velocities with the assembly of ``(x, P)`` (:func:`kalman_increment`, :func:`kalman_update`,
  :func:`assemble`, and the fused :func:`predict_step` / :func:`posterior_step`);
- in :mod:`uwcosim.filters.point_mass_kernels`: the point-mass prediction (spline shift,
  Gaussian and prefilter symbol) and Bayes product.

All are reachable from this module (the filters call ``projection_kernels.NAME``).

Every kernel computes what the numpy code computes, in another summation order: results agree
to round-off (``tests/test_projection_kernels.py`` runs both paths). The arithmetic is IEEE
(no fast-math) and every sum has its order written in the source (:func:`row_sum`): a kernel
compiled afresh and the same kernel loaded from Numba's cache give the same bits
(``tests/test_kernel_determinism.py``). Exponentials of whole
grids stay in numpy (its SIMD ``exp`` is several times faster than a compiled scalar loop).

Numba is optional: without it (or with ``UWCOSIM_NUMBA=0`` in the environment) :data:`ENABLED`
is False and the filters run their numpy code. Numba is imported at the first kernel call, not
at import (about 0.5 s that scenarios without these filters do not pay). Compiled kernels are
cached on disk (``cache=True``), so campaign worker processes load them instead of compiling.
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core import bspline
from uwcosim.core.jit import ENABLED, interrupted, jit, jit_fast
from uwcosim.core.reductions import col_max, col_min_max, max1, max2, min1, neg_sum2, row_sum
from uwcosim.filters.grid.grid_moments import (
    _floor_moments,
    _moments2,
    _moments2_cols,
    grid_moments2,
    moments2,
)
from uwcosim.filters.grid.projection_grid import (  # noqa: F401  (re-exported)
    TWO_PI,
    from_grid2,
    tables,
    to_grid2,
    to_grid2_into,
)

# ---------------------------------------------------------------------------------------------
# terrain


@jit
def terrain_depth(xs, ys, C, x0, y0, dx, dy, nx, ny, pad):
    """``h[i, j] = h_d(xs[i], ys[j])``: the map's cubic B-spline (coefficients ``C[y, x]``,
    ``pad`` padding nodes) on a tensor grid, as :meth:`TerrainGrid.depth`: first along ``y``
    at the map's columns of the support (``Csub' Wy'``, one BLAS product with the banded
    weight matrix), then the 4 taps along ``x`` per grid row (a loop that vectorizes)."""
    iu, wu = bspline.cell_weights((xs - x0) / dx, nx)
    iv, wv = bspline.cell_weights((ys - y0) / dy, ny)
    c0 = iu.min() - 1 + pad
    c1 = iu.max() + 3 + pad
    r0 = iv.min() - 1 + pad
    r1 = iv.max() + 3 + pad
    WyT = np.zeros((r1 - r0, ys.size))
    for j in range(ys.size):
        for a in range(4):
            WyT[iv[j] + pad - 1 - r0 + a, j] = wv[j, a]
    CsubT = np.ascontiguousarray(C[r0:r1, c0:c1].T)  # (cols x, rows y)
    Hy = CsubT @ WyT  # (cols x, len ys)
    h = np.empty((xs.size, ys.size))
    for i in range(xs.size):
        k = iu[i] + pad - 1 - c0
        w0, w1, w2, w3 = wu[i, 0], wu[i, 1], wu[i, 2], wu[i, 3]
        for j in range(ys.size):
            h[i, j] = ((w0 * Hy[k, j] + w1 * Hy[k + 1, j]) + w2 * Hy[k + 2, j]) + w3 * Hy[k + 3, j]
    return h


# ---------------------------------------------------------------------------------------------
# PFM-PSI update


@jit
def grid_axes(lo, length, M):
    """``SpectralBasis.axes()``: ``lo + L n / M``, ``n = 0..M-1``, per dimension."""
    xs = np.empty(M)
    ys = np.empty(M)
    for i in range(M):
        xs[i] = lo[0] + length[0] * i / M
        ys[i] = lo[1] + length[1] * i / M
    return xs, ys


@jit_fast
def bayes_terms(m, Tq, Tx, lo, length, C, tpar, ipar, z, var, inflation, values, W, V):
    """Prior values, terrain log-likelihood terms and the prior's negative mass on the box
    ``(lo, length)`` (``M = Tx.shape[1]`` points per dimension).

    ``tpar = (x0, y0, dx, dy)``, ``ipar = (nx, ny, pad)`` describe the map. Writes the
    prior's grid ``values``, ``W`` and ``S`` (into ``V``) into the caller's ``M x M`` arrays and
    returns ``(neg_prior, tmax, vmin)``, with the log-likelihood
    ``ll = W + tmax - log(V) / 2`` (``W <= 0``, still to be exponentiated), ``S = 1 / sqrt(V)``
    and ``vmin = min(V)``: ``V = var + sum_d (dh/dx_d)^2 r_d`` with ``r_d = (res_d / (2
    h_d))^2 / 12``, ``res_d = inflation L_d / (2K + 1)``, on twice the central differences
    (one-sided ones doubled) when ``inflation`` > 0, else ``V = var`` and ``ll = W + tmax``
    (:meth:`GridLikelihood._terrain_loglik`). ``W = -(S (h - z))^2 / 2``: one square root and
    one division per point serve both ``W`` and the normalization of :func:`bayes_posterior`.
    Both in single precision (twice as fast as double), refined by two Newton steps to
    ``1 / sqrt(V)`` within 2 ulp (not always correctly rounded; IEEE operations in a fixed
    order, so deterministic) when all ``V`` lie in ``[1e-30, 1e30]`` (else in double
    precision): :func:`_inflated_terms`.
    """
    M = Tx.shape[1]
    K = (m.shape[0] - 1) // 2
    scale = 1.0 / math.sqrt(length[0] * length[1])
    cell = (length[0] / M) * (length[1] / M)
    to_grid2_into(m, Tq, Tx, scale, values)
    neg = neg_sum2(values)
    xs, ys = grid_axes(lo, length, M)
    h = terrain_depth(xs, ys, C, tpar[0], tpar[1], tpar[2], tpar[3], ipar[0], ipar[1],
                      ipar[2])
    if inflation != 0.0:  # twice the central differences (one-sided ones doubled)
        rx = (length[0] / (2 * K + 1) * inflation / (2.0 * length[0] / M)) ** 2 / 12.0
        ry = (length[1] / (2 * K + 1) * inflation / (2.0 * length[1] / M)) ** 2 / 12.0
        tmax, vmin = _inflated_terms(h, z, var, rx, ry, W, V)
    else:
        vmin = var
        s = 1.0 / math.sqrt(var)
        for i in range(M):
            for j in range(M):
                e = (h[i, j] - z) * s
                W[i, j] = -0.5 * (e * e)
        V[:] = s
        tmax = max2(W)
    for i in range(M):
        for j in range(M):
            W[i, j] -= tmax
    return -neg * cell, tmax, vmin


@jit
def _inflated_terms(h, z, var, rx, ry, W, V):
    """:func:`bayes_terms`' ``V`` with resolution inflation, then ``S`` (into ``V``) and ``W``;
    returns ``(tmax, vmin)``. The extremes are kept per column (elementwise loops, which
    vectorize; exact in any order). ``S`` is computed in single precision and refined by two
    Newton steps when all ``V`` lie in ``[1e-30, 1e30]``, else as ``1 / sqrt(V)`` in double."""
    M = h.shape[0]
    vlo = np.full(M, np.inf)  # column minima and maxima of V, maxima of W
    vhi = np.full(M, -np.inf)
    whi = np.full(M, -np.inf)
    for i in range(M):
        i0, i1 = max(i - 1, 0), min(i + 1, M - 1)
        f = 1.0 if (i1 - i0) == 2 else 2.0
        for j in range(1, M - 1):
            g = f * (h[i1, j] - h[i0, j])
            q = h[i, j + 1] - h[i, j - 1]
            V[i, j] = (g * g * rx + var) + q * q * ry
        for j, j0, j1 in ((0, 0, 1), (M - 1, M - 2, M - 1)):  # one-sided, doubled
            g = f * (h[i1, j] - h[i0, j])
            q = 2.0 * (h[i, j1] - h[i, j0])
            V[i, j] = (g * g * rx + var) + q * q * ry
        col_min_max(vlo, vhi, V, i)
    vmin = min1(vlo)
    single = vmin >= 1e-30 and max1(vhi) <= 1e30
    for i in range(M):
        if single:
            _inv_sqrt_row_single(h, z, W, V, i)
        else:
            for j in range(M):
                s = 1.0 / math.sqrt(V[i, j])
                e = (h[i, j] - z) * s
                W[i, j] = -0.5 * (e * e)
                V[i, j] = s
        col_max(whi, W, i)
    return max1(whi), vmin


@jit
def _inv_sqrt_row_single(h, z, W, V, i):
    """Row ``i`` of :func:`_inflated_terms`: ``S = 1 / sqrt(V)`` in single precision refined by
    two Newton steps (into ``V``), ``W = -(S (h - z))^2 / 2``."""
    for j in range(V.shape[1]):
        v = V[i, j]
        s = np.float64(np.float32(1.0) / np.sqrt(np.float32(v)))
        s = s * (1.5 - (0.5 * v) * (s * s))  # Newton: 1e-7 -> 1e-14
        s = s * (1.5 - (0.5 * v) * (s * s))  # -> round-off
        e = (h[i, j] - z) * s
        W[i, j] = -0.5 * (e * e)
        V[i, j] = s  # V becomes S = 1 / sqrt(V)


@jit_fast
def prior_values(m, Tq, Tx, length):
    """Grid values of the prior series and their negative mass (no grid measurement rows)."""
    M = Tx.shape[1]
    values = to_grid2(m, Tq, Tx, 1.0 / math.sqrt(length[0] * length[1]))
    neg = neg_sum2(values)
    return values, -neg * (length[0] / M) * (length[1] / M)


@jit
def bayes_posterior(values, E, S, vmin, lo, length):
    """``post = values E sqrt(vmin) S`` (``E = exp(W - tmax)``, ``S = 1 / sqrt(V)`` of
    :func:`bayes_terms`, or ones with ``vmin = 1``), its mass and moments.

    Returns ``(post, Z, mean, cov, status)``: status 0 ok, 1 no posterior mass, 2 clipped
    (a signed prior: the product of its clip was used, as in ``ProjectionFilter._bayes``), 3
    non-finite moments. Moments as :meth:`ProjectionFilter._grid_moments` (variances floored
    at ``(L/M)^2/12``).
    """
    M = values.shape[0]
    post = np.empty((M, M))
    m0 = np.empty(M)
    m1 = np.zeros(M)
    svm = math.sqrt(vmin)
    for i in range(M):
        for j in range(M):
            p = values[i, j] * (E[i, j] * (svm * S[i, j]))
            post[i, j] = p
            m1[j] += p
        m0[i] = row_sum(post, i, False)
    Z, mean, cov, status = _posterior_moments(post, m0, m1, lo, length)
    return post, Z, mean, cov, status


@jit
def _posterior_moments(post, m0, m1, lo, length):
    """Mass and moments of :func:`bayes_posterior` from the marginal sums ``m0`` (rows, in
    :func:`row_sum` order) and ``m1`` (columns, added row after row) of ``post``; clips
    ``post`` in place when its mass is not positive. Returns ``(Z, mean, cov, status)``."""
    M = post.shape[0]
    cell = (length[0] / M) * (length[1] / M)
    Z = m0.sum() * cell
    status = 0
    xs, ys = grid_axes(lo, length, M)
    floor0 = (length[0] / M) ** 2 / 12.0
    floor1 = (length[1] / M) ** 2 / 12.0
    if math.isfinite(Z) and Z > 0.0:
        mean, cov = _moments2_cols(post, m0, m1, xs, ys)
    else:
        s = 0.0
        for i in range(M):
            for j in range(M):
                post[i, j] = max(post[i, j], 0.0)
                s += post[i, j]
        Z = s * cell
        status = 2
        if not (math.isfinite(Z) and Z > 0.0):
            return Z, np.zeros(2), np.zeros((2, 2)), 1
        mean, cov = _moments2(post, xs, ys, False)
    mean, cov = _floor_moments(post, xs, ys, mean, cov, floor0, floor1)
    if not math.isfinite(mean.sum() + cov.sum()):
        status = 3
    return Z, mean, cov, status


@jit_fast
def posterior_coefficients(post, Z, Tg, Tm, Tq, Tx, length, neg_limit):
    """``m = <post, phi> / Z`` (eqs. 45, 47; ``Z`` the mass of ``post``), its grid values and
    negative mass.

    When the negative mass is at most ``neg_limit`` (no positivity repair follows), ``m`` is
    also made Hermitian and normalized (:func:`hermitian_normalize`); the returned mass is then
    that of the Hermitian series, else NaN."""
    M = post.shape[0]
    sv = math.sqrt(length[0] * length[1])
    cell = (length[0] / M) * (length[1] / M)
    m = from_grid2(post, Tg, Tm, sv / M**2)
    m /= Z
    values = to_grid2(m, Tq, Tx, 1.0 / sv)
    neg = -neg_sum2(values) * cell
    mass = np.nan
    if neg <= neg_limit:
        mass = hermitian_normalize(m, sv)
    return m, values, neg, mass


@jit
def hermitian_normalize(m, sqrt_volume):
    """``m = (m + conj(m_-q)) / 2`` in place; divide by the mass when it is finite and > 0.

    Returns the mass (``ProjectionFilter._normalize``)."""
    n0, n1 = m.shape
    for f in range((n0 * n1 + 1) // 2):  # each entry and its mirror (the centre alone) once
        i, j = f // n1, f % n1
        a, b = m[i, j], m[n0 - 1 - i, n1 - 1 - j]
        m[i, j] = 0.5 * (a + b.conjugate())
        m[n0 - 1 - i, n1 - 1 - j] = 0.5 * (b + a.conjugate())
    c = m[(n0 - 1) // 2, (n1 - 1) // 2]
    mass = sqrt_volume * c.real
    if math.isfinite(mass) and mass > 0.0:
        m /= mass
    return mass


@jit
def _sym(A):
    n = A.shape[0]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.5 * (A[i, j] + A[j, i])
    return out


@jit
def box(mean, cov, k_sigma, min_halfwidth):
    """``ProjectionFilter._box``: ``(lo, length)`` of ``mean -+ max(k_sigma sigma, floor)``."""
    n = mean.size
    lo = np.empty(n)
    length = np.empty(n)
    for d in range(n):
        sig = math.sqrt(max(cov[d, d], 0.0))
        floor = max(min_halfwidth, 1e-9 * max(1.0, abs(mean[d])))
        half = max(k_sigma * sig, floor)
        lo[d] = mean[d] - half
        length[d] = 2.0 * half
    return lo, length


# the kernels of the other two modules, reachable from here (imported last: they use the above)
from uwcosim.filters.grid.point_mass_kernels import (  # noqa: E402
    grid_product_moments,
    pm_finish,
    pm_gauss_prefilter,
    pm_grid_shift,
    spline_shift_2d,
    terrain_exponent,
)
from uwcosim.filters.grid.projection_kalman import (  # noqa: E402
    assemble,
    available_bits,
    bayes_step,
    kalman_increment,
    kalman_update,
    posterior_step,
    predict_shift,
    predict_step,
    prior_step,
    shift_decay,
)

__all__ = [
    "ENABLED", "assemble", "available_bits", "bayes_posterior", "bayes_step", "bayes_terms",
    "box",
    "from_grid2", "grid_moments2", "grid_product_moments", "hermitian_normalize", "interrupted",
    "kalman_increment", "kalman_update", "moments2", "pm_finish", "pm_gauss_prefilter",
    "pm_grid_shift", "posterior_coefficients", "posterior_step", "predict_shift",
    "predict_step", "prior_step", "prior_values", "shift_decay", "spline_shift_2d", "tables",
    "terrain_depth",
    "terrain_exponent", "to_grid2", "to_grid2_into",
]
