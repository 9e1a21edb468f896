"""Compiled (Numba) kernels of the projection (``pfm_psi``) and point-mass filters' hot paths.

At 21 x 21 modes or a 101 x 101 grid the filters' arithmetic is small; in numpy the time per
step is the overhead of a few hundred small calls. These kernels fuse the steps of the common
case (two gridded states, a terrain-depth measurement, a drift independent of the position:
the TAN model of seed 000) into a handful of compiled calls:

- :func:`terrain_depth`: the bathymetry B-spline on a tensor grid (separable, 4 + 4 taps);
- :func:`to_grid2` / :func:`from_grid2`: the series <-> grid quadratures of
  :mod:`uwcosim.filters.projection_ops` with the Hermitian symmetry folded (half the products),
  as two BLAS matrix products each;
- :func:`bayes_terms` / :func:`bayes_posterior` / :func:`posterior_coefficients`: the Bayes
  product, its moments and the re-projection of ``ProjectionFilter.update``;
- :func:`shift_decay`: the prediction (exact re-projection and Gaussian decay) of ``predict``;
- :func:`spline_shift_2d`: the cubic B-spline evaluation of the point-mass prediction;
- :func:`kalman_increment` / :func:`kalman_update` / :func:`assemble`: the conditional Kalman
  filter of the velocities and the assembly of ``(x, P)``.

Every kernel computes what the numpy code computes, in another summation order: results agree
to round-off (``tests/test_projection_kernels.py`` runs both paths). Exponentials of whole
grids stay in numpy (its SIMD ``exp`` is several times faster than a compiled scalar loop).

Numba is optional: without it (or with ``UWCOSIM_NUMBA=0`` in the environment) :data:`ENABLED`
is False and the filters run their numpy code. Numba is imported at the first kernel call, not
at import (about 0.5 s that scenarios without these filters do not pay). Compiled kernels are
cached on disk (``cache=True``), so campaign worker processes load them instead of compiling.
"""

from __future__ import annotations

import functools
import importlib.util
import math
import os

import numpy as np

ENABLED = (importlib.util.find_spec("numba") is not None
           and os.environ.get("UWCOSIM_NUMBA", "1") != "0")

TWO_PI = 2.0 * np.pi

# Numba is imported (about 0.5 s) and the kernels are bound to their compiled versions at the
# first call of any kernel, not at import: scenarios without these filters do not pay for it.
_PLAIN: dict[str, tuple] = {}  # name -> (python function, fastmath flags)


def _compile_all() -> None:
    import numba

    g = globals()
    for name, (fn, fastmath) in _PLAIN.items():
        g[name] = numba.njit(cache=True, nogil=True, error_model="numpy",
                             fastmath=fastmath)(fn)
    _PLAIN.clear()


def _register(fn, fastmath):
    _PLAIN[fn.__name__] = (fn, fastmath)

    @functools.wraps(fn)
    def first_call(*args):
        if _PLAIN:
            _compile_all()
        return globals()[fn.__name__](*args)

    return first_call


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a KeyboardInterrupt that a compiled kernel wrapped: Ctrl-C landing in
    the Python code Numba runs while it returns arrays surfaces as a ``SystemError`` caused by
    the ``KeyboardInterrupt`` (callers re-raise it as the interrupt it is)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _jit_fast(fn):
    """Full fast-math (no NaN/inf assumed) for kernels that test nothing for finiteness: their
    max/min reductions vectorize; a NaN input still reaches the callers' checks downstream."""
    return _register(fn, True)


def _jit(fn):
    """Reassociation and contraction (sums vectorize); NaN and inf keep their IEEE meaning
    (no 'nnan'/'ninf'): these kernels test finiteness."""
    return _register(fn, {"reassoc", "nsz", "arcp", "contract"})


# ---------------------------------------------------------------------------------------------
# tables (computed once per (K, M))

_TABLES: dict = {}


def tables(K: int, M: int):
    """Trigonometric tables of the folded transforms for ``q = -K..K`` on ``M`` points.

    Returns ``(Tq, Tx, Tg, Tm)``: ``Tq = [[C, S], [-S, C]]`` with ``C[q, n] = cos(2 pi q n / M)``
    (``(2(2K+1), 2M)``, for ``[m_r | m_i] @ Tq``); ``Tx = [w C0' | -w S0']`` (``(M, 2(K+1))``,
    ``q = 0..K``, ``w = 1, 2, 2, ...``); ``Tg = [C' | S']`` (``(M, 2(2K+1))``); ``Tm = [C0; S0]``
    (``(2(K+1), M)``).
    """
    key = (K, M)
    out = _TABLES.get(key)
    if out is None:
        n = np.arange(M)
        q = np.arange(-K, K + 1)
        ang = TWO_PI * np.outer(q, n) / M
        C, S = np.cos(ang), np.sin(ang)
        Tq = np.ascontiguousarray(np.block([[C, S], [-S, C]]))
        q0 = np.arange(K + 1)
        ang0 = TWO_PI * np.outer(q0, n) / M
        C0, S0 = np.cos(ang0), np.sin(ang0)
        w = np.where(q0 == 0, 1.0, 2.0)[:, None]
        Tx = np.ascontiguousarray(np.hstack([(w * C0).T, -(w * S0).T]))
        Tg = np.ascontiguousarray(np.hstack([C.T, S.T]))
        Tm = np.ascontiguousarray(np.vstack([C0, S0]))
        out = _TABLES[key] = (Tq, Tx, Tg, Tm)
    return out


