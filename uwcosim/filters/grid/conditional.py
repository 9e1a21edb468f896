"""The conditional Kalman filter of the non-gridded states of the grid filters.

:class:`ConditionalKalman` runs the Kalman filter of the ``k`` block of a
:class:`~uwcosim.filters.grid.partition.Partition` conditionally on the mean of the gridded
block, and returns the increment of the gridded block over a step with its covariance: the
velocity uncertainty becomes extra diffusion of the position, inflated to the *long-run*
covariance of the velocity error (see :meth:`ConditionalKalman.increment`).
:meth:`~ConditionalKalman.assemble` joins the two blocks into the filter's ``(x, P)``.

Two forms of the same steps, chosen once when a filter is built: :class:`ConditionalKalman`
(numpy, the reference) and :class:`CompiledConditionalKalman` (the kernels of
:mod:`uwcosim.filters.grid.conditional_kernels`; the same results to round-off,
``tests/test_projection_kernels.py``). Both keep the block's state in ``block``, a
:class:`~uwcosim.filters.grid.conditional_kernels.KalmanBlock` whose arrays are updated in
place, and its measurement rows in ``measurement``, a
:class:`~uwcosim.filters.grid.conditional_kernels.KalmanRows`, so that the compiled steps of
the filters can take them as they are.
"""

from __future__ import annotations

import math
from typing import ClassVar, NamedTuple

import numpy as np
from scipy.linalg import lapack

from uwcosim.filters.grid import conditional_kernels as kernels
from uwcosim.filters.grid.conditional_kernels import KalmanBlock, KalmanRows
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

    #: the steps run compiled kernels
    compiled: ClassVar[bool] = False

    def __init__(self, model, part: Partition, x0, P0, long_run: bool = True) -> None:
        self.model = model
        self.p, self.k = part.p, part.k
        self.rows = part.rows_kalman
        self.long_run = bool(long_run)
        self.step = part.step
        nk = len(self.k)
        self._eye = np.eye(nk)
        #: ``Phi = (I - K H) F`` of the last update (None before the first)
        self.phi: np.ndarray | None = None
        ip, ik = block_index(self.p), block_index(self.k)
        self._ip, self._ik = ip, ik
        self._pp = block_index(self.p, self.p)
        self._pk = block_index(self.p, self.k)
        self._kk = block_index(self.k, self.k)
        if self.rows and nk:
            H = part.H_kalman[:, self.k]
            R = model.R[np.ix_(self.rows, self.rows)]
            c = part.c_kalman
        else:
            H, R, c = np.zeros((0, nk)), np.zeros((0, 0)), np.zeros(0)
        #: the block: its indices, its mean ``x``, covariance ``P`` and ``F_kk`` (updated in
        #: place)
        self.block = KalmanBlock(
            p=np.asarray(self.p, dtype=np.int64), k=np.asarray(self.k, dtype=np.int64),
            x=np.asarray(x0, float)[self.k].copy(),
            P=np.asarray(P0, float)[np.ix_(self.k, self.k)].copy(), F=np.eye(nk))
        #: the block's measurement rows
        self.measurement = KalmanRows(H=H, R=R, c=c, rows=np.asarray(self.rows, dtype=np.intp))

    def long_run_phi(self) -> tuple[np.ndarray, bool]:
        """``(phi, use_phi)``: whether the long-run covariance applies, and the ``Phi`` it
        takes (the identity when it does not)."""
        use = self.long_run and self.phi is not None and bool(self.k)
        return (self.phi if use else self._eye), use

    def long_run_cov(self) -> np.ndarray:
        P = self.block.P
        if not self.long_run or self.phi is None or not len(self.k):
            return P
        _, _, X, info = _gesv(self._eye - self.phi, P)
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
        fx, F, Q = self.step(x_full, u, dt)
        fx = fx.reshape(-1)
        blk = self.block
        d = fx[self._ip] - x_full[self._ip]  # d = f(x)_p - x_p
        D = Q[self._pp]
        if self.k:
            Fpk = F[self._pk]
            Dk = Fpk @ self.long_run_cov() @ Fpk.T  # F_pk S F_pk'
            Dk = 0.5 * (Dk + Dk.T)
            Fkk = F[self._kk]
            C = Fkk @ blk.P @ Fkk.T + Q[self._kk]  # P = F_kk P F_kk' + Q_kk
            blk.x[:] = fx[self._ik]  # x_k = f(x)_k
            blk.P[:] = 0.5 * (C + C.T)
            blk.F[:] = Fkk
            D = D + Dk
        else:
            Dk = np.zeros_like(D)
        return Increment(d, 0.5 * (D + D.T), Dk, F)

    def update(self, x_full, z, rows, diagnostics: dict) -> None:
        """Kalman update of the ``k`` block with the measurement rows ``rows``."""
        if not rows or not self.k:
            return
        blk, meas = self.block, self.measurement
        if rows == self.rows:
            H, R, c = meas.H, meas.R, meas.c
        else:
            sel = [self.rows.index(r) for r in rows]
            H, R, c = meas.H[sel], self.model.R[np.ix_(rows, rows)], meas.c[sel]
        y = z[rows] - (H @ blk.x + c)  # rows affine in x_k, independent of x_p
        PHt = blk.P @ H.T
        S = symmetrize(H @ PHt + R)
        K, cho = kalman_gain(PHt, S, diagnostics)  # K = P H' S^-1 (LAPACK Cholesky)
        diagnostics["nis"] = nis(y, cho)
        IKH = self._eye - K @ H
        C = IKH @ blk.P @ IKH.T + K @ R @ K.T  # Joseph form
        blk.x[:] = blk.x + K @ y
        blk.P[:] = 0.5 * (C + C.T)
        self.phi = IKH @ blk.F
        diagnostics["nis_dof"] = float(len(rows))

    def assemble(self, mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                   bool]:
        """``(x, P, finite)`` of the partitioned filter: the gridded block's ``mean`` and
        ``cov`` with this block's."""
        nx = len(self.p) + len(self.k)
        x = np.zeros(nx)
        P = np.zeros((nx, nx))
        x[self._ip] = mean
        P[self._pp] = cov
        if self.k:
            x[self._ik] = self.block.x
            P[self._kk] = self.block.P
        finite = math.isfinite(float(x.sum() + P.sum()))
        return x, symmetrize(P), finite


