"""Bootstrap particle filter (``pf``) and the resampling schemes (:data:`RESAMPLERS`).

Gordon, Salmond & Smith (1993): particles drawn from ``N(x0, P0)``, moved by the transition
``f`` plus process noise sampled from ``N(0, Q)``, weighted by the measurement likelihood
``N(z; h(x), R)`` (log weights), resampled when the effective sample size
``ESS = 1 / sum w_i^2`` falls below ``ess_threshold * N``, optionally roughened. The estimate is
the weighted mean and covariance of the particles.

Process noise: ``Q`` is additive and sampled through a factor ``L L' = Q``: the model's own
(``model.Q_factor(x, u, dt)``, e.g. ``G diag(q/dt)^(1/2)`` for the TAN model) or the Cholesky
factor of ``model.Q`` (the eigen-decomposition when ``Q`` is singular), evaluated at the
weighted mean. When ``Q`` does not depend on the state (``model.Q_depends_on_x`` false, as for
the TAN and linear models) the factor is computed once per ``(u, dt)`` and reused.

Speed (``benchmarks/bench_filters.py``: the 1000-particle step of the TAN model in about
100 us median, 125 us mean, against 155 and 165 before these measures):

* particles are stored state-major (``(nx, N)``, every state a contiguous row); the model's
  batch functions get column-major views and the numpy fast path of the TAN model is used
  (:mod:`uwcosim.models.tan`);
* the standard normals of the process noise are drawn for 64 steps at once
  (:func:`standard_normals`, Box-Muller: 16 us per step against 38 for
  ``rng.standard_normal``) and consumed one step at a time; the draw falls on one step in 64,
  which the median does not see and the mean does;
* the weights stay normalized in log space, so ``exp(log w + log p(z | X))`` cannot overflow
  and the usual max-shift of the log-sum-exp is only needed when every weight underflows;
* the Gaussian log-likelihood of a diagonal ``R`` is one matrix-vector product, and the NIS of
  the predicted measurement uses the same residuals;
* the mean is one matrix-vector product, computed when ``x`` is read; the covariance one
  matrix product on a preallocated buffer, computed when ``P`` is read;
* systematic resampling counts the copies of each particle from the cumulative weights (no
  search) and gathers with ``take``.

Randomness: only the ``numpy.random.Generator`` given as ``rng`` or created from ``seed``
(``seed`` wins when both are given, so a scenario can pin one filter); none: a fresh,
unseeded generator. A seed fixes the whole run: the noise blocks are drawn from the same
generator in the same order whatever is read in between.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np
from pydantic import Field, StrictFloat, StrictInt
from scipy.linalg import solve_triangular

from uwcosim.core.errors import FilterDivergence
from uwcosim.core.memory import memory_problem
from uwcosim.core.registry import Registry
from uwcosim.filters.base import FilterBase, register
from uwcosim.filters.numerics import cholesky, psd_factor, repair_pd
from uwcosim.filters.robust import StudentTNu, student_t_field, student_t_loglik
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field

Resampler = Callable[[np.ndarray, np.random.Generator], np.ndarray]
RESAMPLERS: Registry[Resampler] = Registry("resampling scheme")

NOISE_BLOCK_STEPS = 64  # steps of process noise drawn per call to the generator
NOISE_BLOCK_MAX = 2**18  # ... but at most this many normals (2 MB) per block
_TWO_PI32 = np.float32(2.0 * math.pi)
_TINY = 1e-250  # below this sum of exp(log w) the weights are renormalized by their maximum


def standard_normals(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Independent ``N(0, 1)`` draws of the given shape by the Box-Muller transform.

    ``(r cos t, r sin t)`` with ``r = sqrt(-2 log(1 - u1))``, ``t = 2 pi u2`` from two
    uniforms of ``rng.random``. The radius is computed in double precision (``u1`` has 53 bits:
    the tails reach 8.5 sigma, probability 1e-17 beyond); the angle in single precision (numpy
    vectorizes the float32 cosine but not the float64 one; ``u2`` has 24 bits), so each draw
    carries a relative rounding error of about 1e-7, far below any Monte Carlo error. About
    4 ns per draw in blocks against 9.5 for ``rng.standard_normal`` on the benchmark machine.
    """
    size = math.prod(shape)
    half = (size + 1) // 2
    r = rng.random(half)
    np.subtract(1.0, r, out=r)  # (0, 1]: log is finite
    np.log(r, out=r)
    r *= -2.0
    np.sqrt(r, out=r)
    t = rng.random(half, dtype=np.float32)
    t *= _TWO_PI32
    out = np.empty(2 * half)
    out[:half] = np.cos(t)
    out[half:] = np.sin(t)
    out[:half] *= r
    out[half:] *= r
    return out[:size].reshape(shape)