# ---------------------------------------------------------------------------------------------
# terrain


@_jit
def _spline_weights(s, n):
    """Cell index and the 4 cubic B-spline weights at positions ``s`` (clamped as the map)."""
    N = s.size
    idx = np.empty(N, np.int64)
    w = np.empty((N, 4))
    for a in range(N):
        v = min(max(s[a], 0.0), n - 1.0)
        i = min(int(v), n - 2)
        f = v - i
        f2 = f * f
        f3 = f2 * f
        idx[a] = i
        w[a, 0] = (1.0 - 3.0 * f + 3.0 * f2 - f3) / 6.0
        w[a, 1] = (4.0 - 6.0 * f2 + 3.0 * f3) / 6.0
        w[a, 2] = (1.0 + 3.0 * f + 3.0 * f2 - 3.0 * f3) / 6.0
        w[a, 3] = f3 / 6.0
    return idx, w


@_jit
def terrain_depth(xs, ys, C, x0, y0, dx, dy, nx, ny, pad):
    """``h[i, j] = h_d(xs[i], ys[j])``: the map's cubic B-spline (coefficients ``C[y, x]``,
    ``pad`` padding nodes) on a tensor grid, as :meth:`TerrainGrid.depth`: ``Wx C' Wy'`` with
    banded weight matrices over the support (two BLAS products)."""
    iu, wu = _spline_weights((xs - x0) / dx, nx)
    iv, wv = _spline_weights((ys - y0) / dy, ny)
    c0 = iu.min() - 1 + pad
    c1 = iu.max() + 3 + pad
    r0 = iv.min() - 1 + pad
    r1 = iv.max() + 3 + pad
    Wx = np.zeros((xs.size, c1 - c0))
    Wy = np.zeros((ys.size, r1 - r0))
    for i in range(xs.size):
        for a in range(4):
            Wx[i, iu[i] + pad - 1 - c0 + a] = wu[i, a]
    for j in range(ys.size):
        for a in range(4):
            Wy[j, iv[j] + pad - 1 - r0 + a] = wv[j, a]
    Csub = np.ascontiguousarray(C[r0:r1, c0:c1])  # (rows y, cols x)
    G = Wx @ np.ascontiguousarray(Csub.T)  # (len xs, rows)
    return G @ np.ascontiguousarray(Wy.T)


# ---------------------------------------------------------------------------------------------
# series <-> grid (two gridded states)


@_jit
def to_grid2(m, Tq, Tx, scale):
    """Real values on the ``M x M`` grid of the Hermitian series ``m`` (``(2K+1, 2K+1)``)."""
    K = (m.shape[0] - 1) // 2
    n = m.shape[1]
    half = np.empty((K + 1, 2 * n))
    for j in range(K + 1):
        for q in range(n):
            v = m[K + j, q]
            half[j, q] = v.real
            half[j, n + q] = v.imag
    A = half @ Tq  # [A_r | A_i], (K+1, 2M)
    M = Tx.shape[0]
    B = np.empty((2 * (K + 1), M))
    B[:K + 1] = A[:, :M]
    B[K + 1:] = A[:, M:]
    out = Tx @ B
    out *= scale
    return out


@_jit
def from_grid2(g, Tg, Tm, scale):
    """Coefficients ``<g, phi_q>`` (FFT quadrature) of real grid values ``g`` (``M x M``)."""
    n = Tg.shape[1] // 2
    K = (n - 1) // 2
    B = g @ Tg  # [B_c | B_s]: B_c = g C', B_s = g S'
    P = Tm @ B  # [[C0 B_c, C0 B_s], [S0 B_c, S0 B_s]]
    m = np.empty((n, n), np.complex128)
    for j in range(K + 1):
        for q in range(n):
            re = P[j, q] - P[K + 1 + j, n + q]
            im = -P[j, n + q] - P[K + 1 + j, q]
            m[K + j, q] = complex(re * scale, im * scale)
    for j in range(1, K + 1):
        for q in range(n):
            m[K - j, q] = m[K + j, n - 1 - q].conjugate()
    return m


# ---------------------------------------------------------------------------------------------
# PFM-PSI update


@_jit
def grid_axes(lo, length, M):
    """``SpectralBasis.axes()``: ``lo + L n / M``, ``n = 0..M-1``, per dimension."""
    xs = np.empty(M)
    ys = np.empty(M)
    for i in range(M):
        xs[i] = lo[0] + length[0] * i / M
        ys[i] = lo[1] + length[1] * i / M
    return xs, ys