class CompiledConditionalKalman(ConditionalKalman):
    """:class:`ConditionalKalman` by the kernels of
    :mod:`~uwcosim.filters.grid.conditional_kernels` (an update that is not the common one,
    or whose ``S`` is not positive definite, runs the numpy form with its repairs)."""

    compiled: ClassVar[bool] = True

    def __init__(self, model, part: Partition, x0, P0, long_run: bool = True) -> None:
        super().__init__(model, part, x0, P0, long_run)
        # the kernels' arguments (jit: plain tuples)
        self._block, self._rows = tuple(self.block), tuple(self.measurement)

    def increment(self, x_full, u, dt: float) -> Increment:
        # the model's outputs as views of its buffers (the kernel copies what it keeps)
        fx, F, Q = self.step.views(x_full, u, dt)
        phi, use_phi = self.long_run_phi()
        step = (np.asarray(x_full, float), fx.reshape(-1), F, Q)  # a ModelStep
        d, D, Dk = kernels.kalman_increment(step, self._block, phi, use_phi)
        return Increment(d, D, Dk, F.copy())

    def update(self, x_full, z, rows, diagnostics: dict) -> None:
        if rows and self.k and rows == self.rows:
            x, P, phi, nis_, ok = kernels.kalman_update(self._block, self._rows,
                                                        z.take(self.measurement.rows))
            if ok:
                self.block.x[:] = x
                self.block.P[:] = P
                self.phi = phi
                diagnostics["nis"] = nis_
                diagnostics["nis_dof"] = float(len(rows))
                return
        super().update(x_full, z, rows, diagnostics)

    def assemble(self, mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                   bool]:
        return kernels.assemble(self._block, mean, cov)
