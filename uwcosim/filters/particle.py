"""Bootstrap particle filter (``pf``) and the resampling schemes (:data:`RESAMPLERS`).

Gordon, Salmond & Smith (1993): particles drawn from ``N(x0, P0)``, moved by the transition
``f`` plus process noise sampled from ``N(0, Q)``, weighted by the measurement likelihood
``N(z; h(x), R)`` (log weights), resampled when the effective sample size
``ESS = 1 / sum w_i^2`` falls below ``ess_threshold * N``, optionally roughened. The estimate is
the weighted mean and covariance of the particles.

Process noise: ``Q`` is additive, evaluated once per step at the weighted mean
(``model.Q(x_mean, u, dt)``, exact for the TAN and linear models whose ``Q`` does not depend on
the state) and sampled through a factor ``L L' = Q`` (Cholesky, or the eigen-decomposition when
``Q`` is singular).

Speed (about 1000 particles in well under a millisecond): particles are stored state-major
(``(nx, N)``, so every state is a contiguous row), the model's batch functions get column-major
views, the numpy fast path of the TAN model is used (:mod:`uwcosim.models.fast_tan`) and the
Gaussian log-likelihood of a diagonal ``R`` is one matrix-vector product.

Randomness: only the ``numpy.random.Generator`` given as ``rng`` or created from ``seed``
(``seed`` wins when both are given, so a scenario can pin one filter); none: a fresh,
unseeded generator.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.linalg import solve_triangular

from uwcosim.errors import FilterDivergence, ScenarioError
from uwcosim.filters.base import register
from uwcosim.filters.kalman import FilterBase
from uwcosim.filters.numerics import cho_solve, cholesky, psd_factor, repair_pd
from uwcosim.registry import Registry

Resampler = Callable[[np.ndarray, np.random.Generator], np.ndarray]
RESAMPLERS: Registry[Resampler] = Registry("resampling scheme")


def _search(w: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Indices ``i`` with ``cumsum(w)[i-1] < position <= cumsum(w)[i]``."""
    cs = np.cumsum(w)
    cs[-1] = 1.0  # guard against round-off: every position in [0, 1) finds a particle
    return np.searchsorted(cs, positions, side="right").clip(max=w.size - 1)