@_jit_fast
def bayes_terms(m, Tq, Tx, lo, length, C, tpar, ipar, z, var, inflation):
    """Prior values, terrain log-likelihood terms and the prior's negative mass on the box
    ``(lo, length)`` (``M = Tx.shape[0]`` points per dimension).

    ``tpar = (x0, y0, dx, dy)``, ``ipar = (nx, ny, pad)`` describe the map. Returns
    ``(values, W, V, neg_prior, tmax, vmin)`` with the log-likelihood
    ``ll = W + tmax - log(V) / 2`` (``W <= 0``, still to be exponentiated): ``V = var +
    sum_d (dh/dx_d)^2 r_d`` with ``r_d = (res_d / (2 h_d))^2 / 12``, ``res_d = inflation L_d /
    (2K + 1)``, on twice the central differences (one-sided ones doubled) when ``inflation``
    > 0, else ``V = var`` and ``ll = W + tmax`` (:meth:`GridLikelihood._terrain_loglik`).
    """
    M = Tx.shape[0]
    K = (m.shape[0] - 1) // 2
    scale = 1.0 / math.sqrt(length[0] * length[1])
    cell = (length[0] / M) * (length[1] / M)
    values = to_grid2(m, Tq, Tx, scale)
    neg = 0.0
    for i in range(M):
        for j in range(M):
            neg += min(values[i, j], 0.0)
    xs, ys = grid_axes(lo, length, M)
    h = terrain_depth(xs, ys, C, tpar[0], tpar[1], tpar[2], tpar[3], ipar[0], ipar[1],
                      ipar[2])
    W = np.empty((M, M))
    V = np.empty((M, M))
    inflate = inflation != 0.0
    if inflate:  # twice the central differences (one-sided ones doubled)
        rx = (length[0] / (2 * K + 1) * inflation / (2.0 * length[0] / M)) ** 2 / 12.0
        ry = (length[1] / (2 * K + 1) * inflation / (2.0 * length[1] / M)) ** 2 / 12.0
        for i in range(M):
            i0, i1 = max(i - 1, 0), min(i + 1, M - 1)
            f = 1.0 if (i1 - i0) == 2 else 2.0
            for j in range(M):
                g = f * (h[i1, j] - h[i0, j])
                V[i, j] = g * g * rx + var
            for j in range(1, M - 1):
                g = h[i, j + 1] - h[i, j - 1]
                V[i, j] += g * g * ry
            g = 2.0 * (h[i, 1] - h[i, 0])
            V[i, 0] += g * g * ry
            g = 2.0 * (h[i, M - 1] - h[i, M - 2])
            V[i, M - 1] += g * g * ry
    else:
        V[:] = var
    tmax = -np.inf
    vmin = np.inf
    for i in range(M):
        for j in range(M):
            e = h[i, j] - z
            t = -0.5 * (e * e) / V[i, j]
            W[i, j] = t
            tmax = max(tmax, t)
            vmin = min(vmin, V[i, j])
    W -= tmax
    return values, W, V, -neg * cell, tmax, vmin


@_jit_fast
def prior_values(m, Tq, Tx, length):
    """Grid values of the prior series and their negative mass (no grid measurement rows)."""
    M = Tx.shape[0]
    values = to_grid2(m, Tq, Tx, 1.0 / math.sqrt(length[0] * length[1]))
    neg = 0.0
    for i in range(M):
        for j in range(M):
            neg += min(values[i, j], 0.0)
    return values, -neg * (length[0] / M) * (length[1] / M)


@_jit
def moments2(post, xs, ys):
    """Mean and covariance of the weights ``post`` on the grid ``xs x ys``."""
    return _moments2(post, xs, ys, False)


@_jit
def _moments2(post, xs, ys, clip):
    """Mean and covariance of (signed, or clipped) weights on the tensor grid (eqs. 50-51)."""
    Mx, My = post.shape
    m0 = np.zeros(Mx)
    m1 = np.zeros(My)
    for i in range(Mx):
        for j in range(My):
            v = post[i, j]
            if clip and v < 0.0:
                v = 0.0
            m0[i] += v
            m1[j] += v
    total = m0.sum()
    mx = (m0 @ xs) / total
    my = (m1 @ ys) / total
    d0 = xs - mx
    d1 = ys - my
    c01 = 0.0
    for i in range(Mx):
        acc = 0.0
        for j in range(My):
            v = post[i, j]
            if clip and v < 0.0:
                v = 0.0
            acc += v * d1[j]
        c01 += d0[i] * acc
    c01 /= total
    mean = np.array([mx, my])
    cov = np.array([[(m0 @ (d0 * d0)) / total, c01], [c01, (m1 @ (d1 * d1)) / total]])
    return mean, cov


