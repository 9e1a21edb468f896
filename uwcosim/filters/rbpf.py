"""Marginalized (Rao-Blackwellized) particle filter (``rbpf``).

Schön, Gustafsson & Nordlund, "Marginalized particle filters for mixed linear/nonlinear
state-space models", IEEE TSP 53(7), 2005; Gustafsson et al., "Particle filters for
positioning, navigation and tracking", IEEE TSP 50(2), 2002 (terrain navigation). The state is
split into *particle* states ``p`` and *linear* states ``k``: by default the states measured by
affine measurement rows (the DVL's velocities, seed 000 eq. 55) and not by a nonlinear one (the
terrain depth's position), for a model of the form::

    p' = f_p(p) + A k + n_p,      k' = F_k k + b_k + n_k,      [n_p; n_k] ~ N(0, Q)
    z  = [H k + c; h(p)] + e,     e ~ N(0, R)  (R block-diagonal between the two groups)

with ``A``, ``F_k``, ``H`` and ``Q`` independent of the state (they may depend on the control
and the step). Each particle carries ``p_i`` and the mean ``m_i`` of a Kalman filter on ``k``;
since no matrix depends on ``p``, the Kalman covariance ``P`` is the same for every particle and
is propagated once per step (the per-particle filters are vectorized over particles).

One step, exact for this model (the joint Gaussian of ``(p', k')`` given ``(p_i, m_i, P)``):

1. ``p'_i ~ N(f_p(p_i) + A m_i, S_pp)`` with ``S_pp = A P A' + Q_pp`` (the marginal prediction
   of the particle states: the bootstrap proposal of the marginalized filter);
2. ``k'`` conditioned on the drawn ``p'_i`` (Schön et al.'s "measurement update with the
   nonlinear dynamics"): ``m'_i = F_k m_i + b_k + S_kp S_pp^-1 (p'_i - f_p(p_i) - A m_i)``,
   ``P' = S_kk - S_kp S_pp^-1 S_pk``, ``S_kp = F_k P A' + Q_kp``, ``S_kk = F_k P F_k' + Q_kk``;
3. weights ``w_i *= N(z_k; H m'_i + c, H P' H' + R_k) N(z_p; h(p'_i), R_p)``;
4. Kalman update of every ``m'_i`` with the common gain ``K = P' H' (H P' H' + R_k)^-1``;
5. resampling (ESS-triggered) of ``(p_i, m_i)`` together.

The estimate is the mixture's mean and covariance: ``x = sum w_i [p_i; m_i]``,
``P = sum w_i (X_i - x)(X_i - x)' + blockdiag(0, P)``.

The split is found numerically from the model's Jacobians at a few points around ``x0`` (a
measurement row whose Jacobian varies is nonlinear; the states the affine rows measure and no
nonlinear row involves are candidates; a candidate stays linear when its dynamics rows involve
linear states only and its Jacobian row and column are constant), or given by
``linear_states``. Without a nonlinear measurement (the TAN model
without terrain) the filter is a mixture of Kalman filters whose particles only carry the
position.

Resampling schemes and the block-drawn normals come from :mod:`uwcosim.filters.particle`.

Speed: with Numba (``UWCOSIM_NUMBA`` not ``0``) the small-matrix algebra of each half step and
the per-particle work that goes with it are one compiled call each
(:mod:`uwcosim.filters.rbpf_kernels`, the same maths with a different rounding); a matrix
that is not positive definite sends that step to the numpy code and its repairs. ``fast``
says which path runs.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, StrictStr
from scipy.linalg import lapack

from uwcosim.core.errors import FilterDivergence
from uwcosim.filters import rbpf_kernels as rk
from uwcosim.filters.base import register
from uwcosim.filters.numerics import (
    linearize,
    psd_factor,
    repair_pd,
    symmetrize,
)
from uwcosim.filters.particle import ParticleCloud
from uwcosim.filters.settings import Measurements, measurements_field

_trtri = lapack.dtrtri
_potrf = lapack.dpotrf


def block_slice(idx: list[int]):
    """A basic slice for contiguous indices (cheaper than fancy indexing), else an array."""
    if idx and list(idx) == list(range(idx[0], idx[0] + len(idx))):
        return slice(idx[0], idx[0] + len(idx))
    return np.asarray(idx, dtype=np.intp)


def block_pair(rows: list[int], cols: list[int]):
    """Index of the block ``rows x cols``: two slices when both are contiguous, else ``ix_``."""
    r, c = block_slice(rows), block_slice(cols)
    if isinstance(r, slice) and isinstance(c, slice):
        return r, c
    return np.ix_(rows, cols)


def _split(model, x0, P0, use, linear_states, names) -> tuple[list[int], list[int]]:
    """``(particle states, linear states)`` of the model (see the module docstring)."""
    nx = model.nx
    if linear_states is not None:
        k = []
        for s in linear_states:
            if s not in names:
                raise ValueError(f"unknown state {s!r} in linear_states "
                                 f"(valid: {', '.join(names)})")
            k.append(names.index(s))
        k = sorted(set(k))
        return [i for i in range(nx) if i not in k], k
    rng = np.random.default_rng(0)  # local and fixed: the split must not depend on a seed
    sd = np.sqrt(np.maximum(np.diag(P0), 0.0))
    pts = [x0 + sd * rng.standard_normal(nx) * 3.0 for _ in range(4)]
    Hs = np.array([model.H(x) for x in pts])[:, use]
    nonlin = np.any(np.abs(Hs - Hs[0]) > 1e-12 * (1.0 + np.abs(Hs[0])), axis=0).any(axis=1)
    on_nonlin = {j for r in np.flatnonzero(nonlin) for j in np.flatnonzero(Hs[0, r])}
    k = {j for r in np.flatnonzero(~nonlin) for j in np.flatnonzero(Hs[0, r])} - on_nonlin
    u = np.zeros(getattr(model, "nu", 0))
    Fs = np.array([linearize(model, x, u, 1.0)[0] for x in pts])
    vary = np.any(np.abs(Fs - Fs[0]) > 1e-12 * (1.0 + np.abs(Fs[0])), axis=0)
    changed = True
    while changed:
        changed = False
        for j in sorted(k):
            outside = [i for i in range(nx) if i not in k and Fs[0, j, i] != 0.0]
            if outside or vary[:, j].any() or vary[j].any():
                k.discard(j)
                changed = True
    k = sorted(k)
    return [i for i in range(nx) if i not in k], k


@register("rbpf")
class RaoBlackwellizedPF(ParticleCloud):
    """Marginalized particle filter: particles on the nonlinear states, one Kalman filter per
    particle (common covariance) on the linear-Gaussian ones.

    The linear states are found from the model unless ``linear_states`` names them.
    """

    class Settings(ParticleCloud.Settings):
        linear_states: list[StrictStr] | None = Field(
            None, description="the Kalman (marginalized) states (default: from the model)")
        measurements: Measurements = measurements_field()

    def __init__(self, model, x0, P0, **kw) -> None:
        super().__init__(model, x0, P0, **kw)
        linear_states = self.settings.linear_states
        self._init_cloud()
        self._x_stale = self._P_stale = False  # x0 and P0 until the particles are drawn
        m = self.model
        n = self.n
        names = tuple(m.state_names)
        self.ip, self.ik = _split(m, self.x, self.P, self._use, linear_states, names)
        ip, ik = self.ip, self.ik
        if not ip:
            raise ValueError("rbpf: every state is linear-Gaussian; use the Kalman filter 'kf'")
        if not ik and linear_states is None:
            raise ValueError("rbpf: the model has no linear-Gaussian sub-state (states with "
                             "linear dynamics of their own, measured only by linear rows); "
                             "name them in linear_states, or use 'pf'")
        # measurement rows: on the linear states only (affine, constant) or on particle states
        H0 = m.H(self.x)
        self.rows_k = [r for r in range(m.nz) if not np.any(H0[r, ip])]
        self.rows_p = [r for r in range(m.nz) if r not in self.rows_k]
        mixed = [m.measurement_names[r] for r in self.rows_p if ik and np.any(H0[r, ik])]
        if mixed:
            raise ValueError(f"rbpf: measurements {mixed} depend on both particle and linear "
                             "states (set linear_states)")
        if self.rows_k and self.rows_p and np.any(m.R[np.ix_(self.rows_k, self.rows_p)]):
            raise ValueError("rbpf: R must be block-diagonal between the measurements of the "
                             "linear states and the others")
        self._Hk = H0[np.ix_(self.rows_k, ik)] if self.rows_k else np.zeros((0, len(ik)))
        self._kalman_row = np.zeros(m.nz, dtype=bool)
        self._kalman_row[self.rows_k] = True
        # particles, state-major: particle states drawn from N(x0, P0)_p, and the linear
        # states' conditional means given them (exact conditioning of the Gaussian prior)
        P = self.P
        Lp = psd_factor(P[np.ix_(ip, ip)])
        dev = Lp @ self.rng.standard_normal((len(ip), n))
        self.particles = np.empty((m.nx, n))
        self.particles[ip] = self.x[ip, None] + dev
        if ik:
            Ppp, Pkp = P[np.ix_(ip, ip)], P[np.ix_(ik, ip)]
            G = np.linalg.lstsq(Ppp, Pkp.T, rcond=None)[0].T  # P_kp P_pp^-1
            self.particles[ik] = self.x[ik, None] + G @ dev
            self.Pk = symmetrize(P[np.ix_(ik, ik)] - G @ Pkp.T)
        else:
            self.Pk = np.zeros((0, 0))
        self.Pk = np.ascontiguousarray(self.Pk)  # the kernels update it in place
        self._x_stale = self._P_stale = True
        self._sp, self._sk = block_slice(ip), block_slice(ik)
        self._kk = block_pair(ik, ik)
        perm = ip + ik
        self._perm = None if perm == list(range(m.nx)) else np.asarray(perm, dtype=np.intp)
        self._nkp = len(ip)
        self._Paug = np.zeros((m.nx, m.nx))
        self._eye_k = np.eye(len(ik))
        self._block_cache: dict[bytes, tuple] = {}
        self._D = np.empty_like(self.particles)  # centred particles, for P
        self._half = np.full(m.nz, 0.5)
        self.fast = bool(rk.ENABLED)  # compiled kernels (else the numpy code below)
        self._perm_idx = np.asarray(perm, dtype=np.intp)
        self._sk_idx = np.asarray(ik, dtype=np.intp)
        self._Lbuf = np.zeros((m.nx, m.nx))
        self._ll = np.empty(n)  # log-likelihoods
        self._row = np.empty(n)  # scratch row of the prediction kernel
        self._kernel_cache: dict[bytes, tuple] = {}

    def _conditional_cov(self, P: np.ndarray) -> np.ndarray:
        """The particles' covariance plus the common Kalman covariance of the linear states."""
        if self.ik:
            P[self._kk] += self.Pk
        return P

    # filter -------------------------------------------------------------------------------
    def predict(self, u, dt: float) -> None:
        """Steps 1-2 with one Cholesky factorization of the joint prediction covariance
        ``S = F blockdiag(0, P) F' + Q`` ordered ``(p, k)``: its factor ``[[L_p, 0],
        [L_kp, L_k]]`` gives ``p' - E[p'] = L_p e``, the conditioned linear means
        ``S_kp S_pp^-1 (p' - E[p']) = L_kp e`` and ``P' = L_k L_k'`` (the Schur complement)."""
        self._begin_predict()
        F, Q = linearize(self.model, self.x, u, dt)
        X = np.asarray(self.model.f_batch(self.particles.T, u, dt)).T  # means (a new array)
        n_p = self._nkp
        e = self._standard_normals(n_p)
        if self.fast:
            done, finite = rk.predict_step(F, Q, self.Pk, self._perm_idx, n_p, e, X,
                                           self._Lbuf, self.Pk, self._row)
            if done:
                if not finite:
                    raise FilterDivergence("rbpf prediction contains NaN or inf")
                self.particles = X
                self._moved()
                return
        Pt = self._Paug  # blockdiag(0, P) in (p, k) order
        Pt[self._nkp:, self._nkp:] = self.Pk
        Fp = F if self._perm is None else F[np.ix_(self._perm, self._perm)]
        Qp = Q if self._perm is None else Q[np.ix_(self._perm, self._perm)]
        S = Fp @ Pt @ Fp.T
        S += Qp
        L, info = _potrf(S, lower=1, clean=1)
        if info == 0:
            noise = L[:, :n_p] @ e
            Lk = L[n_p:, n_p:]
            self.Pk = np.ascontiguousarray(Lk @ Lk.T)
        else:  # singular: pseudo-inverse conditioning
            S = symmetrize(S)
            Spp, Skp = S[:n_p, :n_p], S[n_p:, :n_p]
            delta = psd_factor(Spp) @ e
            G = Skp @ np.linalg.pinv(Spp)  # S_kp S_pp^-1
            noise = np.vstack((delta, G @ delta))
            self.Pk = np.ascontiguousarray(symmetrize(S[n_p:, n_p:] - G @ Skp.T))
        if self._perm is None:
            X += noise
        else:
            X[self._perm] += noise
        if not math.isfinite(float(X.sum())):
            raise FilterDivergence("rbpf prediction contains NaN or inf")
        self.particles = X
        self._moved()

    def _blocks(self, idx: np.ndarray):
        """Per set of available rows: ``(template of M with R in place, positions of the Kalman
        rows (a slice when contiguous), H_k, index of their block)``."""
        key = idx.tobytes()
        out = self._block_cache.get(key)
        if out is None:
            kal = self._kalman_row[idx]
            kpos = np.flatnonzero(kal)
            rows = [self.rows_k.index(int(r)) for r in idx[kal]]
            m = idx.size
            nk = len(self.ik) if kpos.size else 0  # no Kalman row: the linear block stays
            M0 = np.zeros((m + nk, m + nk))
            M0[:m, :m] = self.model.R[np.ix_(idx, idx)]
            kk = block_pair(list(kpos), list(kpos))
            out = (M0, block_slice(list(kpos)), self._Hk[rows], kk, kpos.size > 0)
            self._block_cache[key] = out
        return out

    def update(self, z, mask=None) -> None:
        """Steps 3-5. One Cholesky factorization of ``M = [[C, H_k P], [P H_k', P]]``, ``C``
        the per-particle predictive covariance of the available rows (``H_k P H_k' + R_k`` on
        the Kalman rows, ``R_p`` on the others): with ``M = L L'``, ``L_11^-1 E`` whitens the
        residuals (the log-likelihoods), ``L_21 L_11^-1 E`` is every particle's Kalman
        correction ``K (zhat_i - z)`` and ``L_22 L_22'`` the updated covariance."""
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        z = np.asarray(z, dtype=float)
        Zt = np.asarray(self.model.h_batch(self.particles.T)).T  # (nz, N) predicted means
        if self.fast and self._update_compiled(Zt, z, idx):
            return
        if idx.size < Zt.shape[0]:
            Zt, z = Zt[idx], z[idx]
        E = Zt - z[:, None]  # E_i = zhat_i - z
        M0, kpos, Hk, kk, kalman = self._blocks(idx)
        m = idx.size
        M = M0.copy()
        if kalman:
            HP = Hk @ self.Pk
            M[kpos, m:] = HP
            M[m:, kpos] = HP.T
            M[kk] += HP @ Hk.T
            M[m:, m:] = self.Pk
        L, info = _potrf(M, lower=1, clean=1)
        if info != 0:  # repair the predictive block, then factor again
            C, _ = repair_pd(M[:m, :m], self.diagnostics)
            M[:m, :m] = C
            M = symmetrize(M) + 1e-12 * np.mean(np.diag(M)) * np.eye(M.shape[0])
            L, info = _potrf(M, lower=1, clean=1)
            if info != 0:
                raise FilterDivergence("rbpf: measurement update covariance is not definite")
        L11 = L[:m, :m]
        C = M[:m, :m]
        self._predictive_nis(E, C, m)  # mixture with the prior weights
        Li, info = _trtri(L11, lower=1)
        if info != 0:  # pragma: no cover - L11 is a Cholesky factor
            raise FilterDivergence("rbpf: singular measurement covariance")
        W = Li @ E  # whitened residuals
        if kalman:  # every particle's Kalman correction, common gain
            self.particles[self._sk] -= L[m:, :m] @ W
            L22 = L[m:, m:]
            self.Pk = np.ascontiguousarray(L22 @ L22.T)
        W *= W
        self._reweight(-(self._half[:m] @ W))  # log w_i += log N(z; zhat_i, C) + const

    def _update_compiled(self, Zt: np.ndarray, z: np.ndarray, idx: np.ndarray) -> bool:
        """:meth:`update` by :func:`~uwcosim.filters.rbpf_kernels.update_step`; False (nothing
        changed) when a matrix is not positive definite: the numpy code then repairs it."""
        key = idx.tobytes()
        b = self._kernel_cache.get(key)
        if b is None:
            M0, kpos, Hk, _, kalman = self._blocks(idx)
            m = idx.size
            q = M0.shape[0]
            kp = np.arange(m, dtype=np.intp)[kpos]
            b = (np.ascontiguousarray(M0[:m, :m]), np.ascontiguousarray(Hk), kp, q - m,
                 np.zeros((6, q, q)), np.empty((2 * m + 1, self.n)))
            self._kernel_cache[key] = b
        R, Hk, kp, nkb, small, work = b
        code, nis = rk.update_step(Zt, z, idx, R, Hk, kp, self.Pk, nkb, self._w,
                                   self.particles, self._sk_idx, small, work, self._ll)
        if code:
            return False
        self.diagnostics["nis"] = nis
        self.diagnostics["nis_dof"] = float(idx.size)
        self._reweight(self._ll)
        return True
