"""The Bayes step of the projection filter (PFM-PSI): prior times likelihood on the quadrature
grid, its moments (seed 000 eqs. 46, 50-51), the positivity repairs of the truncated series,
moment matching, the measurement gate and the regrowth of a box that holds no posterior.

:class:`BayesProduct` is a mixin of :class:`~uwcosim.filters.grid.projection.ProjectionFilter`
(it uses the filter's ``basis``, ``m``, ``likelihood``, settings and diagnostics).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from uwcosim.filters.grid import projection_kernels as pk
from uwcosim.filters.grid import spectral as po
from uwcosim.filters.numerics import cholesky, symmetrize

REGROW = (2.0, 4.0, 8.0, 16.0)  # prior std inflations tried when the box holds no posterior
_NO_D = np.zeros((2, 2))
_ONES: dict[int, np.ndarray] = {}


def _ones(M: int) -> np.ndarray:
    one = _ONES.get(M)
    if one is None:
        # writable (a read-only array would be a second compiled specialization); the kernel
        # only reads it
        one = _ONES[M] = np.ones((M, M))
    return one
_NO_R = np.zeros(2)


class BayesProduct:
    """Bayes product, moments and repairs of :class:`ProjectionFilter` (a mixin)."""

    def _match_moments(self, m: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """Give the repaired series the moments of the grid posterior (exact operations).

        Thresholding removes the tails and the low modes with the ripples, so the carried
        density becomes narrower than the posterior whose moments are reported: the filter
        turns overconfident and, on an elongated posterior, loses the track. The series is
        translated by the mean difference and blurred by the covariance deficit (its positive
        semi-definite part): ``m_q exp(-j w.delta - w' Delta w / 2)``.
        """
        mu_s, cov_s, _ = po.moments(m, self.basis)
        if not (np.all(np.isfinite(mu_s)) and np.all(np.isfinite(cov_s))):
            return m
        lam, vec = np.linalg.eigh(symmetrize(cov - cov_s))
        deficit = (vec * np.maximum(lam, 0.0)) @ vec.T
        oms = np.meshgrid(*[self.basis.omega(d) for d in range(self.basis.n)], indexing="ij")
        phase = sum(o * dv for o, dv in zip(oms, mean - mu_s, strict=True))
        self.diagnostics["moment_matched"] = 1.0
        return m * np.exp(-1j * phase) * po.diffusion_decay(self.basis, deficit)

    def _regrow(self, z, rows_g):
        """Bayes product on wider boxes when the prior box holds no posterior mass.

        The measurement is then inconsistent with the prior (its box misses the likelihood):
        the prior is replaced by the Gaussian of its moments with the covariance inflated by
        ``g^2`` (``g`` in :data:`REGROW`) on the box ``mean -+ k_sigma g sigma``, and the product
        redone there. Diagnostic ``regrown`` = the ``g`` that worked.
        """
        mean0, cov0 = self._mean, self._cov
        for g in REGROW:
            cov = cov0 * g**2
            basis = self.basis.moved(*self._box(mean0, cov))
            self.m = po.gaussian_coefficients(mean0, cov, basis)
            out = self._bayes(basis, z, rows_g, record=False)
            if out[3] and self._consistent(rows_g):
                self.basis = basis
                self.diagnostics["regrown"] = float(g)
                return out
        self.diagnostics["inconsistent"] = 1.0
        return None, None, None, False

    def _consistent(self, rows_g) -> bool:
        """Whether the measurement is plausible under the prior (the gate, ``gate`` sigma).

        ``loglik`` is the log of the predictive density ``integral p(x) N(z; h(x), R) dx``
        (up to the constant of ``R``); relative to a perfect match it is below
        ``-chi2_quantile / 2`` when the prior puts no mass where ``z`` could have come from
        (probability ``P(|N(0,1)| > gate)`` for a consistent prior).
        """
        if not self.gate:
            return True
        ll = self.diagnostics.get("loglik")
        return ll is not None and ll >= self._gate_threshold(rows_g)

    def _gate_threshold(self, rows_g) -> float:
        """The least plausible ``loglik`` of :meth:`_consistent` for the rows ``rows_g``
        (cached per set of rows)."""
        key = tuple(rows_g)
        thr = self._gate_ll.get(key)
        if thr is None:
            m = len(rows_g)
            p_tail = float(special.erfc(self.gate / np.sqrt(2.0)))
            thr = -0.5 * float(special.chdtri(m, p_tail))
            if self.resolution_inflation:  # loglik then includes -log det(R + inflation) / 2
                thr -= 0.5 * float(np.linalg.slogdet(self.model.R[np.ix_(key, key)])[1])
            self._gate_ll[key] = thr
        return thr

    def _positive(self, values: np.ndarray, mode: str | None = None) -> np.ndarray:
        """Remove the truncation's negative lobes from grid values.

        ``"clip"``: ``max(p, 0)``. ``"threshold"``: ``max(p - a, 0)`` with ``a`` the depth of the
        deepest negative lobe: the positive ripples of the same amplitude go too, so the mass
        added by clipping is not spread over the whole box (which inflates the variance, hence
        the next box, hence the ripples: an instability seen on rough terrain).
        """
        if (mode or self.positivity) == "threshold":
            a = -float(values.min())
            return np.maximum(values - a, 0.0) if a > 0 else values
        return np.maximum(values, 0.0)

    def _reproject(self, m, basis, new):
        if self.fast:
            return pk.shift_decay(m, basis.lo, basis.length, new.lo, new.length, _NO_D, False)
        return po.reproject(m, basis, new)

    def _bayes_fast(self, basis, z, r: int, record: bool):
        """:meth:`_bayes` for one terrain row and two gridded states (compiled kernels)."""
        tg = self.likelihood.terrain_rows[r]
        tb = pk.tables(self.K, basis.M)
        values, E, V = (np.empty((basis.M, basis.M)) for _ in range(3))
        neg, tmax, vmin = pk.bayes_terms(
            self.m, tb[0], tb[1], basis.lo, basis.length, tg.t.coefficients, tg.tpar, tg.ipar,
            float(z[r]), self._var[r], self.resolution_inflation, values, E, V)
        if record:
            self.diagnostics["neg_mass_prior"] = neg
        np.exp(E, out=E)
        post, Z, mean, cov, status = pk.bayes_posterior(values, E, V, vmin, basis.lo,
                                                        basis.length)
        if status == 1:
            return values, None, None, False
        # ll = W + tmax - log(V) / 2; post used exp(ll - tmax + log(vmin) / 2)
        shift = tmax - 0.5 * math.log(vmin) if self.resolution_inflation else tmax
        self.diagnostics["loglik"] = math.log(Z) + shift
        return post, mean, cov, status != 3

    def _bayes(self, basis, z, rows_g, record: bool):
        """Prior times likelihood on the quadrature grid of ``basis``; its moments (eq. 50-51)."""
        if self.fast and len(rows_g) == 1 and rows_g[0] in self.likelihood.terrain_rows:
            return self._bayes_fast(basis, z, rows_g[0], record)
        if self.fast and not rows_g:  # no grid measurement: the prior's grid and moments
            tb = pk.tables(self.K, basis.M)
            values, neg = pk.prior_values(self.m, tb[0], tb[1], basis.length)
            if record:
                self.diagnostics["neg_mass_prior"] = neg
            one = _ones(basis.M)
            post, _, mean, cov, status = pk.bayes_posterior(values, one, one, 1.0, basis.lo,
                                                            basis.length)
            if status == 1:
                return values, None, None, False
            return post, mean, cov, status != 3
        cell = basis.cell()
        values = po.to_grid(self.m, basis)
        if record:
            self.diagnostics["neg_mass_prior"] = float(-np.minimum(values, 0.0).sum() * cell)
        if self.positivity in ("threshold", "clip", "product"):
            values = self._positive(values)
        post = values
        if rows_g:
            res = basis.length / (2 * self.K + 1) * self.resolution_inflation
            ll = self.likelihood.loglik(
                basis.axes(), z, rows_g, self.x, res if self.resolution_inflation else None
            )
            llmax = float(np.max(ll))
            post = values * np.exp(ll - llmax)
            Z = float(post.sum() * cell)  # E' m- (eq. 46)
            if not (np.isfinite(Z) and Z > 0):  # a signed prior: try its clip
                post = np.maximum(post, 0.0)
                Z = float(post.sum() * cell)
            if not (np.isfinite(Z) and Z > 0):
                return values, None, None, False  # no posterior mass on this box
            self.diagnostics["loglik"] = float(np.log(Z) + llmax)
        elif not post.sum() > 0:  # a signed prior can lose its mass: fall back to its clip
            post = np.maximum(post, 0.0)
            if not post.sum() > 0:
                return values, None, None, False
        mean, cov = self._grid_moments(post, basis)
        ok = math.isfinite(float(mean.sum() + cov.sum()))
        return post, mean, cov, ok

    @staticmethod
    def _grid_moments(post: np.ndarray, basis):
        """Moments of the (possibly signed) grid posterior; of its clip if they are not valid.

        Variances are floored at the grid resolution ``(L / M)^2 / 12``.
        """
        floor = (basis.length / basis.M) ** 2 / 12.0
        mean, cov = po.grid_moments(post, basis)
        var = np.diag(cov)
        ok = math.isfinite(float(cov.sum())) and bool(np.all(var > floor))
        if not (ok and cholesky(cov) is not None):
            mean, cov = po.grid_moments(np.maximum(post, 0.0), basis)
            var = np.diag(cov)
        if np.all(var >= floor):
            return mean, cov
        d = np.sqrt(np.maximum(var, floor) / np.maximum(var, 1e-300))
        return mean, cov * np.outer(d, d)