@_jit
def _floor_moments(post, xs, ys, mean, cov, floor0, floor1):
    """The checks of :meth:`ProjectionFilter._grid_moments` on the signed moments ``(mean,
    cov)``: moments of the clip when they are not valid, variances floored."""
    c00, c11, c01 = cov[0, 0], cov[1, 1], cov[0, 1]
    ok = (math.isfinite(c00 + c11 + 2.0 * c01) and c00 > floor0 and c11 > floor1
          and c00 * c11 - c01 * c01 > 0.0)
    if not ok:
        mean, cov = _moments2(post, xs, ys, True)
    v0, v1 = cov[0, 0], cov[1, 1]
    if v0 >= floor0 and v1 >= floor1:
        return mean, cov
    d0 = math.sqrt(max(v0, floor0) / max(v0, 1e-300))
    d1 = math.sqrt(max(v1, floor1) / max(v1, 1e-300))
    cov[0, 0] *= d0 * d0
    cov[1, 1] *= d1 * d1
    cov[0, 1] *= d0 * d1
    cov[1, 0] *= d0 * d1
    return mean, cov


@_jit
def grid_moments2(post, xs, ys, floor0, floor1):
    """:meth:`ProjectionFilter._grid_moments` for two gridded states."""
    mean, cov = _moments2(post, xs, ys, False)
    return _floor_moments(post, xs, ys, mean, cov, floor0, floor1)


@_jit
def _moments2_marginals(post, m0, m1, xs, ys):
    """:func:`_moments2` (signed weights) from the marginals ``m0``, ``m1`` already summed."""
    M0, M1 = post.shape
    total = m0.sum()
    mx = (m0 @ xs) / total
    my = (m1 @ ys) / total
    d0 = xs - mx
    d1 = ys - my
    c01 = 0.0
    for i in range(M0):
        acc = 0.0
        for j in range(M1):
            acc += post[i, j] * d1[j]
        c01 += d0[i] * acc
    c01 /= total
    mean = np.array([mx, my])
    cov = np.array([[(m0 @ (d0 * d0)) / total, c01], [c01, (m1 @ (d1 * d1)) / total]])
    return mean, cov


@_jit
def bayes_posterior(values, E, V, vmin, lo, length):
    """``post = values E sqrt(vmin / V)`` (``E = exp(W - tmax)``), its mass and moments.

    Returns ``(post, Z, mean, cov, status)``: status 0 ok, 1 no posterior mass, 2 clipped
    (a signed prior: the product of its clip was used, as in ``ProjectionFilter._bayes``), 3
    non-finite moments. Moments as :meth:`ProjectionFilter._grid_moments` (variances floored
    at ``(L/M)^2/12``).
    """
    M = values.shape[0]
    cell = (length[0] / M) * (length[1] / M)
    post = np.empty((M, M))
    m0 = np.zeros(M)
    m1 = np.zeros(M)
    for i in range(M):
        acc = 0.0
        for j in range(M):
            p = values[i, j] * (E[i, j] * math.sqrt(vmin / V[i, j]))
            post[i, j] = p
            acc += p
            m1[j] += p
        m0[i] = acc
    Z = m0.sum() * cell
    status = 0
    xs, ys = grid_axes(lo, length, M)
    floor0 = (length[0] / M) ** 2 / 12.0
    floor1 = (length[1] / M) ** 2 / 12.0
    if math.isfinite(Z) and Z > 0.0:
        mean, cov = _moments2_marginals(post, m0, m1, xs, ys)
    else:
        s = 0.0
        for i in range(M):
            for j in range(M):
                post[i, j] = max(post[i, j], 0.0)
                s += post[i, j]
        Z = s * cell
        status = 2
        if not (math.isfinite(Z) and Z > 0.0):
            return post, Z, np.zeros(2), np.zeros((2, 2)), 1
        mean, cov = _moments2(post, xs, ys, False)
    mean, cov = _floor_moments(post, xs, ys, mean, cov, floor0, floor1)
    if not math.isfinite(mean.sum() + cov.sum()):
        status = 3
    return post, Z, mean, cov, status


@_jit_fast
def posterior_coefficients(post, Tg, Tm, Tq, Tx, length, neg_limit):
    """``m = <post, phi> / mass(post)`` (eqs. 45, 47), its grid values and negative mass.

    When the negative mass is at most ``neg_limit`` (no positivity repair follows), ``m`` is
    also made Hermitian and normalized (:func:`hermitian_normalize`); the returned mass is then
    that of the Hermitian series, else NaN."""
    M = post.shape[0]
    sv = math.sqrt(length[0] * length[1])
    cell = (length[0] / M) * (length[1] / M)
    m = from_grid2(post, Tg, Tm, sv / M**2)
    m /= post.sum() * cell
    values = to_grid2(m, Tq, Tx, 1.0 / sv)
    neg = 0.0
    for i in range(M):
        for j in range(M):
            neg += min(values[i, j], 0.0)
    neg = -neg * cell
    mass = np.nan
    if neg <= neg_limit:
        mass = hermitian_normalize(m, sv)
    return m, values, neg, mass


