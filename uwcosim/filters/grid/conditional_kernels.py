"""Compiled form of the conditional Kalman block of the grid filters (two gridded states or
more; the TAN model's velocities): its prediction with the increment of the gridded block,
its Joseph-form update and the assembly of the filter's ``(x, P)``.

The numpy form, the reference, is :class:`~uwcosim.filters.grid.conditional.ConditionalKalman`;
:class:`~uwcosim.filters.grid.conditional.CompiledConditionalKalman` calls these kernels, and
the fused steps of PFM-PSI call them from compiled code. Arguments are the bundles
:class:`KalmanBlock` (the block's indices and state, its ``x``, ``P`` and ``F`` written in
place), :class:`KalmanRows` (its measurement rows) and :class:`ModelStep` (the model's
one-step map at the estimate), passed as the NamedTuples or as plain tuples of their fields
(:mod:`uwcosim.core.jit`). IEEE arithmetic in
source order; the small products are loops (:mod:`uwcosim.filters.small_linalg`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from uwcosim.core.jit import jit
from uwcosim.filters.small_linalg import chol_ok, mm, mv, sandwich, solve, sym


class KalmanBlock(NamedTuple):
    """The conditional Kalman block as the kernels take it: the indices of the two blocks in
    the full state and the block's state ``x``, ``P``, ``F`` (written in place)."""

    p: np.ndarray  #: indices of the gridded states in the full state (int64)
    k: np.ndarray  #: indices of the Kalman states (int64)
    x: np.ndarray  #: mean of the Kalman states
    P: np.ndarray  #: their covariance
    F: np.ndarray  #: ``F_kk`` of the last prediction


class KalmanRows(NamedTuple):
    """The block's measurement rows, affine in its states: ``z[rows] = H x + c + v``,
    ``v ~ N(0, R)``."""

    H: np.ndarray  #: the rows' Jacobian (rows x Kalman states)
    R: np.ndarray  #: their noise covariance
    c: np.ndarray  #: their offset
    rows: np.ndarray  #: their indices in the measurement vector


class ModelStep(NamedTuple):
    """The model's one-step map at the estimate ``x``: ``f(x)``, its Jacobian ``F`` and the
    discrete process-noise covariance ``Q``."""

    x: np.ndarray
    fx: np.ndarray
    F: np.ndarray
    Q: np.ndarray


@jit
def kalman_increment(step, kal, phi, use_phi):
    """:meth:`~uwcosim.filters.grid.conditional.ConditionalKalman.increment` after the model
    call: ``(d, D, Dk)``, the Kalman block predicted in place.

    ``d = f(x)_p - x_p``; ``Dk = F_pk S F_pk'`` and ``D = sym(Q_pp + Dk)``; ``x_k = f(x)_k``,
    ``P = sym(F_kk P F_kk' + Q_kk)``, ``F = F_kk``. With ``use_phi`` the long-run covariance
    ``S = X + X' - P``, ``X = (I - phi)^-1 P``, replaces ``P`` in ``Dk`` when it is finite,
    not too large and positive definite."""
    x, fx, F, Q = step
    p, k, xk, P, Fkk = kal
    npp, nk = p.size, k.size
    d = np.empty(npp)
    for a in range(npp):
        d[a] = fx[p[a]] - x[p[a]]  # d = f(x)_p - x_p
    Dk = np.zeros((npp, npp))
    if nk:
        S = P
        if use_phi:
            A = np.empty((nk, nk))
            for a in range(nk):
                for b in range(nk):
                    A[a, b] = (1.0 if a == b else 0.0) - phi[a, b]
            X, ok = solve(A, P)  # X = (I - phi)^-1 P
            if ok:
                S2 = np.empty((nk, nk))  # S = sym(X + X' - P)
                tr, trP = 0.0, 0.0
                for a in range(nk):
                    for b in range(nk):
                        S2[a, b] = 0.5 * (((X[a, b] + X[b, a]) - P[a, b])
                                          + ((X[b, a] + X[a, b]) - P[b, a]))
                for a in range(nk):
                    tr += S2[a, a]
                    trP += P[a, a]
                if (math.isfinite(S2.sum()) and not tr > 1e6 * max(trP, 1e-300)
                        and chol_ok(S2)):
                    S = S2
        Dk = sandwich(F, p, k, S, Q, False)  # Dk = F_pk S F_pk'
        P_new = sandwich(F, k, k, P, Q, True)  # P = F_kk P F_kk' + Q_kk
        for a in range(nk):
            xk[a] = fx[k[a]]  # x_k = f(x)_k
            for b in range(nk):
                P[a, b] = P_new[a, b]
                Fkk[a, b] = F[k[a], k[b]]
    D = np.empty((npp, npp))  # D = sym(Q_pp + Dk)
    for a in range(npp):
        for b in range(npp):
            D[a, b] = Q[p[a], p[b]] + Dk[a, b] if nk else Q[p[a], p[b]]
    for a in range(npp):
        for b in range(a, npp):
            v = 0.5 * (D[a, b] + D[b, a])
            D[a, b] = v
            D[b, a] = v
    return d, D, Dk


