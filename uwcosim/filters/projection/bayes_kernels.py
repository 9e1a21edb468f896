"""Compiled form of PFM-PSI's Bayes update (two gridded states, a terrain-depth row: the TAN
model of seed 000): :class:`CompiledBayesUpdate`.

- :func:`bayes_terms`: the prior on the grid, the terrain depth ``h_d`` there and the terms of
  the log-likelihood with the representation-error inflation (one square root and one division
  per point); :func:`bayes_posterior`: the product ``p(z | x) p-(x)`` (eq. 46), its mass and
  its floored moments (eqs. 50-51); :func:`posterior_coefficients`: ``m = F m- / (E' m-)``
  (eqs. 45, 47) with its negative mass, normalized (eq. 48) when no repair follows;
- the fused steps of the common updates, Kalman update of the velocities included:
  :func:`bayes_step` (one terrain row: product, gate, refinement test, posterior series and
  ``(x, P)`` in one call after :func:`bayes_terms`), :func:`prior_step` (no grid row: the
  posterior is the prior) and :func:`posterior_step` (the posterior series of the general
  path). A case they do not cover (a failed gate, a refinement, a positivity repair, no
  posterior mass, another row) returns having written nothing, and the numpy form
  :class:`~uwcosim.filters.projection.bayes.BayesUpdate` runs it.

With ``student_t_nu`` the Gaussian exponent of :func:`bayes_terms` is made Student-t by
:func:`~uwcosim.filters.robust.student_t_exponent` (numpy), the rest is the same.
The same quantities as the numpy form to round-off (``tests/test_projection_kernels.py``).
Bundles (:mod:`uwcosim.core.jit`): a :class:`~uwcosim.filters.projection.series_kernels.Series`,
the :class:`~uwcosim.filters.projection.series_kernels.Tables`, the map's
:class:`~uwcosim.filters.grid.likelihood.TerrainMap`, the scratch :class:`Grids`, the
:class:`UpdateRule`, the :class:`~uwcosim.filters.grid.conditional_kernels.KalmanBlock` and its
:class:`~uwcosim.filters.grid.conditional_kernels.KalmanRows`.
Exponentials of whole grids stay in numpy (its SIMD ``exp`` is several times faster than a
compiled scalar loop).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from uwcosim.core.jit import jit, jit_fast
from uwcosim.core.reductions import (
    col_max,
    col_min_max,
    max1,
    max2,
    min1,
    neg_sum2,
    row_sum,
    sum2,
)
from uwcosim.filters.grid.conditional_kernels import assemble, kalman_step, state_size, store
from uwcosim.filters.grid.likelihood import terrain_depth
from uwcosim.filters.grid.moments import marginals2, moments2, moments2_cols
from uwcosim.filters.projection.bayes import BayesUpdate
from uwcosim.filters.projection.series import SeriesDensity, SpectralBasis
from uwcosim.filters.projection.series_kernels import (
    box,
    folded_tables,
    from_grid2,
    grid_axes,
    hermitian_normalize,
    to_grid2,
    to_grid2_into,
)
from uwcosim.filters.robust import student_t_exponent


class Grids(NamedTuple):
    """The ``M x M`` grids of a product: the prior's values, ``E`` (the log-likelihood's
    exponent ``W``, then ``exp(W)``) and ``S`` (the variance ``V``, then ``1 / sqrt(V)``)."""

    values: np.ndarray
    E: np.ndarray
    S: np.ndarray


class UpdateRule(NamedTuple):
    """The settings the fused update tests: ``refine`` (the posterior box's width ratio below
    which the product is redone), the box's ``k_sigma`` and ``min_halfwidth``, and the negative
    mass above which a positivity repair follows (``neg_limit``; infinite: never)."""

    refine: float
    k_sigma: float
    min_halfwidth: float
    neg_limit: float


@jit_fast
def bayes_terms(series, tables, terrain, z, var, inflation, grids, shift):
    """Prior values, terrain log-likelihood terms and the prior's negative mass of the
    :class:`~uwcosim.filters.projection.series_kernels.Series` ``series`` on its box (``M``
    points per dimension, the :class:`~uwcosim.filters.projection.series_kernels.Tables`
    ``tables``), for the measurement ``z`` of variance ``var`` of the terrain depth on the map
    ``terrain`` (a :class:`~uwcosim.filters.grid.likelihood.TerrainMap`).

    Writes the prior's grid ``values``, ``W`` and ``S`` (into ``V``) into the caller's
    ``M x M`` arrays ``grids = (values, W, V)`` (a :class:`Grids`) and
    returns ``(neg_prior, tmax, vmin)``, with the log-likelihood
    ``ll = W + tmax - log(V) / 2`` (``W <= 0``, still to be exponentiated), ``S = 1 / sqrt(V)``
    and ``vmin = min(V)``: ``V = var + sum_d (dh/dx_d)^2 r_d`` with ``r_d = (res_d / (2
    h_d))^2 / 12``, ``res_d = inflation L_d / (2K + 1)``, on twice the central differences
    (one-sided ones doubled) when ``inflation`` > 0, else ``V = var`` and ``ll = W + tmax``
    (:meth:`~uwcosim.filters.grid.likelihood.GridLikelihood.loglik`).
    ``W = -(S (h - z))^2 / 2``: one square root and one division per point serve both ``W``
    and the normalization of :func:`bayes_posterior`.
    Both in single precision (twice as fast as double), refined by two Newton steps to
    ``1 / sqrt(V)`` within 2 ulp (not always correctly rounded; IEEE operations in a fixed
    order, so deterministic) when all ``V`` lie in ``[1e-30, 1e30]`` (else in double
    precision): :func:`_inflated_terms`. Without ``shift``, ``W`` is left unshifted
    (``W = -(S (h - z))^2 / 2``, the Student-t likelihood's input:
    :func:`~uwcosim.filters.robust.student_t_exponent` shifts it).
    """
    m, lo, length = series
    values, W, V = grids
    _, Tx, _, _ = tables
    M = Tx.shape[1]
    K = (m.shape[0] - 1) // 2
    scale = 1.0 / math.sqrt(length[0] * length[1])
    cell = (length[0] / M) * (length[1] / M)
    to_grid2_into(m, tables, scale, values)  # the prior on the grid (eq. 24)
    neg = neg_sum2(values)
    xs, ys = grid_axes(lo, length, M)
    h = terrain_depth(xs, ys, terrain)  # h_d(x_n) (eq. 55)
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
    if shift:
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
def prior_values(m, tables, length):
    """Grid values of the prior series and their negative mass (no grid measurement rows)."""
    _, Tx, _, _ = tables
    M = Tx.shape[1]
    values = to_grid2(m, tables, 1.0 / math.sqrt(length[0] * length[1]))
    neg = neg_sum2(values)
    return values, -neg * (length[0] / M) * (length[1] / M)


@jit
def bayes_posterior(grids, vmin, lo, length):
    """``post = values E sqrt(vmin) S`` of ``grids = (values, E, S)`` (``E = exp(W - tmax)``,
    ``S = 1 / sqrt(V)`` of :func:`bayes_terms`, or ones with ``vmin = 1``) on the box
    ``(lo, length)``: the product of eq. 46, its mass and moments (eqs. 50-51).

    Returns ``(post, Z, mean, cov, status)``: status 0 ok, 1 no posterior mass, 2 clipped
    (a signed prior: the product of its clip was used, as in :meth:`BayesUpdate.product`), 3
    non-finite moments. Moments as :func:`~uwcosim.filters.projection.bayes.
    grid_posterior_moments` (variances floored at ``(L/M)^2/12``).
    """
    values, E, S = grids
    M = values.shape[0]
    post = np.empty((M, M))
    m0 = np.empty(M)
    m1 = np.zeros(M)
    svm = math.sqrt(vmin)
    for i in range(M):
        for j in range(M):
            p = values[i, j] * (E[i, j] * (svm * S[i, j]))  # p(z | x) p-(x)
            post[i, j] = p
            m1[j] += p
        m0[i] = row_sum(post, i, False)
    Z, mean, cov, status = _posterior_moments(post, m0, m1, lo, length)
    return post, Z, mean, cov, status


@jit
def _posterior_moments(post, m0, m1, lo, length):
    """Mass and moments of :func:`bayes_posterior` from the marginal sums ``m0`` (rows, in
    ``row_sum`` order) and ``m1`` (columns, added row after row) of ``post``; clips
    ``post`` in place when its mass is not positive. Returns ``(Z, mean, cov, status)``."""
    M = post.shape[0]
    cell = (length[0] / M) * (length[1] / M)
    Z = m0.sum() * cell
    status = 0
    xs, ys = grid_axes(lo, length, M)
    floor0 = (length[0] / M) ** 2 / 12.0
    floor1 = (length[1] / M) ** 2 / 12.0
    if math.isfinite(Z) and Z > 0.0:
        mean, cov = moments2_cols(post, m0, m1, xs, ys)
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
        mean, cov = moments2(post, xs, ys, False)
    mean, cov = _floor_moments(post, xs, ys, mean, cov, floor0, floor1)
    if not math.isfinite(mean.sum() + cov.sum()):
        status = 3
    return Z, mean, cov, status


@jit
def _floor_moments(post, xs, ys, mean, cov, floor0, floor1):
    """The checks of :func:`~uwcosim.filters.projection.bayes.grid_posterior_moments` on the
    signed moments ``(mean, cov)``: moments of the clip when they are not valid, variances
    floored."""
    c00, c11, c01 = cov[0, 0], cov[1, 1], cov[0, 1]
    ok = (math.isfinite(c00 + c11 + 2.0 * c01) and c00 > floor0 and c11 > floor1
          and c00 * c11 - c01 * c01 > 0.0)
    if not ok:
        mean, cov = moments2(post, xs, ys, True)
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


@jit_fast
def posterior_coefficients(post, Z, tables, length, neg_limit):
    """``m = <post, phi> / Z`` (eqs. 45, 47; ``Z`` the mass of ``post``), its grid values and
    negative mass.

    When the negative mass is at most ``neg_limit`` (no positivity repair follows), ``m`` is
    also made Hermitian and normalized (:func:`hermitian_normalize`); the returned mass is then
    that of the Hermitian series, else NaN."""
    M = post.shape[0]
    sv = math.sqrt(length[0] * length[1])
    cell = (length[0] / M) * (length[1] / M)
    m = from_grid2(post, tables, sv / M**2)  # F m- (eq. 45)
    m /= Z  # / E' m- (eq. 47)
    values = to_grid2(m, tables, 1.0 / sv)
    neg = -neg_sum2(values) * cell
    mass = np.nan
    if neg <= neg_limit:
        mass = hermitian_normalize(m, sv)
    return m, values, neg, mass


@jit
def posterior_step(post, tables, length, neg_limit, kal, mean, cov):
    """:func:`posterior_coefficients` of the grid posterior ``post`` and, when the series needs
    no repair, ``(x, P)`` assembled from the posterior moments ``(mean, cov)`` and the Kalman
    block ``kal``: ``(m, values, neg, mass, x, P, finite)``."""
    cell = (length[0] / post.shape[0]) * (length[1] / post.shape[1])
    m, values, neg, mass = posterior_coefficients(post, sum2(post, False) * cell, tables,
                                                  length, neg_limit)
    if math.isfinite(mass) and mass > 0.0:
        x, P, finite = assemble(kal, mean, cov)
    else:
        nx = state_size(kal)
        x, P, finite = np.zeros(nx), np.zeros((nx, nx)), False
    return m, values, neg, mass, x, P, finite


@jit
def bayes_step(grids, vmin, shift, thr, prior_box, rule, tables, kal, rows, z, active, mean,
               cov):
    """The common update with one terrain row, after :func:`bayes_terms` and the exponential:
    :func:`bayes_posterior` on the prior's box ``prior_box`` (a ``Box``), the log-likelihood
    ``log(Z) + shift``, the gate (``loglik >= thr``), the refinement test (the posterior box
    narrower than ``refine`` times the prior box on some axis) and :func:`posterior_step` in
    one call.

    First the Kalman update of the velocities (:func:`~uwcosim.filters.grid.conditional_kernels.
    kalman_step` with the rows ``rows`` of ``z`` when ``active``). Returns ``(code, loglik, m,
    neg, x, P, finite, phi, nis)``; ``code`` 0: done (``m`` Hermitian and normalized, no repair
    needed; the gridded block's moments written into ``mean``, ``cov`` and the velocities' mean
    and covariance into the block, in place: fewer arrays to return); 1: any other case (no
    posterior mass, non-finite moments, gate failed, refinement, positivity repair, failed
    Kalman update), which the caller runs on its general path: then nothing is written. The
    arithmetic is that of the separate kernels, in the same order."""
    refine, k_sigma, min_halfwidth, neg_limit = rule
    lo, length = prior_box
    km, kc, phi, nis, ok = kalman_step(kal, rows, z, active)
    no = np.zeros((1, 1), np.complex128)
    nx = state_size(kal)
    X, Pz = np.zeros(nx), np.zeros((nx, nx))
    if not ok:
        return 1, np.nan, no, np.nan, X, Pz, False, phi, nis
    post, Z, mean2, cov2, status = bayes_posterior(grids, vmin, lo, length)
    if status == 1 or status == 3:
        return 1, np.nan, no, np.nan, X, Pz, False, phi, nis
    loglik = math.log(Z) + shift
    if not loglik >= thr:  # the gate
        return 1, loglik, no, np.nan, X, Pz, False, phi, nis
    if refine < 1.0:
        _, len2 = box(mean2, cov2, k_sigma, min_halfwidth)  # eq. 33 at the posterior
        if len2[0] < refine * length[0] or len2[1] < refine * length[1]:
            return 1, loglik, no, np.nan, X, Pz, False, phi, nis
    m, _, neg, mass = posterior_coefficients(post, Z, tables, length, neg_limit)
    if not (math.isfinite(mass) and mass > 0.0):
        return 1, loglik, no, neg, X, Pz, False, phi, nis
    store(kal, km, kc)
    x, P, finite = assemble(kal, mean2, cov2)
    mean[:] = mean2
    cov[:, :] = cov2
    return 0, loglik, m, neg, x, P, finite, phi, nis


@jit
def prior_step(series, tables, neg_limit, kal, rows, z, active, mean, cov):
    """The update without a grid measurement row: the posterior is the prior.

    The prior's grid values and negative mass (:func:`prior_values`), their moments (those of
    :func:`bayes_posterior` with unit factors, bit for bit: the factors multiply by exactly 1)
    and ``(x, P)``, after the Kalman update of the velocities (``kalman_step``). The
    series is kept as it is: the general path re-projects the grid values
    onto the basis, which gives the (Hermitian, normalized) series back to round-off, and
    recomputes the same grid values. Returns ``(ok, neg, x, P, finite, phi, nis)`` and writes
    the moments and the Kalman state in place as :func:`bayes_step`; ``ok`` False (the caller
    runs its general path; nothing written) when the Kalman update fails, the values have no
    positive mass, their moments are not finite, or ``neg > neg_limit`` (a positivity repair
    follows)."""
    m, lo, length = series
    km, kc, phi, nis, ok = kalman_step(kal, rows, z, active)
    values, neg = prior_values(m, tables, length)
    m0, m1 = marginals2(values)
    _, mean2, cov2, status = _posterior_moments(values, m0, m1, lo, length)
    if not ok or status != 0 or not neg <= neg_limit:
        nx = state_size(kal)
        return False, neg, np.zeros(nx), np.zeros((nx, nx)), False, phi, nis
    store(kal, km, kc)
    x, P, finite = assemble(kal, mean2, cov2)
    mean[:] = mean2
    cov[:, :] = cov2
    return True, neg, x, P, finite, phi, nis


_NO_Z = np.zeros(0)  # the measurement vector of an update without measurements


class CompiledBayesUpdate(BayesUpdate):
    """:class:`~uwcosim.filters.projection.bayes.BayesUpdate` by the kernels above: the
    common updates fused (:meth:`fused`), the products of one terrain row or of no grid row
    and the posterior series compiled; the other cases (and the repairs) in the numpy form."""

    compiled = True

    def __init__(self, settings, part, likelihood, kalman, ops, R, M: int) -> None:
        """``M``: the quadrature grid's points per dimension (fixed for the filter)."""
        super().__init__(settings, part, likelihood, kalman, ops, R)
        s = settings
        self._var = [float(v) for v in np.diag(R)]
        # the kernels' constant arguments (jit: plain tuples)
        self._block, self._rows = tuple(kalman.block), tuple(kalman.measurement)
        self._tables = tuple(folded_tables(s.K, M))
        #: negative mass above which a positivity repair follows (the numpy form's)
        self._limit = s.neg_limit if s.positivity == "auto" else math.inf
        self._rule = (s.refine, s.k_sigma, s.min_halfwidth, self._limit)  # an UpdateRule
        self._grids = tuple(np.empty((M, M)) for _ in range(3))  # a Grids, reused
        # writable (a read-only array would be a second compiled specialization); the kernel
        # only reads it
        self._one = np.ones((M, M))
        self._terrain: dict[int, tuple] = {}  # per terrain row, see _terrain_args

    def update(self, density: SeriesDensity, x, z, rows_k, rows_g, diag: dict):
        done = self.fused(density, z, rows_k, rows_g, diag)
        if done is not None:
            return done
        return super().update(density, x, z, rows_k, rows_g, diag)

    def fused(self, density: SeriesDensity, z, rows_k, rows_g, diag: dict):
        """The common updates in one or two compiled calls, the Kalman update of the
        velocities included: no grid row (the posterior is the prior, :func:`prior_step`), or
        one terrain row whose posterior passes the gate and needs neither a finer box nor a
        positivity repair (:func:`bayes_step`). Returns ``None``, having changed nothing, in
        every other case: :meth:`update` then runs the numpy form, which computes the same
        quantities (to round-off) and handles the case."""
        kal = self.kalman
        active = bool(rows_k) and bool(kal.k)
        if active and rows_k != kal.rows:
            return None
        zz = _NO_Z if z is None else z
        basis = density.basis
        if not rows_g:
            ok, neg, x, P, finite, phi, nis = prior_step(
                (density.m, basis.lo, basis.length), self._tables, self._limit, self._block,
                self._rows, zz, active, density.mean, density.cov)
            if not ok:
                return None
            diag["neg_mass_prior"] = neg
        else:
            if len(rows_g) != 1:
                return None
            r = rows_g[0]
            targs = self._terrain.get(r) or self._terrain_args(r)
            if not targs:
                return None
            terrain, var, thr = targs
            grids = self._grids  # filled by bayes_terms, consumed by bayes_step
            inflation = self.settings.resolution_inflation
            nu = self.likelihood.nu
            neg_prior, tmax, vmin = bayes_terms((density.m, basis.lo, basis.length),
                                                self._tables, terrain, float(z[r]), var,
                                                inflation, grids, nu is None)
            if nu is not None:  # the Student-t likelihood (filters.robust)
                tmax = student_t_exponent(grids[1], nu)
            np.exp(grids[1], out=grids[1])  # E = exp(W)
            shift = tmax - 0.5 * math.log(vmin) if inflation else tmax
            code, loglik, m, neg, x, P, finite, phi, nis = bayes_step(
                grids, vmin, shift, thr, (basis.lo, basis.length), self._rule, self._tables,
                self._block, self._rows, zz, active, density.mean, density.cov)
            if code:
                return None
            density.m = m
            diag["neg_mass_prior"] = neg_prior
            diag["loglik"] = loglik
        if active:  # the Kalman block's mean and covariance were written in place
            kal.phi = phi
            diag["nis"] = nis
            diag["nis_dof"] = float(len(rows_k))
        return self.accept(density, diag, neg, None, None, x, P, finite)  # moments in place

    def _terrain_args(self, r: int) -> tuple:
        """The constant arguments of the fused update with the terrain row ``r`` (cached):
        ``(map, variance, gate threshold)``; ``()`` when ``r`` is not a terrain row (the
        numpy form handles it)."""
        tg = self.likelihood.terrain_rows.get(r)
        if tg is None:
            return ()
        thr = self.gate_threshold([r]) if self.settings.gate else -math.inf
        out = self._terrain[r] = (tuple(tg.map), self._var[r], thr)
        return out

    def accept(self, density: SeriesDensity, diag: dict, neg: float, mean, cov, x, P,
               finite: bool):
        """A compiled update's result: the gridded block's moments (``None``: the kernel wrote
        them into ``density``), the diagnostics (no positivity repair) and ``(x, P,
        finite)``."""
        diag["neg_mass"] = neg
        if self.settings.positivity == "auto":
            diag["positivity_applied"] = 0.0
        if mean is not None:
            density.mean, density.cov = mean, cov
        return x, P, finite

    def product(self, density: SeriesDensity, basis: SpectralBasis, z, rows_g, x, record: bool,
                diag: dict):
        if len(rows_g) == 1 and rows_g[0] in self.likelihood.terrain_rows:
            return self._terrain_product(density, basis, z, rows_g[0], record, diag)
        if not rows_g:  # no grid measurement: the prior's grid and moments
            values, neg = prior_values(density.m, self._tables, basis.length)
            if record:
                diag["neg_mass_prior"] = neg
            one = self._one
            post, _, mean, cov, status = bayes_posterior((values, one, one), 1.0, basis.lo,
                                                         basis.length)
            if status == 1:
                return values, None, None, False
            return post, mean, cov, status != 3
        return super().product(density, basis, z, rows_g, x, record, diag)

    def _terrain_product(self, density: SeriesDensity, basis: SpectralBasis, z, r: int,
                         record: bool, diag: dict):
        """:meth:`product` for one terrain row (compiled)."""
        tg = self.likelihood.terrain_rows[r]
        M = basis.M
        grids = tuple(np.empty((M, M)) for _ in range(3))  # a Grids
        inflation = self.settings.resolution_inflation
        nu = self.likelihood.nu
        neg, tmax, vmin = bayes_terms((density.m, basis.lo, basis.length), self._tables,
                                      tuple(tg.map), float(z[r]), self._var[r], inflation,
                                      grids, nu is None)
        if record:
            diag["neg_mass_prior"] = neg
        if nu is not None:  # the Student-t likelihood (filters.robust)
            tmax = student_t_exponent(grids[1], nu)
        np.exp(grids[1], out=grids[1])
        post, Z, mean, cov, status = bayes_posterior(grids, vmin, basis.lo, basis.length)
        if status == 1:
            return grids[0], None, None, False
        # ll = W + tmax - log(V) / 2; post used exp(ll - tmax + log(vmin) / 2)
        shift = tmax - 0.5 * math.log(vmin) if inflation else tmax
        diag["loglik"] = math.log(Z) + shift
        return post, mean, cov, status != 3

    def posterior(self, density: SeriesDensity, post, mean, cov, diag: dict):
        basis = density.basis
        density.m, values, neg, mass, x, P, finite = posterior_step(
            post, self._tables, basis.length, self._limit, self._block, mean, cov)
        if math.isfinite(mass) and mass > 0:  # no repair: normalized by the kernel
            return self.accept(density, diag, neg, mean, cov, x, P, finite)
        self.repair(density, values, neg, mean, cov, diag)
        return None