@_jit
def hermitian_normalize(m, sqrt_volume):
    """``m = (m + conj(m_-q)) / 2`` in place; divide by the mass when it is finite and > 0.

    Returns the mass (``ProjectionFilter._normalize``)."""
    n0, n1 = m.shape
    src = m.copy()
    for i in range(n0):
        for j in range(n1):
            m[i, j] = 0.5 * (src[i, j] + src[n0 - 1 - i, n1 - 1 - j].conjugate())
    c = m[(n0 - 1) // 2, (n1 - 1) // 2]
    mass = sqrt_volume * c.real
    if math.isfinite(mass) and mass > 0.0:
        m /= mass
    return mass


@_jit
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


# ---------------------------------------------------------------------------------------------
# PFM-PSI prediction


@_jit
def _transfer(K, lo, length, lo2, length2):
    """:func:`projection_ops.transfer_matrix` (one dimension), with the phases and the sine of
    the difference ``sin(x_i - y_j)`` separated into per-index factors."""
    n = 2 * K + 1
    a = max(lo, lo2)
    w = min(lo + length, lo2 + length2) - a
    T = np.zeros((n, n), np.complex128)
    if w <= 0.0:
        return T
    c = w / math.sqrt(length * length2)
    left = np.empty(n, np.complex128)
    right = np.empty(n, np.complex128)
    om = np.empty(n)
    om2 = np.empty(n)
    sa = np.empty(n)
    ca = np.empty(n)
    sb = np.empty(n)
    cb = np.empty(n)
    for i in range(n):
        om2[i] = TWO_PI * (i - K) / length2
        om[i] = TWO_PI * (i - K) / length
        ph = -om2[i] * (a - lo2 + 0.5 * w)
        left[i] = complex(math.cos(ph), math.sin(ph))
        ph = om[i] * (a - lo + 0.5 * w)
        right[i] = complex(math.cos(ph), math.sin(ph))
        x = -0.5 * w * om2[i]
        y = -0.5 * w * om[i]
        sa[i], ca[i] = math.sin(x), math.cos(x)
        sb[i], cb[i] = math.sin(y), math.cos(y)
    for i in range(n):
        for j in range(n):
            delta = (om2[i] - om[j]) * (-0.5 * w)
            if delta == 0.0:
                s = 1.0
            else:
                s = (sa[i] * cb[j] - ca[i] * sb[j]) / delta
            T[i, j] = left[i] * right[j] * (s * c)
    return T


@_jit
def shift_decay(m, lo, length, lo2, length2, D, decay):
    """Re-projection of ``m`` from the box ``(lo, length)`` onto ``(lo2, length2)`` (exact
    integrals, :func:`projection_ops.reproject`), times ``exp(-w' D w / 2)`` on the new box
    when ``decay`` (:func:`projection_ops.diffusion_decay`)."""
    K = (m.shape[0] - 1) // 2
    n = 2 * K + 1
    T0 = _transfer(K, lo[0], length[0], lo2[0], length2[0])
    T1 = _transfer(K, lo[1], length[1], lo2[1], length2[1])
    # the result is Hermitian (out[-q] = conj(out[q]), as m and the transfers are): compute
    # the rows q_0 >= 0 and mirror them
    half = np.ascontiguousarray(T0[K:]) @ m @ np.ascontiguousarray(T1.T)
    out = np.empty((n, n), np.complex128)
    for i in range(K + 1):
        a = TWO_PI * i / length2[0]
        for j in range(n):
            v = half[i, j]
            if decay:
                b = TWO_PI * (j - K) / length2[1]
                quad = (0.5 * D[0, 0]) * (a * a) + (0.5 * D[1, 1]) * (b * b) + (D[0, 1] * a) * b
                v *= math.exp(-quad)
            out[K + i, j] = v
            if i > 0:
                out[K - i, n - 1 - j] = v.conjugate()
    return out


@_jit
def predict_shift(m, lo, length, mean, cov, d, D, k_sigma, min_halfwidth):
    """``ProjectionFilter.predict`` for a drift independent of the gridded states.

    The box moves to ``box(mean + d, cov + D)``; the series is translated by ``d`` and re-projected
    there, then decays by ``exp(-w' D w / 2)``. Returns ``(m, lo, length, mean, cov, mass)``;
    when the mass is finite and positive, ``m`` is already made Hermitian and normalized.
    """
    mean2 = mean + d
    cov2 = cov + D
    lo2, len2 = box(mean2, cov2, k_sigma, min_halfwidth)
    out = shift_decay(m, lo + d, length, lo2, len2, D, True)
    K = (m.shape[0] - 1) // 2
    mass = math.sqrt(len2[0] * len2[1]) * out[K, K].real
    if math.isfinite(mass) and mass > 0.0:
        mass = hermitian_normalize(out, math.sqrt(len2[0] * len2[1]))
    return out, lo2, len2, mean2, _sym(cov2), mass


# ---------------------------------------------------------------------------------------------
# point mass


@_jit
def _spline_rows(coords, n, size):
    """Rows of the cubic B-spline evaluation matrix of ``point_mass._spline_matrix``: indices
    (wrapped into ``size``) and weights (zero outside ``[0, n - 1]``)."""
    N = coords.size
    idx = np.empty((N, 4), np.int64)
    w = np.empty((N, 4))
    for a in range(N):
        c = coords[a]
        inside = 0.0 <= c <= n - 1.0
        if not inside:
            c = 0.0
        i = int(math.floor(c))
        f = c - i
        f2 = f * f
        f3 = f2 * f
        s = 1.0 if inside else 0.0
        w[a, 0] = s * (1.0 - 3.0 * f + 3.0 * f2 - f3) / 6.0
        w[a, 1] = s * (4.0 - 6.0 * f2 + 3.0 * f3) / 6.0
        w[a, 2] = s * (1.0 + 3.0 * f + 3.0 * f2 - 3.0 * f3) / 6.0
        w[a, 3] = s * f3 / 6.0
        for t in range(4):
            idx[a, t] = (i - 1 + t) % size
    return idx, w


@_jit
def spline_shift_2d(X, coords0, coords1, n0, n1):
    """Cubic B-spline of the prefiltered periodic coefficients ``X`` at the fractional grid
    coordinates ``coords0 x coords1`` (zero outside the old ``n0 x n1`` grid), clipped at 0.

    Both passes combine whole contiguous rows (the second one on the transpose), so that the
    inner loops vectorize instead of gathering."""
    i0, w0 = _spline_rows(coords0, n0, X.shape[0])
    i1, w1 = _spline_rows(coords1, n1, X.shape[1])
    N0, N1, S1 = coords0.size, coords1.size, X.shape[1]
    rows = np.empty((N0, S1))
    for a in range(N0):
        r0, r1, r2, r3 = i0[a, 0], i0[a, 1], i0[a, 2], i0[a, 3]
        u0, u1, u2, u3 = w0[a, 0], w0[a, 1], w0[a, 2], w0[a, 3]
        for c in range(S1):
            rows[a, c] = u0 * X[r0, c] + u1 * X[r1, c] + u2 * X[r2, c] + u3 * X[r3, c]
    rowsT = np.ascontiguousarray(rows.T)  # (S1, N0)
    outT = np.empty((N1, N0))
    for b in range(N1):
        r0, r1, r2, r3 = i1[b, 0], i1[b, 1], i1[b, 2], i1[b, 3]
        u0, u1, u2, u3 = w1[b, 0], w1[b, 1], w1[b, 2], w1[b, 3]
        for a in range(N0):
            v = u0 * rowsT[r0, a] + u1 * rowsT[r1, a] + u2 * rowsT[r2, a] + u3 * rowsT[r3, a]
            outT[b, a] = max(v, 0.0)
    return np.ascontiguousarray(outT.T)


@_jit
def pm_grid_shift(values, ax0, ax1, mean, cov, d, D, span, unit0, unit1, buf):
    """First part of the point-mass prediction (drift independent of the grid).

    The new grid ``mean + d -+ span sigma`` (``sigma`` from ``cov + D``;
    ``PointMassFilter._grid``), the fractional coordinates on the old grid of its points
    pulled back by ``d``, and ``values`` copied into the top-left block of the zero-padded
    FFT buffer ``buf``. Returns
    ``(new0, new1, coords0, coords1, mean, cov)`` (the predicted moments: exact for a
    translation and a Gaussian convolution)."""
    mean2 = mean + d
    cov2 = cov + D
    out = []
    for k in range(2):
        sig = math.sqrt(max(cov2[k, k], 0.0))
        half = max(span * sig, 1e-9 * max(1.0, abs(mean2[k])))
        u = unit0 if k == 0 else unit1
        a = u * half
        a += mean2[k]
        out.append(a)
    new0, new1 = out[0], out[1]
    sp0 = ax0[1] - ax0[0]
    sp1 = ax1[1] - ax1[0]
    c0 = (new0 - d[0] - ax0[0]) / sp0
    c1 = (new1 - d[1] - ax1[0]) / sp1
    n0, n1 = values.shape
    for i in range(buf.shape[0]):
        for j in range(buf.shape[1]):
            buf[i, j] = values[i, j] if (i < n0 and j < n1) else 0.0
    return new0, new1, c0, c1, mean2, _sym(cov2)


@_jit
def pm_gauss_prefilter(X, L1, sp0, sp1, D, col, row):
    """``X *= exp(-w' D w / 2) * prefilter`` on a real-FFT spectrum (two dimensions, grid
    spacings ``sp0``, ``sp1``, padded length ``L1`` of the last axis): the diagonal factors
    per index, the cross term ``exp(-D01 a_i b_j) = q_i^j`` (``b_j = j b_1`` on the last,
    real-FFT axis) by powers."""
    N0, N1 = X.shape
    b1 = TWO_PI / L1 / sp1
    eb = np.empty(N1)
    for j in range(N1):
        b = j * b1
        eb[j] = math.exp(-0.5 * D[1, 1] * b * b) * row[0, j]
    for i in range(N0):
        k = i if i < (N0 + 1) // 2 else i - N0
        a = TWO_PI * k / N0 / sp0
        ea = math.exp(-0.5 * D[0, 0] * a * a) * col[i, 0]
        q = math.exp(-D[0, 1] * a * b1)
        p = 1.0
        for j in range(N1):
            X[i, j] *= ea * eb[j] * p
            p *= q


@_jit
def pm_finish(X, coords0, coords1, n0, n1, cell):
    """Spline at the shifted points (clipped at 0) and normalization: ``(values, mass)``;
    ``values`` are divided by the mass when it is finite and positive."""
    out = spline_shift_2d(X, coords0, coords1, n0, n1)
    mass = out.sum() * cell
    if math.isfinite(mass) and mass > 0.0:
        out /= mass
    return out, mass


@_jit_fast
def terrain_exponent(xs, ys, C, tpar, ipar, z, var):
    """``ll - max(ll)`` of the terrain row, ``ll = -(h - z)^2 / (2 var)``, and ``max(ll)``
    (map as in :func:`bayes_terms`)."""
    h = terrain_depth(xs, ys, C, tpar[0], tpar[1], tpar[2], tpar[3], ipar[0], ipar[1],
                      ipar[2])
    tmax = -np.inf
    for i in range(h.shape[0]):
        for j in range(h.shape[1]):
            e = h[i, j] - z
            t = -0.5 * (e * e) / var
            h[i, j] = t
            tmax = max(tmax, t)
    h -= tmax
    return h, tmax


@_jit
def grid_product_moments(values, lik, cell, xs, ys):
    """``post = values * lik`` normalized, its mass ``Z`` and moments (point-mass update).

    When the mass is not finite and positive, ``post`` is ``values`` unchanged (the update is
    skipped, ``Z`` is returned for the caller to report)."""
    Mx, My = values.shape
    post = np.empty((Mx, My))
    m0 = np.zeros(Mx)
    m1 = np.zeros(My)
    for i in range(Mx):
        acc = 0.0
        for j in range(My):
            p = values[i, j] * lik[i, j]
            post[i, j] = p
            acc += p
            m1[j] += p
        m0[i] = acc
    Z = m0.sum() * cell
    if math.isfinite(Z) and Z > 0.0:
        post /= Z
        m0 /= Z
        m1 /= Z
        mean, cov = _moments2_marginals(post, m0, m1, xs, ys)
    else:
        post = values
        mean, cov = _moments2(post, xs, ys, False)
    return post, Z, mean, cov


@_jit
def available_bits(z, mask, use):
    """Bit ``r`` set when ``z[r]`` is finite and ``mask[r]`` and ``use[r]`` (``split_rows``)."""
    bits = 0
    for r in range(z.size):
        if mask[r] and use[r] and math.isfinite(z[r]):
            bits |= 1 << r
    return bits


# ---------------------------------------------------------------------------------------------
# conditional Kalman filter of the velocities and (x, P)


@_jit
def _chol_ok(S):
    """Whether the symmetric ``S`` (lower triangle) is positive definite (Cholesky)."""
    n = S.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            v = S[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / L[j, j]
    return True


@_jit
def _solve(A, B):
    """``A^-1 B`` by Gaussian elimination with partial pivoting (as LAPACK gesv); ``ok``."""
    n = A.shape[0]
    A = A.copy()
    X = B.copy()
    for c in range(n):
        p = c
        for r in range(c + 1, n):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if A[p, c] == 0.0:
            return X, False
        if p != c:
            for k in range(n):
                A[c, k], A[p, k] = A[p, k], A[c, k]
            for k in range(X.shape[1]):
                X[c, k], X[p, k] = X[p, k], X[c, k]
        for r in range(c + 1, n):
            f = A[r, c] / A[c, c]
            for k in range(c, n):
                A[r, k] -= f * A[c, k]
            for k in range(X.shape[1]):
                X[r, k] -= f * X[c, k]
    for c in range(n - 1, -1, -1):
        for k in range(X.shape[1]):
            v = X[c, k]
            for j in range(c + 1, n):
                v -= A[c, j] * X[j, k]
            X[c, k] = v / A[c, c]
    return X, True


@_jit
def _sym(A):
    n = A.shape[0]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.5 * (A[i, j] + A[j, i])
    return out


@_jit
def _mm(A, B):
    """``A @ B`` by loops (tiny matrices: cheaper than a BLAS call)."""
    n, m, p = A.shape[0], A.shape[1], B.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a = A[i, k]
            for j in range(p):
                out[i, j] += a * B[k, j]
    return out


@_jit
def _mv(A, x):
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        for k in range(A.shape[1]):
            out[i] += A[i, k] * x[k]
    return out


@_jit
def kalman_increment(x, fx, F, Q, p, k, cov, phi, use_phi):
    """:meth:`ConditionalKalman.increment` after the model call: ``(d, D, Dk, mean, cov)``."""
    npp, nk = p.size, k.size
    d = np.empty(npp)
    D = np.empty((npp, npp))
    for a in range(npp):
        d[a] = fx[p[a]] - x[p[a]]
        for b in range(npp):
            D[a, b] = Q[p[a], p[b]]
    Dk = np.zeros((npp, npp))
    mean = np.empty(nk)
    new_cov = cov
    if nk:
        S = cov
        if use_phi:
            eye = np.eye(nk)
            X, ok = _solve(eye - phi, cov)
            if ok:
                S2 = _sym(X + X.T - cov)
                tr, trP = 0.0, 0.0
                for a in range(nk):
                    tr += S2[a, a]
                    trP += cov[a, a]
                if (math.isfinite(S2.sum()) and not tr > 1e6 * max(trP, 1e-300)
                        and _chol_ok(S2)):
                    S = S2
        Fpk = np.empty((npp, nk))
        Fkk = np.empty((nk, nk))
        Qkk = np.empty((nk, nk))
        for a in range(npp):
            for b in range(nk):
                Fpk[a, b] = F[p[a], k[b]]
        for a in range(nk):
            mean[a] = fx[k[a]]
            for b in range(nk):
                Fkk[a, b] = F[k[a], k[b]]
                Qkk[a, b] = Q[k[a], k[b]]
        Dk = _sym(_mm(_mm(Fpk, S), Fpk.T))
        new_cov = _sym(_mm(_mm(Fkk, cov), Fkk.T) + Qkk)
        D = D + Dk
    return d, _sym(D), Dk, mean, new_cov


@_jit
def kalman_update(mean, cov, H, R, c, y_meas, F):
    """Joseph-form update of the ``k`` block: ``(mean, cov, phi, nis, ok)``; ``ok`` False when
    ``S`` is not positive definite (the caller then runs the repairing numpy path)."""
    y = y_meas - (_mv(H, mean) + c)
    PHt = _mm(cov, H.T)
    S = _sym(_mm(H, PHt) + R)
    if not _chol_ok(S):
        return mean, cov, F, 0.0, False
    Sinv_y, _ = _solve(S, y.reshape(-1, 1))
    Kt, _ = _solve(S, PHt.T.copy())
    K = Kt.T.copy()
    nis = 0.0
    for a in range(y.size):
        nis += y[a] * Sinv_y[a, 0]
    new_mean = mean + _mv(K, y)
    IKH = np.eye(mean.size) - _mm(K, H)
    new_cov = _sym(_mm(_mm(IKH, cov), IKH.T) + _mm(_mm(K, R), K.T))
    return new_mean, new_cov, _mm(IKH, F), nis, True


@_jit
def assemble(nx, p, k, mean_p, cov_p, mean_k, cov_k):
    """``(x, P, finite)`` of a partitioned filter (:func:`assemble_estimate`)."""
    x = np.zeros(nx)
    P = np.zeros((nx, nx))
    for a in range(p.size):
        x[p[a]] = mean_p[a]
        for b in range(p.size):
            P[p[a], p[b]] = cov_p[a, b]
    for a in range(k.size):
        x[k[a]] = mean_k[a]
        for b in range(k.size):
            P[k[a], k[b]] = cov_k[a, b]
    finite = math.isfinite(x.sum() + P.sum())
    return x, _sym(P), finite


@_jit
def predict_step(x, fx, F, Q, p, k, kcov, phi, use_phi, m, lo, length, mean, cov, k_sigma,
                 min_halfwidth):
    """One ``ProjectionFilter.predict`` (drift independent of the gridded states) after the
    model call ``(fx, F, Q)``: :func:`kalman_increment`, :func:`predict_shift` and
    :func:`assemble` in one call. Returns ``(m, lo, length, mean, cov, mass, kmean, kcov, Fkk,
    x, P, finite)``."""
    d, D, _, kmean, kcov2 = kalman_increment(x, fx, F, Q, p, k, kcov, phi, use_phi)
    m2, lo2, len2, mean2, cov2, mass = predict_shift(m, lo, length, mean, cov, d, D, k_sigma,
                                                     min_halfwidth)
    Fkk = np.empty((k.size, k.size))
    for a in range(k.size):
        for b in range(k.size):
            Fkk[a, b] = F[k[a], k[b]]
    x2, P2, finite = assemble(x.size, p, k, mean2, cov2, kmean, kcov2)
    return m2, lo2, len2, mean2, cov2, mass, kmean, kcov2, Fkk, x2, P2, finite


@_jit
def posterior_step(post, Tg, Tm, Tq, Tx, length, neg_limit, nx, p, k, mean, cov, kmean, kcov):
    """:func:`posterior_coefficients` and, when the series needs no repair, :func:`assemble`
    of ``(x, P)`` from the posterior moments: ``(m, values, neg, mass, x, P, finite)``."""
    m, values, neg, mass = posterior_coefficients(post, Tg, Tm, Tq, Tx, length, neg_limit)
    if math.isfinite(mass) and mass > 0.0:
        x, P, finite = assemble(nx, p, k, mean, cov, kmean, kcov)
    else:
        x, P, finite = np.zeros(nx), np.zeros((nx, nx)), False
    return m, values, neg, mass, x, P, finite