@jit
def kalman_update(kal, rows, z):
    """Joseph-form update of the block with the measurements ``z`` of its rows ``rows`` (a
    :class:`KalmanRows`): ``(x, P, phi, nis, ok)``, not written into the block; ``ok`` False
    when ``S`` is not positive definite (the caller then runs the repairing numpy form)."""
    _, _, x, P, F = kal
    H, R, c, _ = rows
    y = z - (mv(H, x) + c)  # y = z - (H x + c)
    PHt = mm(P, H.T)
    S = sym(mm(H, PHt) + R)  # S = H P H' + R
    if not chol_ok(S):
        return x, P, F, 0.0, False
    Sinv_y, _ = solve(S, y.reshape(-1, 1))
    Kt, _ = solve(S, PHt.T.copy())
    K = Kt.T.copy()  # K = P H' S^-1
    nis = 0.0
    for a in range(y.size):
        nis += y[a] * Sinv_y[a, 0]  # y' S^-1 y
    new_x = x + mv(K, y)  # x = x + K y
    IKH = np.eye(x.size) - mm(K, H)
    new_P = sym(mm(mm(IKH, P), IKH.T) + mm(mm(K, R), K.T))  # (I-KH) P (I-KH)' + K R K'
    return new_x, new_P, mm(IKH, F), nis, True  # phi = (I - K H) F


@jit
def kalman_step(kal, rows, z, active):
    """:func:`kalman_update` with the rows ``rows`` of the full measurement vector ``z`` when
    ``active`` (else the block unchanged): ``(x, P, phi, nis, ok)``."""
    _, _, x, P, F = kal
    if not active:
        return x, P, F, 0.0, True
    _, _, _, idx = rows
    zk = np.empty(idx.size)
    for a in range(idx.size):
        zk[a] = z[idx[a]]
    return kalman_update(kal, rows, zk)


@jit
def state_size(kal):
    """The size of the full state: the gridded and the Kalman states."""
    p, k, _, _, _ = kal
    return p.size + k.size


@jit
def store(kal, x, P):
    """Write the block's mean and covariance (``x``, ``P`` may be the block's own)."""
    _, _, xk, Pk, _ = kal
    xk[:] = x
    Pk[:, :] = P


@jit
def assemble(kal, mean, cov):
    """``(x, P, finite)`` of a partitioned filter: the gridded block's ``mean`` and ``cov``
    and the Kalman block's ``x``, ``P``
    (:meth:`~uwcosim.filters.grid.conditional.ConditionalKalman.assemble`)."""
    p, k, xk, Pk, _ = kal
    nx = state_size(kal)
    x = np.zeros(nx)
    P = np.zeros((nx, nx))
    for a in range(p.size):
        x[p[a]] = mean[a]
        for b in range(p.size):
            P[p[a], p[b]] = cov[a, b]
    for a in range(k.size):
        x[k[a]] = xk[a]
        for b in range(k.size):
            P[k[a], k[b]] = Pk[a, b]
    finite = math.isfinite(x.sum() + P.sum())
    return x, sym(P), finite
