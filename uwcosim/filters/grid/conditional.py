"""The conditional Kalman filter of the non-gridded states of the grid filters.

:class:`ConditionalKalman` runs the Kalman filter of the ``k`` block of a
:class:`~uwcosim.filters.grid.partition.Partition` conditionally on the mean of the gridded
block, and returns the increment of the gridded block over a step with its covariance: the
velocity uncertainty becomes extra diffusion of the position, inflated to the *long-run*
covariance of the velocity error (see :meth:`ConditionalKalman.increment`).
:func:`assemble_estimate` joins the two blocks into the filter's ``(x, P)``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.linalg import lapack

from uwcosim.core.errors import FilterDivergence
from uwcosim.filters.grid import projection_kernels as pk
from uwcosim.filters.grid.partition import Partition
from uwcosim.filters.numerics import cholesky, kalman_gain, nis, symmetrize

_gesv = lapack.dgesv


def block_index(rows: list[int], cols: list[int] | None = None):
    """Index of ``rows`` (and ``cols``): basic slices when contiguous (cheaper than fancy
    indexing on the small matrices of every step), else integer arrays / ``np.ix_``."""

    def one(idx):
        if idx and list(idx) == list(range(idx[0], idx[0] + len(idx))):
            return slice(idx[0], idx[0] + len(idx))
        return np.asarray(idx, dtype=np.intp)

    if cols is None:
        return one(rows)
    r, c = one(rows), one(cols)
    if isinstance(r, slice) and isinstance(c, slice):
        return r, c
    return np.ix_(rows, cols)


class Increment(NamedTuple):
    """Increment of the gridded block over a step, at the mean of the other states."""

    d: np.ndarray  # mean increment f(x)_p - x_p
    D: np.ndarray  # its covariance Q_pp + F_pk S F_pk'
    Dk: np.ndarray  # the part due to the Kalman states, F_pk S F_pk'
    F: np.ndarray  # Jacobian of the one-step map at the mean


class ConditionalKalman:
    """Kalman filter of the ``k`` block, conditionally on the mean of the gridded block.

    The joint density is approximated by ``p(x_p) N(x_k; mean, cov)`` (cross-covariance
    neglected). Over a step the gridded block moves by ``d = f(x)_p - x_p`` at the mean, with
    covariance ``Q_pp + F_pk S F_pk'``. ``S`` is the long-run covariance of the Kalman error
    ``e_k`` (``sum over lags of Cov(e_k, e_{k+l})``): the error of a filtered velocity is
    correlated from step to step (``e_{k+1} = Phi e_k + noise``, ``Phi = (I - K H) F``), so the
    position error it integrates grows like ``S`` per step, not like the one-step ``P``:
    ``S = (I - Phi)^-1 P + P (I - Phi')^-1 - P``. With ``long_run=False``, ``S = P``.
    """

    def __init__(self, model, part: Partition, x0, P0, long_run: bool = True) -> None:
        self.model = model
        self.p, self.k = part.p, part.k
        self.rows = part.rows_kalman
        self.mean = np.asarray(x0, float)[self.k].copy()
        self.cov = np.asarray(P0, float)[np.ix_(self.k, self.k)].copy()
        self.long_run = bool(long_run)
        self._F = np.eye(len(self.k))
        self._eye = np.eye(len(self.k))
        self._phi = None
        self.step = part.step
        ip, ik = block_index(self.p), block_index(self.k)
        self._ip, self._ik = ip, ik
        self._pp = block_index(self.p, self.p)
        self._pk = block_index(self.p, self.k)
        self._kk = block_index(self.k, self.k)
        self._p_arr = np.asarray(self.p, dtype=np.int64)
        self._k_arr = np.asarray(self.k, dtype=np.int64)
        #: compiled kernels (projection_kernels) when Numba is there; False: numpy code
        self.fast = pk.ENABLED
        self._rows_idx = np.asarray(self.rows, dtype=np.intp)
        if self.rows:
            self.H = part.H_kalman[:, self.k]
            self.c = part.c_kalman
            self._R = model.R[np.ix_(self.rows, self.rows)]

    def long_run_cov(self) -> np.ndarray:
        P = self.cov
        if not self.long_run or self._phi is None or not len(self.k):
            return P
        _, _, X, info = _gesv(self._eye - self._phi, P)
        if info != 0:
            return P
        S = X + X.T - P
        S = 0.5 * (S + S.T)
        if not math.isfinite(float(S.sum())) or np.trace(S) > 1e6 * max(np.trace(P), 1e-300):
            return P  # (nearly) unit eigenvalue: no DVL information, random-walk error
        if cholesky(S) is None:
            return P
        return S

    def increment(self, x_full, u, dt: float) -> Increment:
        """Predict the ``k`` block; return the gridded block's increment over the step."""
        if self.fast:
            # the model's outputs as views of its buffers (the kernel copies what it keeps)
            fx, F, Q = self.step.views(x_full, u, dt)
            use_phi = self.long_run and self._phi is not None and bool(self.k)
            phi = self._phi if use_phi else self._eye
            d, D, Dk, self.mean, self.cov = pk.kalman_increment(
                np.asarray(x_full, float), fx.reshape(-1), F, Q, self._p_arr, self._k_arr,
                self.cov, phi, use_phi)
            F = F.copy()
            if self.k:
                self._F = F[self._kk]
            return Increment(d, D, Dk, F)
        fx, F, Q = self.step(x_full, u, dt)
        fx = fx.reshape(-1)
        k = self.k
        d = fx[self._ip] - x_full[self._ip]
        D = Q[self._pp]
        if k:
            Fpk = F[self._pk]
            Dk = Fpk @ self.long_run_cov() @ Fpk.T
            Dk = 0.5 * (Dk + Dk.T)
            Fkk = F[self._kk]
            self.mean = fx[self._ik]
            C = Fkk @ self.cov @ Fkk.T + Q[self._kk]
            self.cov = 0.5 * (C + C.T)
            self._F = Fkk
            D = D + Dk
        else:
            Dk = np.zeros_like(D)
        return Increment(d, 0.5 * (D + D.T), Dk, F)

    def update(self, x_full, z, rows, diagnostics: dict) -> None:
        """Kalman update of the ``k`` block with the measurement rows ``rows``."""
        if not rows or not self.k:
            return
        if rows == self.rows:
            H, R, c = self.H, self._R, self.c
            if self.fast:
                mean, cov, phi, nis_, ok = pk.kalman_update(self.mean, self.cov, H, R, c,
                                                            z.take(self._rows_idx), self._F)
                if ok:
                    self.mean, self.cov, self._phi = mean, cov, phi
                    diagnostics["nis"] = nis_
                    diagnostics["nis_dof"] = float(len(rows))
                    return
        else:
            sel = [self.rows.index(r) for r in rows]
            H, R, c = self.H[sel], self.model.R[np.ix_(rows, rows)], self.c[sel]
        y = z[rows] - (H @ self.mean + c)  # rows affine in x_k, independent of x_p
        PHt = self.cov @ H.T
        S = symmetrize(H @ PHt + R)
        K, cho = kalman_gain(PHt, S, diagnostics)  # K = P H' S^-1 (LAPACK Cholesky)
        diagnostics["nis"] = nis(y, cho)
        self.mean = self.mean + K @ y
        IKH = self._eye - K @ H
        C = IKH @ self.cov @ IKH.T + K @ R @ K.T  # Joseph form
        self.cov = 0.5 * (C + C.T)
        self._phi = IKH @ self._F
        diagnostics["nis_dof"] = float(len(rows))


def begin_update(est, z, mask):
    """The first part of a grid filter's ``update``: fresh diagnostics (unless a prediction
    just wrote them), the rows split into Kalman and grid rows, and the Kalman block updated
    with its rows. Returns ``(z, rows_k, rows_g)``."""
    if est._after_update:
        est.diagnostics = {}
    est._after_update = True
    z, rows_k, rows_g = est.part.split_rows(z, mask, est.model.nz)
    est.kalman.update(est.x, z, rows_k, est.diagnostics)
    return z, rows_k, rows_g


def assemble_estimate(est) -> tuple[np.ndarray, np.ndarray]:
    """``(x, P)`` of a partitioned filter (grid or projection) from its gridded block
    (``_mean``, ``_cov``) and its conditional Kalman block; FilterDivergence if non-finite."""
    kal = est.kalman
    if kal.fast:
        x, P, finite = pk.assemble(est.x.size, kal._p_arr, kal._k_arr, est._mean, est._cov,
                                   kal.mean, kal.cov)
        if not finite:
            est.diverged = True
            raise FilterDivergence(f"{est.kind}: non-finite estimate")
        return x, P
    x = est.x.copy()
    P = np.zeros_like(est.P)
    x[est._ip] = est._mean
    P[est._pp] = est._cov
    if est.part.k:
        x[est._ik] = est.kalman.mean
        P[est._kk] = est.kalman.cov
    if not np.isfinite(x.sum() + P.sum()):
        raise FilterDivergence(f"{est.kind}: non-finite estimate")
    return x, symmetrize(P)
