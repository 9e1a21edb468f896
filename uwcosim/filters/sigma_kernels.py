"""Compiled steps of the sigma-point filters (UKF, CKF, CUKF) on a model's compiled form.

The equations of :class:`uwcosim.filters.sigma_point.SigmaPointFilter` as loops, on the
:class:`~uwcosim.filters.kalman_kernels.Workspace` of :mod:`uwcosim.filters.kalman_kernels`
(its model part) with the rule's fields (:func:`rule_fields`): weights ``wm``, ``wc``, the
scale ``s`` of the points ``x +- s L_i`` (``P = L L'``), whether the centre is a point, and the
propagated points ``Y`` (the CUKF's unscented update uses them, not redrawn ones). The point
set is the numpy step's bit for bit (``x_j + s L_ji``); moments, factorizations and solves agree
with it to round-off (:mod:`uwcosim.filters.kalman_kernels` says why). The products are
:mod:`uwcosim.filters.small_linalg`'s, weighted sums ``sum_i w_i a_i b_i'`` as ``(w a)' b``.
"""

from __future__ import annotations

import numpy as np

from uwcosim.core import kinematics
from uwcosim.core.jit import jit
from uwcosim.filters import kalman_kernels as kk
from uwcosim.filters.small_linalg import mm, mm_into, mv


def rule_fields(n: int, npts: int) -> list[tuple]:
    """The rule's fields of the workspace (filled from a :class:`~uwcosim.filters.
    sigma_point.SigmaRule`)."""
    return [("wm", "f8", npts), ("wc", "f8", npts), ("scale", "f8"), ("center", "i8"),
            ("Y", "f8", (npts, n))]


@jit
def points(s, x, L, X):
    """``X_0 = x`` (if the rule has a centre), ``X_i = x + s L_i``, ``X_{n+i} = x - s L_i``."""
    n = x.shape[0]
    c = s.center
    if c:
        X[0, :] = x
    sc = s.scale
    for i in range(n):
        for j in range(n):
            X[c + i, j] = x[j] + sc * L[j, i]
            X[c + n + i, j] = x[j] + (-sc) * L[j, i]


@jit
def moments(wm, wc, Y, mean, cov, D):
    """``mean = sum wm_i Y_i`` (relative to ``Y_0``), ``D = Y - mean``,
    ``cov = sum wc_i D_i D_i'``."""
    npts, d = Y.shape
    for j in range(d):
        v = 0.0
        for i in range(npts):
            v += wm[i] * (Y[i, j] - Y[0, j])
        mean[j] = v + Y[0, j]
    for i in range(npts):
        for j in range(d):
            D[i, j] = Y[i, j] - mean[j]
    W = np.empty((npts, d))
    for i in range(npts):
        for j in range(d):
            W[i, j] = wc[i] * D[i, j]
    mm_into(W.T, D, cov)  # cov = sum wc_i D_i D_i'


@jit
def sigma_predict(ws, x, P):
    """Prediction through the rule's points; ``x``, ``P`` in place, the propagated points in
    ``ws[0].Y``. Returns ``(status, repairs)``."""
    s = ws[0]
    n = x.shape[0]
    L = np.zeros((n, n))
    repairs, status = kk.factor(P, L)  # P = L L' (repaired if needed)
    if status != kk.OK:
        return status, repairs
    npts = s.wm.shape[0]
    X = np.empty((npts, n))
    points(s, x, L, X)
    F, b, Y = s.F, s.b, s.Y
    mm_into(X, F.T, Y)
    for i in range(npts):
        for a in range(n):
            Y[i, a] = Y[i, a] + b[a]  # Y_i = f(X_i, u) = F X_i + b
    D = np.empty((npts, n))
    A = np.empty((n, n))
    moments(s.wm, s.wc, Y, x, A, D)  # x = sum wm_i Y_i
    for i in range(n):
        for j in range(n):
            A[i, j] += s.Q[i, j]  # P = sum wc_i (Y_i - x)(Y_i - x)' + Q
    kk.symmetrize_into(A, P)
    return (kk.OK if kk.finite(x, P) else kk.NOT_FINITE), repairs


@jit
def sigma_update(ws, table, x, P, z, mask, stored):
    """Update with the available components of ``z`` (finite, ``mask`` and used): points
    redrawn from ``(x, P)``, or the propagated ``ws[0].Y`` if ``stored``; ``x``, ``P`` in
    place. Returns ``(status, nis, nis_dof, repairs)``."""
    s = ws[0]
    n, nz = x.shape[0], z.shape[0]
    rows = np.empty(nz, np.int64)
    m = kk.select_rows(s.use, z, mask, rows)
    if m == 0:
        return kk.NO_DATA, 0.0, 0.0, 0.0
    npts = s.wm.shape[0]
    repairs = 0.0
    if stored:
        X = s.Y.copy()
    else:
        L = np.zeros((n, n))
        repairs, status = kk.factor(P, L)
        if status != kk.OK:
            return status, 0.0, 0.0, repairs
        X = np.empty((npts, n))
        points(s, x, L, X)
    Z = np.empty((npts, m))
    for i in range(npts):
        kk.measure_value(s, table, X[i], rows, m, Z[i])  # Z_i = h(X_i)
    zhat = np.empty(m)
    S = np.empty((m, m))
    DZ = np.empty((npts, m))
    moments(s.wm, s.wc, Z, zhat, S, DZ)
    for a in range(m):
        for c in range(m):
            S[a, c] += s.R[rows[a], rows[c]]  # S = Pzz + R
    WX = np.empty((npts, n))
    for i in range(npts):
        for a in range(n):
            WX[i, a] = s.wc[i] * (X[i, a] - x[a])
    Pxz = mm(WX.T, DZ)  # Pxz = sum wc_i (X_i - x)(Z_i - zhat)'
    y = np.empty(m)
    for c in range(m):
        y[c] = z[rows[c]] - zhat[c]  # y = z - zhat
    K, nis, more, status = kk.gain_and_nis(Pxz, S, y)  # K = Pxz S^-1
    repairs += more
    if status != kk.OK:
        return status, 0.0, 0.0, repairs
    x += mv(K, y)  # x = x + K y
    A = P - mm(mm(K, S), K.T)  # P = P - K S K'
    kk.symmetrize_into(A, P)
    return (kk.OK if kk.finite(x, P) else kk.NOT_FINITE), nis, float(m), repairs


@jit
def sigma_step(ws, table, u, dt, z, mask):
    """A whole step of the UKF/CKF on ``ws[0].x``, ``ws[0].P``: the model's transition (if
    compiled in), :func:`sigma_predict`, then :func:`sigma_update` on redrawn points. Returns
    ``(status, nis, nis_dof, repairs)``, a failed prediction's status plus
    :data:`~uwcosim.filters.kalman_kernels.IN_PREDICTION`."""
    s = ws[0]
    kinematics.write(s.motion, u, dt, s.params, s.F, s.b, s.Q)  # F, b, Q of the step
    x, P = s.x, s.P
    status, repairs = sigma_predict(ws, x, P)  # Y_i = f(X_i, u), x = sum wm_i Y_i, P
    if status != kk.OK:
        return status + kk.IN_PREDICTION, 0.0, 0.0, repairs
    status, nis, dof, more = sigma_update(ws, table, x, P, z, mask, False)  # K, x, P
    return status, nis, dof, repairs + more