def _search(w: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Indices ``i`` with ``cumsum(w)[i-1] < position <= cumsum(w)[i]``."""
    cs = np.cumsum(w)
    cs[-1] = 1.0  # guard against round-off: every position in [0, 1) finds a particle
    return np.searchsorted(cs, positions, side="right").clip(max=w.size - 1)


@RESAMPLERS.register("systematic")
def systematic(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform offset ``U``, ``N`` evenly spaced positions ``(U + k) / N`` (lowest variance,
    O(N)).

    Particle ``i`` gets the positions below ``c_i = cumsum(w)_i`` and not below ``c_{i-1}``:
    ``#{k : (U + k) / N < c} = clip(ceil(N c - U), 0, N)``, so the copies are counted from
    the cumulative weights without a search.
    """
    n = w.size
    c = np.cumsum(w)
    c *= n
    c -= rng.random()
    np.ceil(c, out=c)
    np.maximum(c, 0.0, out=c)
    np.minimum(c, n, out=c)  # (np.clip is several times slower on small arrays)
    c[-1] = n  # guard against round-off: every position finds a particle
    k = np.zeros(n + 1, dtype=np.intp)
    k[1:] = c
    return np.repeat(np.arange(n), k[1:] - k[:-1])


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


def quad_form(L: np.ndarray, y: np.ndarray) -> float:
    """``y' (L L')^-1 y`` for a lower triangular ``L`` (forward substitution; the few
    measurement components of a step make plain floats cheaper than a LAPACK call)."""
    rows, b = L.tolist(), y.tolist()
    acc = 0.0
    for i, row in enumerate(rows):
        s = b[i]
        for j in range(i):
            s -= row[j] * b[j]
        s /= row[i]
        b[i] = s
        acc += s * s
    return acc


#: the resampling schemes by name, as a setting (the same names as :data:`RESAMPLERS`)
Resampling = Literal["systematic", "stratified", "residual", "multinomial"]


class ParticleCloud(FilterBase):
    """Weighted particles, state-major (row ``j`` holds state ``j`` of every particle), with
    normalized log weights and the estimate computed when read (once per step): what the
    particle filters (``pf``, ``rpf``, ``rbpf``) share. Subclasses call :meth:`_init_cloud`,
    draw ``self.particles`` and add to :meth:`_conditional_cov` what the particles do not
    carry (the RBPF's Kalman covariance)."""

    class Settings(FilterSettings):
        """What the particle filters (``pf``, ``rbpf``, ``rpf``) share."""

        n_particles: StrictInt = Field(1000, ge=2, description="number of particles")
        resampling: Resampling = Field("systematic", description="resampling scheme")
        ess_threshold: StrictFloat = Field(0.5, ge=0, le=1, description="resample when the "
                                           "effective sample size falls below this fraction "
                                           "of N")

    needs_rng = True

    def _init_cloud(self) -> None:
        s = self.settings
        n = s.n_particles
        # per particle: the cloud and its centred copy, the prediction's draws and
        # temporaries (about 4 nx), weights, log-likelihoods, resampling indices, the
        # measurement residuals (about 2 nz): estimated before any of it is allocated
        nx, nz = self.model.nx, getattr(self.model, "nz", 1)
        why = memory_problem(float(n) * 8.0 * (6 * nx + 2 * nz + 12),
                             f"n_particles {n}", "use fewer particles")
        if why:
            raise ValueError(why)
        self.resample = RESAMPLERS.get(s.resampling)
        self.n = n
        self.ess_threshold = s.ess_threshold
        self.logw = np.full(n, -math.log(n))  # normalized log weights, updated in place
        self._w = np.full(n, 1.0 / n)
        self._normals: np.ndarray | None = None  # block of standard normals, (steps, nw, N)
        self._next_normals = 0
        self._x_stale = self._P_stale = True

    # estimate -----------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        if getattr(self, "_x_stale", False):
            self._x = self.particles @ self._w  # x = sum w_i X_i
            self._x_stale = False
        return self._x

    @x.setter
    def x(self, value) -> None:
        self._x = value

    @property
    def P(self) -> np.ndarray:
        if getattr(self, "_P_stale", False):
            D = np.subtract(self.particles, self.x[:, None], out=self._D)
            P = (D * self._w) @ D.T  # P = sum w_i (X_i - x)(X_i - x)'
            P += P.T
            P *= 0.5
            self._P = self._conditional_cov(P)
            self._P_stale = False
        return self._P

    @P.setter
    def P(self, value) -> None:
        self._P = value

    def _conditional_cov(self, P: np.ndarray) -> np.ndarray:
        """``P`` plus the covariance the particles do not carry (none here)."""
        return P

    @property
    def weights(self) -> np.ndarray:
        """Normalized particle weights (a copy)."""
        return self._w.copy()

    def _moved(self) -> None:
        self._x_stale = self._P_stale = True

    # update -------------------------------------------------------------------------------
    def _predictive_nis(self, E: np.ndarray, C: np.ndarray, dof: int) -> None:
        """NIS ``y' S^-1 y`` of the predicted measurement distribution (prior weights), from
        the particles' residuals ``E_i = zhat_i - z`` and the covariance ``C`` of each one:
        ``y = -sum w_i E_i``, ``S = sum w_i E_i E_i' - y y' + C`` (the sign of y does not
        matter)."""
        w = self._w
        y = E @ w
        S = (E * w) @ E.T
        S -= y[:, None] * y
        S += C
        LS = cholesky(S)
        if LS is None:
            S, LS = repair_pd(S, self.diagnostics)
        self.diagnostics["nis"] = quad_form(LS, y)
        self.diagnostics["nis_dof"] = float(dof)

    def _reweight(self, ll: np.ndarray) -> None:
        """``log w_i += ll_i`` (log-likelihoods), normalize, and resample when the effective
        sample size falls below ``ess_threshold * N``. The log weights were normalized and the
        log-likelihoods are <= 0, so exp cannot overflow; the maximum is only subtracted when
        the weights underflow (or are NaN, which it reports)."""
        w, logw = self._w, self.logw
        logw += ll
        np.exp(logw, out=w)
        total = float(w.sum())
        if total > _TINY:
            shift = math.log(total)
        else:
            top = float(logw.max())
            if not math.isfinite(top):
                raise FilterDivergence("particle weights are NaN or all zero")
            np.subtract(logw, top, out=w)
            np.exp(w, out=w)
            total = float(w.sum())
            shift = top + math.log(total)
        w *= 1.0 / total
        logw -= shift  # normalized log weights
        ess = 1.0 / float(w @ w)  # ESS = 1 / sum w_i^2
        self.diagnostics["ess"] = ess
        # ess_threshold 1 resamples every step: ESS = N (equal weights) may round either way
        resampled = self.ess_threshold >= 1.0 or ess < self.ess_threshold * self.n
        if resampled:
            self.particles = self.particles.take(self.resample(w, self.rng), axis=1)
            w.fill(1.0 / self.n)
            logw.fill(-math.log(self.n))
            self._after_resample()
        self.diagnostics["resampled"] = float(resampled)
        self._moved()

    def _after_resample(self) -> None:
        """What a filter does right after resampling (nothing here)."""

    def _standard_normals(self, nw: int) -> np.ndarray:
        """``(nw, N)`` standard normals for one step, from a block drawn for several."""
        block, k = self._normals, self._next_normals
        if block is None or k == block.shape[0] or block.shape[1] != nw:
            steps = max(1, min(NOISE_BLOCK_STEPS, NOISE_BLOCK_MAX // (nw * self.n)))
            block = self._normals = standard_normals(self.rng, (steps, nw, self.n))
            k = 0
        self._next_normals = k + 1
        return block[k]


@register("pf")
class ParticleFilter(ParticleCloud):
    """Bootstrap particle filter.

    ``ess_threshold`` 1 resamples every step, 0 never; ``roughening`` is Gordon et al.'s ``K``:
    after resampling add ``N(0, (K E_j N^(-1/nx))^2)`` to state ``j``, ``E_j`` the particles'
    range. ``x`` and ``P`` are the weighted mean and covariance, computed when read (once per
    step).
    """

    class Settings(ParticleCloud.Settings):
        roughening: StrictFloat = Field(0.0, ge=0, description="Gordon et al.'s K: jitter "
                                        "after resampling (0 = off)")
        measurements: Measurements = measurements_field()
        student_t_nu: StudentTNu = student_t_field()  # filters.robust

    def __init__(self, model, x0, P0, **kw) -> None:
        super().__init__(model, x0, P0, **kw)
        L = psd_factor(self.P)  # P0 may be singular (a state known exactly); read before
        x = self.x  # the cloud makes x and P lazy
        self._init_cloud()
        # the regularized PF (rpf) has no roughening: it draws from a kernel instead
        self.roughening = getattr(self.settings, "roughening", 0.0)
        # particles, state-major: row j holds state j of every particle
        self.particles = x[:, None] + L @ self.rng.standard_normal((model.nx, self.n))
        self._D = np.empty_like(self.particles)  # centred particles, for P
        self._xdep = getattr(self.model, "Q_depends_on_x", True)
        self._Q_factor = getattr(self.model, "Q_factor", None)
        self._noise_key: tuple | None = None
        self._lik_cache: dict[bytes, tuple] = {}
        self._nu = getattr(self.settings, "student_t_nu", None)  # robust likelihood

    # filter -------------------------------------------------------------------------------
    def _noise_factor(self, u, dt: float) -> np.ndarray:
        key = (np.asarray(u, dtype=float).tobytes(), float(dt))
        if self._xdep or key != self._noise_key:
            if self._Q_factor is not None:
                self._L = self._Q_factor(self.x, u, dt)
            else:
                self._L = psd_factor(self.model.Q(self.x, u, dt))
            self._noise_key = key
        return self._L

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        L = self._noise_factor(u, dt)
        Xn = np.asarray(self.model.f_batch(self.particles.T, u, dt)).T  # X_i = f(X_i, u)
        X = L @ self._standard_normals(L.shape[1])  # w_i ~ N(0, Q)
        X += Xn
        if not math.isfinite(X.sum()):  # NaN or inf anywhere makes the sum non-finite
            raise FilterDivergence("pf prediction contains NaN or inf")
        self.particles = X
        self._moved()

    def _likelihood_terms(self, idx: np.ndarray):
        """``(R_idx, -1/(2 r), True)`` for a diagonal block, ``(R_idx, L, False)`` (Cholesky)
        otherwise."""
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
        z = np.asarray(z, dtype=float)
        Zt = np.asarray(self.model.h_batch(self.particles.T)).T  # (nz, N): Z_i = h(X_i)
        if idx.size < Zt.shape[0]:
            z, Zt = z[idx], Zt[idx]
        R, lik, diagonal = self._likelihood_terms(idx)
        E = Zt - z[:, None]  # E_i = h(X_i) - z = -e_i
        # NIS y' S^-1 y of the predicted measurement distribution (prior weights): with
        # y = z - zhat = -sum w_i E_i, S = sum w_i (Z_i - zhat)(Z_i - zhat)' + R
        # = sum w_i E_i E_i' - y y' + R (the sign of y does not matter)
        self._predictive_nis(E, R, idx.size)
        # log-likelihood -1/2 e' R^-1 e of every particle
        if self._nu is not None:  # Student-t per component (filters.robust)
            if not diagonal:
                raise ValueError("student_t_nu needs a diagonal measurement covariance R")
            E *= E
            ll = student_t_loglik(E, np.diag(R)[:, None], self._nu).sum(axis=0)
        elif diagonal:
            E *= E
            ll = lik @ E
        else:
            Wh = solve_triangular(lik, E, lower=True, check_finite=False)
            ll = -0.5 * np.einsum("ij,ij->j", Wh, Wh)
        self._reweight(ll)

    def _after_resample(self) -> None:
        if self.roughening > 0.0:
            self._roughen()

    def _roughen(self) -> None:
        Xp = self.particles
        spread = Xp.max(axis=1) - Xp.min(axis=1)  # E_j
        sigma = self.roughening * spread * self.n ** (-1.0 / Xp.shape[0])  # K E_j N^(-1/d)
        Xp += sigma[:, None] * self.rng.standard_normal(Xp.shape)