@RESAMPLERS.register("systematic")
def systematic(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform offset, ``N`` evenly spaced positions (lowest variance, O(N))."""
    n = w.size
    return _search(w, (rng.random() + np.arange(n)) / n)


@RESAMPLERS.register("stratified")
def stratified(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform position in each of ``N`` equal strata."""
    n = w.size
    return _search(w, (rng.random(n) + np.arange(n)) / n)


@RESAMPLERS.register("multinomial")
def multinomial(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``N`` independent draws from the weights."""
    return _search(w, rng.random(w.size))


@RESAMPLERS.register("residual")
def residual(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``floor(N w_i)`` copies of each particle, the rest drawn multinomially from the
    residual weights (Liu & Chen 1998)."""
    n = w.size
    counts = np.floor(n * w).astype(np.intp)
    rest = n - int(counts.sum())
    idx = np.repeat(np.arange(n), counts)
    if rest > 0:
        r = n * w - counts
        idx = np.concatenate((idx, _search(r / r.sum(), rng.random(rest))))
    return idx


@register("pf")
class ParticleFilter(FilterBase):
    """Bootstrap particle filter.

    Settings: ``n_particles`` (1000), ``resampling`` (``systematic``, ``stratified``,
    ``residual`` or ``multinomial``), ``ess_threshold`` (fraction of ``N`` below which to
    resample, 0.5; 1 resamples every step), ``roughening`` (Gordon et al.'s ``K``: after
    resampling add ``N(0, (K E_j N^(-1/nx))^2)`` to state ``j``, ``E_j`` the particles' range;
    0 = off), ``seed``, ``rng``, ``measurements``.

    ``x`` and ``P`` are the weighted mean and covariance, computed when read.
    """

    def __init__(
        self,
        model,
        x0,
        P0,
        n_particles: int = 1000,
        resampling: str = "systematic",
        ess_threshold: float = 0.5,
        roughening: float = 0.0,
        seed: int | None = None,
        rng: np.random.Generator | None = None,
        measurements: list[str] | None = None,
    ) -> None:
        super().__init__(model, x0, P0, measurements)
        if int(n_particles) < 2:
            raise ValueError(f"n_particles must be at least 2, got {n_particles}")
        if not 0.0 <= float(ess_threshold) <= 1.0:
            raise ValueError(f"ess_threshold must be in [0, 1], got {ess_threshold}")
        if float(roughening) < 0.0:
            raise ValueError(f"roughening must be >= 0, got {roughening}")
        try:
            self.resample = RESAMPLERS.get(resampling)
        except ScenarioError as exc:  # from_settings prefixes the scenario location
            raise ValueError(str(exc)) from None
        self.n = int(n_particles)
        self.ess_threshold = float(ess_threshold)
        self.roughening = float(roughening)
        if seed is not None:
            rng = np.random.default_rng(seed)
        self.rng = rng if rng is not None else np.random.default_rng()
        L = psd_factor(self.P)  # P0 may be singular (a state known exactly)
        # particles, state-major: row j holds state j of every particle
        self.particles = self.x[:, None] + L @ self.rng.standard_normal((model.nx, self.n))
        self.logw = np.full(self.n, -math.log(self.n))
        self._w = np.full(self.n, 1.0 / self.n)
        self._moments_stale = True
        self._noise_key: tuple | None = None
        self._xdep = getattr(self.model, "Q_depends_on_x", True)
        self._lik_cache: dict[bytes, tuple] = {}

    # estimate -----------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        if getattr(self, "_moments_stale", False):
            self._moments()
        return self._x

    @x.setter
    def x(self, value) -> None:
        self._x = value

    @property
    def P(self) -> np.ndarray:
        if getattr(self, "_moments_stale", False):
            self._moments()
        return self._P

    @P.setter
    def P(self, value) -> None:
        self._P = value

    @property
    def weights(self) -> np.ndarray:
        """Normalized particle weights."""
        return self._w

    def _moments(self) -> None:
        Xp, w = self.particles, self._w
        m = Xp @ w  # x = sum w_i X_i
        D = Xp - m[:, None]
        P = (D * w) @ D.T  # P = sum w_i (X_i - x)(X_i - x)'
        self._x, self._P = m, 0.5 * (P + P.T)
        self._moments_stale = False

    # filter -------------------------------------------------------------------------------
    def _noise_factor(self, u, dt: float) -> np.ndarray:
        key = (np.asarray(u, dtype=float).tobytes(), float(dt))
        if self._xdep or key != self._noise_key:
            mean = self.particles @ self._w
            self._L = psd_factor(self.model.Q(mean, u, dt))
            self._noise_key = key
        return self._L

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        L = self._noise_factor(u, dt)
        Xn = np.asarray(self.model.f_batch(self.particles.T, u, dt)).T  # X_i = f(X_i, u)
        noise = L @ self.rng.standard_normal((L.shape[1], self.n))  # w_i ~ N(0, Q)
        noise += Xn
        self.particles = noise
        if not np.isfinite(noise.sum()):  # NaN or inf anywhere makes the sum non-finite
            raise FilterDivergence("pf prediction contains NaN or inf")
        self._moments_stale = True

    def _likelihood_terms(self, idx: np.ndarray):
        """``(R_idx, -1/(2 r))`` for a diagonal block, ``(R_idx, L)`` (Cholesky) otherwise."""
        key = idx.tobytes()
        terms = self._lik_cache.get(key)
        if terms is None:
            R = self.model.R[np.ix_(idx, idx)]
            r = np.diag(R).copy()
            if np.count_nonzero(R - np.diag(r)) == 0:
                terms = (R, -0.5 / r, True)
            else:
                L = cholesky(R)
                if L is None:
                    raise FilterDivergence("measurement covariance R is not positive definite")
                terms = (R, L, False)
            self._lik_cache[key] = terms
        return terms

    def update(self, z, mask=None) -> None:
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        z = np.asarray(z, dtype=float)[idx]
        Z = np.asarray(self.model.h_batch(self.particles.T))  # Z_i = h(X_i)
        Zt = Z.T[idx] if idx.size < Z.shape[1] else Z.T  # (p, N)
        R, lik, diagonal = self._likelihood_terms(idx)
        # NIS of the predicted measurement distribution (prior weights)
        w = self._w
        zhat = Zt @ w
        D = Zt - zhat[:, None]
        S = (D * w) @ D.T + R  # S = sum w_i (Z_i - zhat)(Z_i - zhat)' + R
        LS = cholesky(S)
        if LS is None:
            S, LS = repair_pd(S, self.diagnostics)
        y = z - zhat
        self.diagnostics["nis"] = float(y @ cho_solve((LS, True), y))
        self.diagnostics["nis_dof"] = float(idx.size)
        # log-likelihood -1/2 e' R^-1 e of every particle, e = z - h(X_i)
        D -= y[:, None]  # D = Z_i - z = -e
        if diagonal:
            D *= D
            ll = lik @ D
        else:
            Wh = solve_triangular(lik, D, lower=True, check_finite=False)
            ll = -0.5 * np.einsum("ij,ij->j", Wh, Wh)
        logw = self.logw + ll  # log w_i += log p(z | X_i)
        top = logw.max()
        if not np.isfinite(top):
            raise FilterDivergence("pf weights are NaN or all zero")
        w = np.exp(logw - top)
        total = w.sum()
        w /= total
        logw -= top + math.log(total)  # normalized log weights
        ess = 1.0 / (w @ w)  # ESS = 1 / sum w_i^2
        self.diagnostics["ess"] = float(ess)
        resampled = ess < self.ess_threshold * self.n
        if resampled:
            self.particles = self.particles[:, self.resample(w, self.rng)]
            w = np.full(self.n, 1.0 / self.n)
            logw = np.full(self.n, -math.log(self.n))
            if self.roughening > 0.0:
                self._roughen()
        self._w, self.logw = w, logw
        self.diagnostics["resampled"] = float(resampled)
        self._moments_stale = True

    def _roughen(self) -> None:
        Xp = self.particles
        spread = Xp.max(axis=1) - Xp.min(axis=1)  # E_j
        sigma = self.roughening * spread * self.n ** (-1.0 / Xp.shape[0])  # K E_j N^(-1/d)
        Xp += sigma[:, None] * self.rng.standard_normal(Xp.shape)
