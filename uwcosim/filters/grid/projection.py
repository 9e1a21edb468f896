"""PFM-PSI: the projection filter on a projection symmetric interval (seed 000, section 3).

The density of the gridded states ``p`` (all states of a low-dimensional model; the position
``(x, y)`` of the TAN model) is the truncated complex-exponential series of
:mod:`uwcosim.filters.grid.spectral` on the box ``E +- k_sigma * sigma`` (eq. 33). The other
states ``k`` (the DVL-measured velocities of the TAN model) are handled by a conditional Kalman
filter (:mod:`uwcosim.filters.grid.partition`). One step:

1. *Re-centring* (eq. 33): the box is centred on the predicted mean with half-width ``k_sigma``
   predicted standard deviations; the coefficients are re-projected exactly from the old box
   (the old series taken as zero outside it) by per-axis transfer matrices.
2. *Prediction* (eqs. 15, 23, 41-43): ``m- = exp(A dt) m`` with ``A`` the Galerkin matrix of the
   Fokker-Planck operator ``L* p = 1/2 sum d2(B p)/dx_r dx_s - sum d(f p)/dx_r``, built from the
   CasADi drift, its divergence and the diffusion ``B = g Q g'`` (and its derivatives) on the
   quadrature grid (Toeplitz in ``q - i``, one FFT per field); ``exp(A dt)`` by ``expm``
   (``expm_multiply`` above 1200 basis functions). The drift is tapered to zero on the outer 10 %
   of each side of the box (where the density is negligible): on the periodic box a drift that
   does not vanish jumps at the seam and gives ``A`` spurious growing modes.
   When neither ``f_p`` nor ``B`` depends on ``x_p`` (the TAN position block: its drift is the
   rotated velocity), ``A`` is diagonal: a phase shift (applied by translating the box, which is
   exact and cannot wrap around) and the decay ``exp(-w' D w / 2)``. ``D`` includes the velocity
   uncertainty (:class:`~uwcosim.filters.grid.conditional.ConditionalKalman`).
3. *Bayes update* (eqs. 45-48): ``m = F m- / (E' m-)``, computed as the FFT quadrature of the
   product of likelihood and prior on the grid (``F m-`` is exactly that projection, so ``F`` is
   never formed). When the posterior box (eq. 33 with the posterior moments) is narrower than
   ``refine`` times the prior box, the product is redone on the posterior box's finer grid.
4. *Moments* (eqs. 50-51): quadratures on the grid of the posterior product before truncation
   (eq. 50 with ``Psi = sqrt(L)/K IFFT(x_n)`` is that quadrature), variances floored at the grid
   resolution.
5. *Negative lobes*: the mass ``integral of max(-p, 0)`` of the truncated posterior is reported
   as ``neg_mass`` (and ``neg_mass_prior``). ``positivity="auto"`` (default) keeps the signed
   series as the paper does (the lobes carry the truncation error with nearly zero net mass and
   cancel in the moments) while ``neg_mass <= neg_limit``; above it the grid values are
   thresholded (``max(p - a, 0)``, ``a`` the deepest lobe), renormalized and re-projected
   (``positivity_applied`` = 1). ``"clip"`` (clip and renormalize) is available but unstable on
   rough terrain: the positive halves of the ripples stay, spread over the box, inflate the
   variance, hence the next box, hence the ripples. ``"threshold"`` always thresholds (stable,
   but it trims tails every step: overconfident); ``"jackson"`` damps the coefficients with the
   positive Jackson kernel (nonnegative by construction, but the blur of one resolution cell per
   step outgrows the information at ``K = 10``); ``"none"`` never corrects.
6. *Representation error*: a likelihood rougher than the basis can resolve is not sampled as if
   exact: the measurement variance is inflated by the variation of ``h`` within a resolution
   cell ``L / (2K + 1)`` (``resolution_inflation``, 1 = on; vanishes as the box shrinks).

Deviations from the paper (docs/projection_filter.md):

- frequencies ``q = -K..K`` (``2K+1`` functions per dimension) instead of ``q = 0..N-1``: the
  positive set cannot represent a real density nor the coupling ``q <-> q -+ k`` that an
  ``x``-dependent drift creates;
- eq. 33 is garbled in the extraction (``-E - 10C``): implemented as
  ``[E - k_sigma sigma, E + k_sigma sigma]`` per dimension with the predicted ``E``, ``sigma``;
  default ``k_sigma = 4`` instead of 10: with ``K = 10`` a box of 20 sigma resolves a Gaussian
  only to 1e-2 and the filter loses the track on rough terrain (see the docs for the numbers);
- re-projection uses exact integrals, inner products the FFT quadrature on ``M`` points
  (``grid_factor (2K+1)``) instead of ``K`` interval points.

Settings: ``K`` (highest harmonic per dimension, 10), ``k_sigma`` (4), ``states`` (gridded
states; default from the model structure), ``measurements``, ``grid_factor`` (2.5),
``positivity`` (``"auto"``), ``neg_limit`` (0.1), ``spectral_filter`` (0 = off, else the even
order of an exponential filter), ``long_run`` (True), ``min_halfwidth`` (0),
``resolution_inflation`` (1), ``refine`` (0.7; 1 = off), ``moment_match`` (True: after a
threshold the series gets the grid posterior's mean and covariance back), ``gate`` (5 sigma;
0 = off: an implausible measurement regrows the box, see :meth:`ProjectionFilter._regrow`).
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import numpy as np
from pydantic import Field, StrictBool, StrictFloat, StrictInt, StrictStr
from scipy.linalg import expm
from scipy.sparse.linalg import expm_multiply

from uwcosim.core.errors import FilterDivergence
from uwcosim.filters.base import Estimator, register
from uwcosim.filters.grid import projection_kernels as pk
from uwcosim.filters.grid import spectral as po
from uwcosim.filters.grid.conditional import (
    ConditionalKalman,
    assemble_estimate,
    begin_update,
    block_index,
)
from uwcosim.filters.grid.likelihood import GridLikelihood
from uwcosim.filters.grid.partition import Partition, symbolic
from uwcosim.filters.grid.projection_bayes import BayesProduct
from uwcosim.filters.numerics import symmetrize
from uwcosim.filters.settings import MEASUREMENTS, STATES, FilterSettings, Measurements

#: the treatments of negative lobes of the truncated series, as a setting
Positivity = Literal["auto", "none", "threshold", "clip", "product", "jackson"]
POSITIVITY = get_args(Positivity)
_NO_Z = np.zeros(0)  # the measurement vector of an update without measurements
DENSE_EXPM_MAX = 1200  # basis size up to which exp(A dt) is formed densely
@register("pfm_psi")
class ProjectionFilter(BayesProduct, Estimator):
    """PFM-PSI projection filter (complex-exponential Galerkin projection of the FPE)."""

    class Settings(FilterSettings):
        K: StrictInt = Field(10, ge=1, description="highest harmonic per dimension")
        k_sigma: StrictFloat = Field(4.0, gt=0, description="half-width of the box (eq. 33) in "
                                     "predicted standard deviations")
        states: list[StrictStr | StrictInt] | None = Field(None, description=STATES)
        measurements: Measurements = Field(None, description=MEASUREMENTS)
        grid_factor: StrictFloat = Field(2.5, ge=2, description="quadrature points per basis "
                                         "function and dimension")
        positivity: Positivity = Field(
            "auto", description="treatment of negative lobes of the truncated series")
        spectral_filter: StrictFloat = Field(0.0, ge=0, description="even order of an "
                                             "exponential filter (0 = off)")
        long_run: StrictBool = Field(True, description="conditional Kalman filter of the other "
                                     "states in its long-run form")
        min_halfwidth: StrictFloat = Field(0.0, ge=0, description="floor of the box half-width")
        resolution_inflation: StrictFloat = Field(
            1.0, ge=0, description="inflate R by the variation of h within a resolution cell "
            "(1 = on)")
        refine: StrictFloat = Field(0.7, gt=0, description="redo the product on the "
                                    "posterior box below this width ratio (1 = off)")
        neg_limit: StrictFloat = Field(0.1, ge=0, description="negative mass above which 'auto' "
                                       "thresholds")
        moment_match: StrictBool = Field(True, description="give the series the grid "
                                         "posterior's mean and covariance after a threshold")
        gate: StrictFloat = Field(5.0, ge=0, description="implausible-measurement gate in "
                                  "standard deviations (0 = off)")


    def __init__(self, model, x0, P0, **settings) -> None:
        model = symbolic(model)
        super().__init__(model, x0, P0, **settings)
        s = self.settings
        K, k_sigma, states, measurements = s.K, s.k_sigma, s.states, s.measurements
        grid_factor, positivity, spectral_filter = s.grid_factor, s.positivity, s.spectral_filter
        long_run, min_halfwidth, resolution_inflation = (s.long_run, s.min_halfwidth,
                                                         s.resolution_inflation)
        refine, neg_limit, moment_match, gate = s.refine, s.neg_limit, s.moment_match, s.gate
        if int(K) != K or K < 1:
            raise ValueError(f"K must be a positive integer, got {K}")
        if not k_sigma > 0 or not grid_factor >= 2:
            raise ValueError("k_sigma must be > 0 and grid_factor >= 2")
        if positivity not in POSITIVITY:
            raise ValueError(f"positivity must be one of {POSITIVITY}, got {positivity!r}")
        self.K = int(K)
        self.k_sigma = float(k_sigma)
        self.positivity = positivity
        self.min_halfwidth = float(min_halfwidth)
        self.resolution_inflation = float(resolution_inflation)
        self.refine = float(refine)
        self.neg_limit = float(neg_limit)
        self.moment_match = bool(moment_match)
        self.gate = float(gate)
        self._gate_ll: dict[tuple, float] = {}
        self.fast = False  # set below, once the basis is known
        self.part = Partition(model, states, measurements)
        self.kalman = ConditionalKalman(model, self.part, self.x, self.P, long_run)
        self.likelihood = GridLikelihood(model, self.part)
        self._var = [float(v) for v in np.diag(model.R)]
        p = self.part.p
        self._ip, self._ik = block_index(p), block_index(self.part.k)
        self._pp, self._kk = block_index(p, p), block_index(self.part.k, self.part.k)
        self._keys = [(f"interval_lo_{n}", f"interval_hi_{n}") for n in self.part.names]
        M = po.fft_size(grid_factor * (2 * self.K + 1))
        if not self.part.drift_constant:
            M = max(M, po.fft_size(4 * self.K + 2))
        mean = self.x[p]
        cov = self.P[np.ix_(p, p)]
        if np.any(np.diag(cov) <= 0):
            raise ValueError("P0 must have a positive variance for every gridded state")
        lo, length = self._box(mean, cov)
        self.basis = po.SpectralBasis(lo, length, self.K, M)
        self._n_basis = float(self.basis.size)
        self.m = po.gaussian_coefficients(mean, cov, self.basis)
        self._filter = (
            po.exponential_filter(self.basis, spectral_filter) if spectral_filter else None
        )
        self._mean, self._cov = mean, cov
        self._after_update = False
        #: compiled kernels (projection_kernels) for two gridded states when Numba is there;
        #: False runs the numpy code (same results to round-off)
        self.fast: bool = bool(pk.ENABLED and self.basis.n == 2 and positivity in ("auto", "none")
                         and spectral_filter == 0)
        self.kalman.fast = self.fast
        if self.fast:  # the fast paths' constant arguments and grid arrays (reused)
            tb = self._tables = pk.tables(self.K, M)
            self._grids = tuple(np.empty((M, M)) for _ in range(3))
            #: negative mass above which a positivity repair follows (the general path's)
            self._limit = self.neg_limit if self.positivity == "auto" else math.inf
            self._bayes_const = (self.refine, self.k_sigma, self.min_halfwidth, tb[2], tb[3],
                                 tb[0], tb[1], self._limit, self.x.size, self.kalman._p_arr,
                                 self.kalman._k_arr)
            self._terrain_const: dict[int, tuple] = {}  # per terrain row, see _terrain_args
        self._fast_predict = self.fast and self.part.drift_constant
        kal = self.kalman
        nk = len(self.part.k)
        self._kal_args = ((kal.H, kal._R, kal.c) if kal.rows and nk else
                          (np.zeros((0, nk)), np.zeros((0, 0)), np.zeros(0)))
        self._set_estimate()

    # ------------------------------------------------------------------------------------------
    def _box(self, mean, cov) -> tuple[np.ndarray, np.ndarray]:
        """Symmetric interval ``mean -+ k_sigma sigma`` (eq. 33), with a floor on the width."""
        if self.fast:
            return pk.box(mean, cov, self.k_sigma, self.min_halfwidth)
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        floor = np.maximum(self.min_halfwidth, 1e-9 * np.maximum(1.0, np.abs(mean)))
        half = np.maximum(self.k_sigma * sig, floor)
        return mean - half, 2.0 * half

    def _set_estimate(self) -> None:
        self.x, self.P = assemble_estimate(self)

    def _normalize(self) -> float:
        if self.fast:
            mass = pk.hermitian_normalize(self.m, self.basis.sqrt_volume())
            if not (math.isfinite(mass) and mass > 0):
                self.diverged = True
                raise FilterDivergence(f"{self.kind}: density lost its mass ({mass})")
            return mass
        m = self.m
        m += np.conj(m[(slice(None, None, -1),) * m.ndim])  # Hermitian part (times 2)
        m *= 0.5
        mass = po.mass(m, self.basis)
        if not (math.isfinite(mass) and mass > 0):
            raise FilterDivergence(f"{self.kind}: density lost its mass ({mass})")
        self.m /= mass  # eqs. 40, 44, 48
        return mass

    def _moments(self, values=None) -> None:
        mean, cov, _ = po.moments(self.m, self.basis)
        if np.any(np.diag(cov) <= 0) or not np.all(np.isfinite(cov)):
            values = po.to_grid(self.m, self.basis) if values is None else values
            mean, cov = po.grid_moments(np.maximum(values, 0.0), self.basis)
        self._mean, self._cov = mean, symmetrize(cov)

    # ------------------------------------------------------------------------------------------
    def predict(self, u, dt: float) -> None:
        self.diagnostics = {}
        self._after_update = False
        u = np.asarray(u, dtype=float).reshape(-1)
        if self._fast_predict:
            self._predict_fast(u, dt)
            return
        part = self.part
        xk_before = None if part.drift_constant else self.kalman.mean.copy()
        inc = self.kalman.increment(self.x, u, dt)
        if part.drift_constant:
            # A diagonal: translation by the increment (moves the box) and diffusion decay
            new = self.basis.moved(*self._box(self._mean + inc.d, self._cov + inc.D))
            mats = po.transfer_matrices(self.K, self.basis.lo + inc.d, self.basis.length,
                                        new.lo, new.length)
            self.m = po.contract(self.m, list(mats))
            self.m *= po.diffusion_decay(new, inc.D)
        else:
            guess_mean = self._mean + inc.d
            Fpp = inc.F[np.ix_(part.p, part.p)]
            guess_cov = Fpp @ self._cov @ Fpp.T + inc.D
            lo1, len1 = self._box(self._mean, self._cov)
            lo2, len2 = self._box(guess_mean, guess_cov)
            lo = np.minimum(lo1, lo2)
            new = self.basis.moved(lo, np.maximum(lo1 + len1, lo2 + len2) - lo)
            self.m = po.reproject(self.m, self.basis, new)
            xk_mid = 0.5 * (xk_before + self.kalman.mean)
            c0, c1, c2 = part.fpe_coefficients(new.axes(), xk_mid, u, dt, inc.Dk / dt)
            A = po.galerkin_matrix(new, c0, c1, c2)
            if A.shape[0] <= DENSE_EXPM_MAX:  # scaling and squaring: robust for stiff A
                mv = expm(A * dt) @ self.m.ravel()
            else:
                mv = expm_multiply(A * dt, self.m.ravel())
            self.m = mv.reshape(self.m.shape)  # eq. 43
        self.basis = new
        if part.drift_constant:  # translation and Gaussian convolution: moments are exact
            mean, cov = self._mean + inc.d, symmetrize(self._cov + inc.D)
        else:
            mean, cov = guess_mean, symmetrize(guess_cov)
        mass = po.mass(self.m, new)
        if not (math.isfinite(mass) and mass > 0):
            # the signed series lost its mass on the new box: carry the Gaussian of the
            # predicted moments on its own box
            self.basis = new.moved(*self._box(mean, cov))
            self.m = po.gaussian_coefficients(mean, cov, self.basis)
            self.diagnostics["gaussian_fallback"] = 1.0
        self.diagnostics["prior_mass"] = self._normalize()
        if part.drift_constant or self.diagnostics.get("gaussian_fallback"):
            self._mean, self._cov = mean, cov
        else:
            self._moments()
        self._set_estimate()

    def _predict_fast(self, u, dt: float) -> None:
        """:meth:`predict` for a drift independent of the gridded states: the conditional
        Kalman prediction, the moved and decayed series and ``(x, P)`` in one compiled call."""
        kal = self.kalman
        step = kal.step
        _, F, Q = step.views(self.x, u, dt)  # consumed by the kernel at once
        phi = kal._phi
        use_phi = phi is not None and kal.long_run and bool(kal.k)
        # the predicted moments and the Kalman block are written in place (_mean, _cov,
        # kal.mean, kal.cov, kal._F)
        m, lo, length, mass, x, P, finite = pk.predict_step(
            self.x, step.flat[0], F, Q, kal._p_arr, kal._k_arr, kal.cov,
            phi if use_phi else kal._eye, use_phi, self.m, self.basis.lo,
            self.basis.length, self._mean, self._cov, self.k_sigma, self.min_halfwidth,
            kal.mean, kal._F)
        self.m = m
        self.basis = self.basis.moved(lo, length, copy=False)  # fresh arrays from the kernel
        mean, cov = self._mean, self._cov
        if math.isfinite(mass) and mass > 0:  # normalized by the kernel
            self.diagnostics["prior_mass"] = mass
            if not finite:
                self.diverged = True
                raise FilterDivergence(f"{self.kind}: non-finite estimate")
            self.x, self.P = x, P
            return
        # the signed series lost its mass on the new box: the Gaussian of the predicted moments
        self.basis = self.basis.moved(*self._box(mean, cov))
        self.m = po.gaussian_coefficients(mean, cov, self.basis)
        self.diagnostics["gaussian_fallback"] = 1.0
        self.diagnostics["prior_mass"] = self._normalize()
        self._set_estimate()

    def update(self, z, mask=None) -> None:
        if self.fast and self._update_fast(z, mask):
            return
        z, rows_k, rows_g = begin_update(self, z, mask)
        diag = self.diagnostics
        prior, prior_basis = self.m, self.basis
        post, mean, cov, ok = self._bayes(self.basis, z, rows_g, record=True)
        if rows_g and not (ok and self._consistent(rows_g)):
            post, mean, cov, ok = self._regrow(z, rows_g)
        elif rows_g and self.refine < 1.0:
            # re-centre on the posterior (eq. 33 with the posterior moments) and, when the
            # posterior box is much narrower, redo the product on its finer grid
            lo, length = self._box(mean, cov)
            r = self.refine
            if any(a < r * b for a, b in zip(length.tolist(), self.basis.length.tolist(),
                                             strict=True)):
                new = self.basis.moved(lo, np.minimum(length, self.basis.length))
                self.m = self._reproject(prior, prior_basis, new)
                post2, mean2, cov2, ok2 = self._bayes(new, z, rows_g, record=False)
                if ok2:
                    self.basis, post, mean, cov = new, post2, mean2, cov2
                    diag["refined"] = 1.0
                else:
                    self.m = prior
        if not ok:
            # last resort (no mass even on the widest box): keep the prior, say so
            self.m, self.basis = prior, prior_basis
            diag["update_skipped"] = 1.0
            diag.pop("regrown", None)
            self._normalize()
            self._moments()
            self._set_estimate()
            self._report()
            return
        cell = self.basis.cell()
        if self.fast:
            tb = pk.tables(self.K, self.basis.M)
            limit = self.neg_limit if self.positivity == "auto" else np.inf
            kal = self.kalman
            self.m, values, neg, mass, x, P, finite = pk.posterior_step(
                post, tb[2], tb[3], tb[0], tb[1], self.basis.length, limit, self.x.size,
                kal._p_arr, kal._k_arr, mean, cov, kal.mean, kal.cov)
            if math.isfinite(mass) and mass > 0:  # no repair: normalized by the kernel
                self._accept(diag, neg, mean, cov, x, P, finite)
                return
        else:
            self.m = po.from_grid(post, self.basis)  # eqs. 45, 47
            self.m /= float(post.sum() * cell)
            if self.positivity == "jackson":
                self.m = self.m * po.jackson_factors(self.basis)
            if self._filter is not None:
                self.m = self.m * self._filter
            values = po.to_grid(self.m, self.basis)
            neg = float(-np.minimum(values, 0.0).sum() * cell)
        diag["neg_mass"] = neg
        mode = self.positivity
        if mode == "auto":
            mode = "threshold" if neg > self.neg_limit else "none"
            diag["positivity_applied"] = float(mode == "threshold")
        if mode in ("threshold", "clip") and neg > 0:
            values = self._positive(values, mode)
            kept = float(values.sum() * cell)
            if np.isfinite(kept) and kept > 0:
                self.m = po.from_grid(values / kept, self.basis)
                if self.moment_match:
                    self.m = self._match_moments(self.m, mean, cov)
            else:
                # the truncated series is all ripple (the posterior is much narrower than the
                # basis resolves on this box): carry the moment-matched Gaussian of the grid
                # posterior on its own box instead of nothing
                self.basis = self.basis.moved(*self._box(mean, cov))
                self.m = po.gaussian_coefficients(mean, cov, self.basis)
                diag["gaussian_fallback"] = 1.0
        self._normalize()
        self._mean, self._cov = mean, cov
        self._set_estimate()
        self._report()

    def _update_fast(self, z, mask) -> bool:
        """The common updates in one or two compiled calls, the Kalman update of the
        velocities included: no grid row (the posterior is the prior:
        :func:`~uwcosim.filters.grid.projection_kalman.prior_step`), or one terrain row whose
        posterior passes the gate and needs neither a finer box nor a positivity repair
        (:func:`~uwcosim.filters.grid.projection_kalman.bayes_step`). Returns False, having
        changed nothing, in every other case: :meth:`update` then runs its general path, which
        computes the same quantities (to round-off) and handles the case."""
        z, rows_k, rows_g = self.part.split_rows(z, mask, self.model.nz)
        basis, kal = self.basis, self.kalman
        active = bool(rows_k) and bool(kal.k)
        if active and rows_k != kal.rows:
            return False
        H, R, c = self._kal_args
        zz = _NO_Z if z is None else z
        if not rows_g:
            tb = self._tables
            ok, neg, x, P, finite, phi, nis = pk.prior_step(
                self.m, tb[0], tb[1], basis.lo, basis.length, self._limit, self.x.size,
                kal._p_arr, kal._k_arr, kal.mean, kal.cov, H, R, c, zz, kal._rows_idx, kal._F,
                active, self._mean, self._cov)
            if not ok:
                return False
            diag = self._fresh_diagnostics(active, phi, nis, len(rows_k))
            diag["neg_mass_prior"] = neg
        else:
            if len(rows_g) != 1:
                return False
            r = rows_g[0]
            targs = self._terrain_const.get(r) or self._terrain_args(r)
            if not targs:
                return False
            values, E, V = self._grids  # filled by the kernel, consumed by bayes_step
            tables, terrain, noise, thr = targs
            neg_prior, tmax, vmin = pk.bayes_terms(self.m, *tables, basis.lo, basis.length,
                                                   *terrain, float(z[r]), *noise, values, E, V)
            np.exp(E, out=E)
            shift = tmax - 0.5 * math.log(vmin) if self.resolution_inflation else tmax
            code, loglik, m, neg, x, P, finite, phi, nis = pk.bayes_step(
                values, E, V, vmin, basis.lo, basis.length, shift, thr, *self._bayes_const,
                kal.mean, kal.cov, H, R, c, zz, kal._rows_idx, kal._F, active, self._mean,
                self._cov)
            if code:
                return False
            self.m = m
            diag = self._fresh_diagnostics(active, phi, nis, len(rows_k))
            diag["neg_mass_prior"] = neg_prior
            diag["loglik"] = loglik
        self._accept(diag, neg, None, None, x, P, finite)  # moments written in place
        return True

    def _terrain_args(self, r: int) -> tuple:
        """The constant arguments of the fast update with the terrain row ``r`` (cached):
        ``((Tq, Tx), (map coefficients, tpar, ipar), (variance, inflation), gate
        threshold)``; ``()`` when ``r`` is not a terrain row (the general path handles it)."""
        tg = self.likelihood.terrain_rows.get(r)
        if tg is None:
            return ()
        thr = self._gate_threshold([r]) if self.gate else -math.inf
        out = self._terrain_const[r] = ((self._tables[0], self._tables[1]),
                                        (tg.t.coefficients, tg.tpar, tg.ipar),
                                        (self._var[r], self.resolution_inflation), thr)
        return out

    def _accept(self, diag: dict, neg: float, mean, cov, x, P, finite: bool) -> None:
        """Take a compiled update's result: the gridded block's moments (``None``: the kernel
        wrote them into ``_mean``, ``_cov``), the estimate ``(x, P)`` (FilterDivergence if not
        finite) and the diagnostics (no positivity repair)."""
        diag["neg_mass"] = neg
        if self.positivity == "auto":
            diag["positivity_applied"] = 0.0
        if mean is not None:
            self._mean, self._cov = mean, cov
        if not finite:
            self.diverged = True
            raise FilterDivergence(f"{self.kind}: non-finite estimate")
        self.x, self.P = x, P
        self._report()

    def _fresh_diagnostics(self, active, phi, nis, n_rows) -> dict:
        """:func:`begin_update`'s bookkeeping after a fused update: fresh diagnostics (unless
        a prediction just wrote them), the Kalman block's ``phi`` (its mean and covariance were
        written in place) and NIS."""
        if self._after_update:
            self.diagnostics = {}
        self._after_update = True
        diag = self.diagnostics
        if active:
            kal = self.kalman
            kal._phi = phi
            diag["nis"] = nis
            diag["nis_dof"] = float(n_rows)
        return diag

    def _report(self) -> None:
        d = self.diagnostics
        d["n_basis"] = self._n_basis
        lo, length = self.basis.lo.tolist(), self.basis.length.tolist()
        for i, (klo, khi) in enumerate(self._keys):
            d[klo] = lo[i]
            d[khi] = lo[i] + length[i]  # basis.hi

    # ------------------------------------------------------------------------------------------
    @property
    def gridded_states(self) -> list[str]:
        return self.part.names

    def density_grid(self, axes=None, n: int = 101, clip: bool = True):
        """Posterior density of the gridded states on a tensor grid.

        ``axes``: one array per gridded state (default: ``n`` points across the current box).
        Returns ``(axes, values)`` with ``values[i, j, ...]`` at ``(axes[0][i], axes[1][j], ...)``;
        zero outside the box; negative lobes clipped unless ``clip=False``.
        """
        if axes is None:
            lo, hi = self.basis.lo, self.basis.hi
            axes = [np.linspace(lo[d], hi[d], n) for d in range(lo.size)]
        axes = [np.asarray(a, dtype=float) for a in axes]
        values = po.evaluate(self.m, self.basis, axes)
        return axes, (np.maximum(values, 0.0) if clip else values)
