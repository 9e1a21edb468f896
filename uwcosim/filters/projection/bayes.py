"""PFM-PSI's Bayes update (seed 000 eqs. 45-48, 50-51): the posterior series from the product
of likelihood and prior on the quadrature grid, its moments, the positivity repairs of the
truncated series, the measurement gate and the regrowth of a box that holds no posterior.

1. *Product* (eqs. 45-47): ``m = F m- / (E' m-)`` is the FFT quadrature of the product of the
   likelihood and the prior on the grid (``F m-`` is exactly that projection, so ``F`` is never
   formed): the prior's grid values times ``p(z | x)``, projected (:func:`~uwcosim.filters.
   projection.series.from_grid`) and divided by the mass ``E' m-`` (eq. 46), then normalized
   (eq. 48). When the posterior box (eq. 33 with the posterior moments) is narrower than
   ``refine`` times the prior box, the product is redone on the posterior box's finer grid.
2. *Moments* (eqs. 50-51): quadratures on the grid of the posterior product before truncation
   (eq. 50 with ``Psi = sqrt(L)/K IFFT(x_n)`` is that quadrature), variances floored at the grid
   resolution (:func:`grid_posterior_moments`).
3. *Negative lobes*: the mass ``integral of max(-p, 0)`` of the truncated posterior is reported
   as ``neg_mass`` (and ``neg_mass_prior``). ``positivity="auto"`` keeps the signed series as
   the paper does (the lobes carry the truncation error with nearly zero net mass and cancel in
   the moments) while ``neg_mass <= neg_limit``; above it the grid values are
   thresholded (``max(p - a, 0)``, ``a`` the deepest lobe), renormalized and re-projected
   (``positivity_applied`` = 1), and with ``moment_match`` the series gets the grid posterior's
   mean and covariance back (:meth:`BayesUpdate.match_moments`). ``"clip"`` (clip and
   renormalize) is available but unstable on rough terrain: the positive halves of the ripples
   stay, spread over the box, inflate the variance, hence the next box, hence the ripples.
   ``"threshold"`` always thresholds (stable, but it trims tails every step: overconfident);
   ``"jackson"`` damps the coefficients with the positive Jackson kernel
   (:func:`jackson_factors`: nonnegative by construction, but the blur of one resolution cell
   per step outgrows the information at ``K = 10``); ``"none"`` never corrects.
   ``spectral_filter`` multiplies the coefficients by :func:`exponential_filter`.
4. *Representation error*: a likelihood rougher than the basis can resolve is not sampled as if
   exact: the measurement variance is inflated by the variation of ``h`` within a resolution
   cell ``L / (2K + 1)`` (``resolution_inflation``, 1 = on; vanishes as the box shrinks).
5. *Gate* (``gate`` sigma; 0 = off): a measurement the prior cannot explain (its predictive
   density below the two-sided ``gate``-sigma quantile) regrows the box
   (:meth:`BayesUpdate.regrow`); when no box holds a posterior the update is skipped.

:class:`BayesUpdate` is the numpy form (any number of gridded states);
:class:`~uwcosim.filters.projection.bayes_kernels.CompiledBayesUpdate` runs the common updates
in one or two compiled calls.
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import numpy as np
from scipy import special

from uwcosim.filters.grid.conditional import ConditionalKalman
from uwcosim.filters.grid.likelihood import GridLikelihood
from uwcosim.filters.grid.partition import Partition
from uwcosim.filters.numerics import cholesky, symmetrize
from uwcosim.filters.projection.series import (
    SeriesDensity,
    SeriesOps,
    SpectralBasis,
    carried_moments,
    diffusion_decay,
    from_grid,
    gaussian_coefficients,
    grid_moments,
    series_moments,
    to_grid,
)

#: the treatments of negative lobes of the truncated series, as a setting
Positivity = Literal["auto", "none", "threshold", "clip", "product", "jackson"]
POSITIVITY = get_args(Positivity)
REGROW = (2.0, 4.0, 8.0, 16.0)  # prior std inflations tried when the box holds no posterior


def exponential_filter(basis: SpectralBasis, order: float, alpha: float = 36.0) -> np.ndarray:
    """Spectral filter ``exp(-alpha (|q|/K)^order)`` per dimension (``order`` even, e.g. 8)."""
    s = np.exp(-alpha * (np.abs(basis.q) / max(basis.K, 1)) ** order)
    out = s
    for _ in range(basis.n - 1):
        out = np.multiply.outer(out, s)
    return out


def jackson_factors(basis: SpectralBasis) -> np.ndarray:
    """Jackson damping ``g_|q|`` (tensor product): the smoothed series is the convolution of the
    density with the positive Jackson kernel, hence nonnegative, and keeps its mass (``g_0 = 1``);
    the kernel's width is about ``L / (2K + 2)`` (kernel polynomial method, Weisse et al. 2006).
    """
    N = basis.K
    q = np.abs(basis.q)
    a = np.pi / (N + 2)
    g = ((N + 2 - q) * np.cos(a * q) + np.sin(a * q) / np.tan(a)) / (N + 2)
    out = g
    for _ in range(basis.n - 1):
        out = np.multiply.outer(out, g)
    return out


def positive(values: np.ndarray, mode: str) -> np.ndarray:
    """Remove the truncation's negative lobes from grid values.

    ``"clip"``: ``max(p, 0)``. ``"threshold"``: ``max(p - a, 0)`` with ``a`` the depth of the
    deepest negative lobe: the positive ripples of the same amplitude go too, so the mass
    added by clipping is not spread over the whole box (which inflates the variance, hence
    the next box, hence the ripples: an instability seen on rough terrain).
    """
    if mode == "threshold":
        a = -float(values.min())
        return np.maximum(values - a, 0.0) if a > 0 else values
    return np.maximum(values, 0.0)


def grid_posterior_moments(post: np.ndarray, basis: SpectralBasis):
    """Moments of the (possibly signed) grid posterior (eqs. 50-51 as quadratures); of its clip
    if they are not valid. Variances are floored at the grid resolution ``(L / M)^2 / 12``.
    """
    floor = (basis.length / basis.M) ** 2 / 12.0
    mean, cov = grid_moments(post, basis)
    var = np.diag(cov)
    ok = math.isfinite(float(cov.sum())) and bool(np.all(var > floor))
    if not (ok and cholesky(cov) is not None):
        mean, cov = grid_moments(np.maximum(post, 0.0), basis)
        var = np.diag(cov)
    if np.all(var >= floor):
        return mean, cov
    d = np.sqrt(np.maximum(var, floor) / np.maximum(var, 1e-300))
    return mean, cov * np.outer(d, d)


class BayesUpdate:
    """PFM-PSI's measurement update, numpy form (any number of gridded states).

    ``settings``: the filter's settings (``K``, ``positivity``, ``neg_limit``, ``refine``,
    ``gate``, ``resolution_inflation``, ``moment_match``, ``spectral_filter``); ``R``: the
    model's measurement covariance (the gate's threshold)."""

    #: the step runs compiled kernels
    compiled = False

    def __init__(self, settings, part: Partition, likelihood: GridLikelihood,
                 kalman: ConditionalKalman, ops: SeriesOps, R: np.ndarray) -> None:
        self.settings = settings
        self.part = part
        self.likelihood = likelihood
        self.kalman = kalman
        self.ops = ops
        self.R = R
        self._gate_ll: dict[tuple, float] = {}
        self._filter: np.ndarray | None = None  # the spectral filter (one basis shape)

    def update(self, density: SeriesDensity, x: np.ndarray, z, rows_k: list[int],
               rows_g: list[int], diag: dict) -> tuple[np.ndarray, np.ndarray, bool]:
        """The update of ``density`` (in place) and of the Kalman block with the available
        rows of ``z`` (``rows_k`` of the Kalman block, ``rows_g`` of the grid), at the prior
        estimate ``x``; returns the posterior's ``(x, P, finite)``."""
        self.kalman.update(x, z, rows_k, diag)
        s = self.settings
        prior, prior_basis = density.m, density.basis
        post, mean, cov, ok = self.product(density, density.basis, z, rows_g, x, True, diag)
        if rows_g and not (ok and self.consistent(rows_g, diag)):
            post, mean, cov, ok = self.regrow(density, z, rows_g, x, diag)
        elif rows_g and s.refine < 1.0:
            # re-centre on the posterior (eq. 33 with the posterior moments) and, when the
            # posterior box is much narrower, redo the product on its finer grid
            lo, length = self.ops.box(mean, cov)
            r = s.refine
            if any(a < r * b for a, b in zip(length.tolist(), density.basis.length.tolist(),
                                             strict=True)):
                new = density.basis.moved(lo, np.minimum(length, density.basis.length))
                density.m = self.ops.reproject(prior, prior_basis, new)
                post2, mean2, cov2, ok2 = self.product(density, new, z, rows_g, x, False, diag)
                if ok2:
                    density.basis, post, mean, cov = new, post2, mean2, cov2
                    diag["refined"] = 1.0
                else:
                    density.m = prior
        if not ok:
            # last resort (no mass even on the widest box): keep the prior, say so
            density.m, density.basis = prior, prior_basis
            diag["update_skipped"] = 1.0
            diag.pop("regrown", None)
            self.ops.normalize(density.m, density.basis)
            density.mean, density.cov = carried_moments(density.m, density.basis)
            return self.kalman.assemble(density.mean, density.cov)
        done = self.posterior(density, post, mean, cov, diag)
        if done is not None:
            return done
        self.ops.normalize(density.m, density.basis)
        density.mean, density.cov = mean, cov
        return self.kalman.assemble(mean, cov)

    def product(self, density: SeriesDensity, basis: SpectralBasis, z, rows_g, x, record: bool,
                diag: dict):
        """Prior (``density.m`` on ``basis``) times likelihood on the quadrature grid of
        ``basis``, and its moments (eqs. 46, 50-51): ``(post, mean, cov, ok)``; ``record``:
        report the prior's negative mass."""
        s = self.settings
        cell = basis.cell()
        values = to_grid(density.m, basis)
        if record:
            diag["neg_mass_prior"] = float(-np.minimum(values, 0.0).sum() * cell)
        if s.positivity in ("threshold", "clip", "product"):
            values = positive(values, s.positivity)
        post = values
        if rows_g:
            res = basis.length / (2 * s.K + 1) * s.resolution_inflation
            ll = self.likelihood.loglik(
                basis.axes(), z, rows_g, x, res if s.resolution_inflation else None
            )
            llmax = float(np.max(ll))
            post = values * np.exp(ll - llmax)
            Z = float(post.sum() * cell)  # E' m- (eq. 46)
            if not (np.isfinite(Z) and Z > 0):  # a signed prior: try its clip
                post = np.maximum(post, 0.0)
                Z = float(post.sum() * cell)
            if not (np.isfinite(Z) and Z > 0):
                return values, None, None, False  # no posterior mass on this box
            diag["loglik"] = float(np.log(Z) + llmax)
        elif not post.sum() > 0:  # a signed prior can lose its mass: fall back to its clip
            post = np.maximum(post, 0.0)
            if not post.sum() > 0:
                return values, None, None, False
        mean, cov = grid_posterior_moments(post, basis)
        ok = math.isfinite(float(mean.sum() + cov.sum()))
        return post, mean, cov, ok

    def posterior(self, density: SeriesDensity, post: np.ndarray, mean, cov, diag: dict):
        """The posterior series from the grid posterior ``post`` (eqs. 45, 47) and the
        positivity repair of its negative lobes; ``None`` (normalization and moments
        follow in :meth:`update`), or the step's ``(x, P, finite)`` when it is complete."""
        s = self.settings
        basis = density.basis
        cell = basis.cell()
        density.m = from_grid(post, basis)  # eqs. 45, 47
        density.m /= float(post.sum() * cell)
        if s.positivity == "jackson":
            density.m = density.m * jackson_factors(basis)
        if s.spectral_filter:
            if self._filter is None:
                self._filter = exponential_filter(basis, s.spectral_filter)
            density.m = density.m * self._filter
        values = to_grid(density.m, basis)
        neg = float(-np.minimum(values, 0.0).sum() * cell)
        self.repair(density, values, neg, mean, cov, diag)
        return None

    def repair(self, density: SeriesDensity, values: np.ndarray, neg: float, mean, cov,
               diag: dict) -> None:
        """The positivity treatment of the posterior series whose grid ``values`` have the
        negative mass ``neg`` (module docstring, item 3)."""
        s = self.settings
        diag["neg_mass"] = neg
        mode = s.positivity
        if mode == "auto":
            mode = "threshold" if neg > s.neg_limit else "none"
            diag["positivity_applied"] = float(mode == "threshold")
        if mode in ("threshold", "clip") and neg > 0:
            cell = density.basis.cell()
            values = positive(values, mode)
            kept = float(values.sum() * cell)
            if np.isfinite(kept) and kept > 0:
                density.m = from_grid(values / kept, density.basis)
                if s.moment_match:
                    density.m = self.match_moments(density.m, density.basis, mean, cov, diag)
            else:
                # the truncated series is all ripple (the posterior is much narrower than the
                # basis resolves on this box): carry the moment-matched Gaussian of the grid
                # posterior on its own box instead of nothing
                density.basis = density.basis.moved(*self.ops.box(mean, cov))
                density.m = gaussian_coefficients(mean, cov, density.basis)
                diag["gaussian_fallback"] = 1.0

    def match_moments(self, m: np.ndarray, basis: SpectralBasis, mean: np.ndarray,
                      cov: np.ndarray, diag: dict) -> np.ndarray:
        """Give the repaired series the moments of the grid posterior (exact operations).

        Thresholding removes the tails and the low modes with the ripples, so the carried
        density becomes narrower than the posterior whose moments are reported: the filter
        turns overconfident and, on an elongated posterior, loses the track. The series is
        translated by the mean difference and blurred by the covariance deficit (its positive
        semi-definite part): ``m_q exp(-j w.delta - w' Delta w / 2)``.
        """
        mu_s, cov_s, _ = series_moments(m, basis)
        if not (np.all(np.isfinite(mu_s)) and np.all(np.isfinite(cov_s))):
            return m
        lam, vec = np.linalg.eigh(symmetrize(cov - cov_s))
        deficit = (vec * np.maximum(lam, 0.0)) @ vec.T
        oms = np.meshgrid(*[basis.omega(d) for d in range(basis.n)], indexing="ij")
        phase = sum(o * dv for o, dv in zip(oms, mean - mu_s, strict=True))
        diag["moment_matched"] = 1.0
        return m * np.exp(-1j * phase) * diffusion_decay(basis, deficit)

    def regrow(self, density: SeriesDensity, z, rows_g, x, diag: dict):
        """Bayes product on wider boxes when the prior box holds no posterior mass.

        The measurement is then inconsistent with the prior (its box misses the likelihood):
        the prior is replaced by the Gaussian of its moments with the covariance inflated by
        ``g^2`` (``g`` in :data:`REGROW`) on the box ``mean -+ k_sigma g sigma``, and the product
        redone there. Diagnostic ``regrown`` = the ``g`` that worked.
        """
        mean0, cov0 = density.mean, density.cov
        for g in REGROW:
            cov = cov0 * g**2
            basis = density.basis.moved(*self.ops.box(mean0, cov))
            density.m = gaussian_coefficients(mean0, cov, basis)
            out = self.product(density, basis, z, rows_g, x, False, diag)
            if out[3] and self.consistent(rows_g, diag):
                density.basis = basis
                diag["regrown"] = float(g)
                return out
        diag["inconsistent"] = 1.0
        return None, None, None, False

    def consistent(self, rows_g, diag: dict) -> bool:
        """Whether the measurement is plausible under the prior (the gate, ``gate`` sigma).

        ``loglik`` is the log of the predictive density ``integral p(x) N(z; h(x), R) dx``
        (up to the constant of ``R``); relative to a perfect match it is below
        ``-chi2_quantile / 2`` when the prior puts no mass where ``z`` could have come from
        (probability ``P(|N(0,1)| > gate)`` for a consistent prior). With a Student-t likelihood
        (``student_t_nu``) the threshold is the t density at the quantile of the same tail
        probability, per row (a far heavier tail: an outlier is then plausible).
        """
        if not self.settings.gate:
            return True
        ll = diag.get("loglik")
        return ll is not None and ll >= self.gate_threshold(rows_g)

    def gate_threshold(self, rows_g) -> float:
        """The least plausible ``loglik`` of :meth:`consistent` for the rows ``rows_g``
        (cached per set of rows)."""
        key = tuple(rows_g)
        thr = self._gate_ll.get(key)
        if thr is None:
            s = self.settings
            m = len(rows_g)
            p_tail = float(special.erfc(s.gate / np.sqrt(2.0)))
            nu = self.likelihood.nu
            if nu is None:
                thr = -0.5 * float(special.chdtri(m, p_tail))
            else:  # Student-t rows (filters.robust): each at its own two-sided tail quantile
                q = float(special.stdtrit(nu, 1.0 - 0.5 * p_tail))
                thr = -0.5 * (nu + 1.0) * m * float(np.log1p(q * q / nu))
            if s.resolution_inflation:  # loglik then includes -log det(R + inflation) / 2
                thr -= 0.5 * float(np.linalg.slogdet(self.R[np.ix_(key, key)])[1])
            self._gate_ll[key] = thr
        return thr
