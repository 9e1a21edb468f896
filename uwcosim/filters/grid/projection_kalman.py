"""Compiled kernels of the projection filter's prediction and of the conditional Kalman filter.

Part of :mod:`uwcosim.filters.projection_kernels` (same conventions, same lazy compilation; the
filters reach these kernels through that module): the prediction of the series on a moved box
(:func:`predict_shift`; the re-projection with the Gaussian decay, :func:`shift_decay`, is in
:mod:`uwcosim.filters.grid.projection_predict` and re-exported here), the conditional
Kalman filter of the velocities (:func:`kalman_increment`, :func:`kalman_update`), the assembly
of ``(x, P)`` (:func:`assemble`) and the fused per-step calls :func:`predict_step`,
:func:`posterior_step` and, for the common updates, :func:`bayes_step` (a terrain row) and
:func:`prior_step` (no grid row). Small matrices are multiplied by loops (cheaper than a BLAS
call).
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit
from uwcosim.core.reductions import sum2
from uwcosim.filters.grid.grid_moments import _marginals2
from uwcosim.filters.grid.projection_kernels import (
    _posterior_moments,
    _sym,
    bayes_posterior,
    box,
    posterior_coefficients,
    prior_values,
)
from uwcosim.filters.grid.projection_predict import _shift_decay, shift_decay

__all__ = ["assemble", "available_bits", "bayes_step", "kalman_increment", "kalman_step",
           "kalman_update", "posterior_step", "predict_shift", "predict_step", "prior_step",
           "shift_decay"]

# ---------------------------------------------------------------------------------------------
# PFM-PSI prediction


@jit
def predict_shift(m, lo, length, mean, cov, d, D, k_sigma, min_halfwidth):
    """``ProjectionFilter.predict`` for a drift independent of the gridded states.

    The box moves to ``box(mean + d, cov + D)``; the series is translated by ``d`` and re-projected
    there, then decays by ``exp(-w' D w / 2)`` (:func:`shift_decay`). Returns ``(m, lo, length,
    mean, cov, mass)``; when the mass is finite and positive, ``m`` is already made Hermitian
    and normalized (:func:`~uwcosim.filters.grid.projection_predict._shift_decay`).
    """
    mean2 = mean + d
    cov2 = cov + D
    lo2, len2 = box(mean2, cov2, k_sigma, min_halfwidth)
    out, mass = _shift_decay(m, lo + d, length, lo2, len2, D, True,
                             math.sqrt(len2[0] * len2[1]), True)
    return out, lo2, len2, mean2, _sym(cov2), mass


@jit
def available_bits(z, mask, use):
    """Bit ``r`` set when ``z[r]`` is finite and ``mask[r]`` and ``use[r]`` (``split_rows``)."""
    bits = 0
    for r in range(z.size):
        if mask[r] and use[r] and math.isfinite(z[r]):
            bits |= 1 << r
    return bits


# ---------------------------------------------------------------------------------------------
# conditional Kalman filter of the velocities and (x, P)


@jit
def _chol_ok(S):
    """Whether the symmetric ``S`` (lower triangle) is positive definite (Cholesky)."""
    n = S.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            v = S[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / L[j, j]
    return True


@jit
def _solve(A, B):
    """``A^-1 B`` by Gaussian elimination with partial pivoting (as LAPACK gesv); ``ok``."""
    n = A.shape[0]
    A = A.copy()
    X = B.copy()
    for c in range(n):
        p = c
        for r in range(c + 1, n):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if A[p, c] == 0.0:
            return X, False
        if p != c:
            for k in range(n):
                A[c, k], A[p, k] = A[p, k], A[c, k]
            for k in range(X.shape[1]):
                X[c, k], X[p, k] = X[p, k], X[c, k]
        for r in range(c + 1, n):
            f = A[r, c] / A[c, c]
            for k in range(c, n):
                A[r, k] -= f * A[c, k]
            for k in range(X.shape[1]):
                X[r, k] -= f * X[c, k]
    for c in range(n - 1, -1, -1):
        for k in range(X.shape[1]):
            v = X[c, k]
            for j in range(c + 1, n):
                v -= A[c, j] * X[j, k]
            X[c, k] = v / A[c, c]
    return X, True


@jit
def _mm(A, B):
    """``A @ B`` by loops (tiny matrices: cheaper than a BLAS call)."""
    n, m, p = A.shape[0], A.shape[1], B.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a = A[i, k]
            for j in range(p):
                out[i, j] += a * B[k, j]
    return out


@jit
def _mv(A, x):
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        for k in range(A.shape[1]):
            out[i] += A[i, k] * x[k]
    return out


@jit
def _sandwich(F, r, k, S, Q, add_q):
    """``_sym(A S A' + B)`` with ``A = F[r][:, k]`` and ``B = Q[r][:, r]`` (no ``B`` unless
    ``add_q``): the arithmetic of ``_sym(_mm(_mm(A, S), A.T) + B)`` without the copies."""
    n, m = r.size, k.size
    T = np.zeros((n, m))
    for i in range(n):
        for c in range(m):
            a = F[r[i], k[c]]
            for j in range(m):
                T[i, j] += a * S[c, j]
    U = np.zeros((n, n))
    for i in range(n):
        for c in range(m):
            a = T[i, c]
            for j in range(n):
                U[i, j] += a * F[r[j], k[c]]
    if add_q:
        for i in range(n):
            for j in range(n):
                U[i, j] = U[i, j] + Q[r[i], r[j]]
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (U[i, j] + U[j, i])
            U[i, j] = v
            U[j, i] = v
    return U


@jit
def kalman_increment(x, fx, F, Q, p, k, cov, phi, use_phi):
    """:meth:`ConditionalKalman.increment` after the model call: ``(d, D, Dk, mean, cov)``.

    With ``use_phi`` the long-run covariance ``S = X + X' - cov``, ``X = (I - phi)^-1 cov``,
    replaces ``cov`` in ``Dk`` when it is finite, not too large and positive definite."""
    npp, nk = p.size, k.size
    d = np.empty(npp)
    for a in range(npp):
        d[a] = fx[p[a]] - x[p[a]]
    Dk = np.zeros((npp, npp))
    mean = np.empty(nk)
    new_cov = cov
    if nk:
        S = cov
        if use_phi:
            A = np.empty((nk, nk))
            for a in range(nk):
                for b in range(nk):
                    A[a, b] = (1.0 if a == b else 0.0) - phi[a, b]
            X, ok = _solve(A, cov)
            if ok:
                S2 = np.empty((nk, nk))  # _sym(X + X' - cov)
                tr, trP = 0.0, 0.0
                for a in range(nk):
                    for b in range(nk):
                        S2[a, b] = 0.5 * (((X[a, b] + X[b, a]) - cov[a, b])
                                          + ((X[b, a] + X[a, b]) - cov[b, a]))
                for a in range(nk):
                    tr += S2[a, a]
                    trP += cov[a, a]
                if (math.isfinite(S2.sum()) and not tr > 1e6 * max(trP, 1e-300)
                        and _chol_ok(S2)):
                    S = S2
        for a in range(nk):
            mean[a] = fx[k[a]]
        Dk = _sandwich(F, p, k, S, Q, False)
        new_cov = _sandwich(F, k, k, cov, Q, True)
    D = np.empty((npp, npp))  # _sym(Q[p][:, p] + Dk)
    for a in range(npp):
        for b in range(npp):
            D[a, b] = Q[p[a], p[b]] + Dk[a, b] if nk else Q[p[a], p[b]]
    for a in range(npp):
        for b in range(a, npp):
            v = 0.5 * (D[a, b] + D[b, a])
            D[a, b] = v
            D[b, a] = v
    return d, D, Dk, mean, new_cov


@jit
def kalman_update(mean, cov, H, R, c, y_meas, F):
    """Joseph-form update of the ``k`` block: ``(mean, cov, phi, nis, ok)``; ``ok`` False when
    ``S`` is not positive definite (the caller then runs the repairing numpy path)."""
    y = y_meas - (_mv(H, mean) + c)
    PHt = _mm(cov, H.T)
    S = _sym(_mm(H, PHt) + R)
    if not _chol_ok(S):
        return mean, cov, F, 0.0, False
    Sinv_y, _ = _solve(S, y.reshape(-1, 1))
    Kt, _ = _solve(S, PHt.T.copy())
    K = Kt.T.copy()
    nis = 0.0
    for a in range(y.size):
        nis += y[a] * Sinv_y[a, 0]
    new_mean = mean + _mv(K, y)
    IKH = np.eye(mean.size) - _mm(K, H)
    new_cov = _sym(_mm(_mm(IKH, cov), IKH.T) + _mm(_mm(K, R), K.T))
    return new_mean, new_cov, _mm(IKH, F), nis, True


@jit
def assemble(nx, p, k, mean_p, cov_p, mean_k, cov_k):
    """``(x, P, finite)`` of a partitioned filter (:func:`assemble_estimate`)."""
    x = np.zeros(nx)
    P = np.zeros((nx, nx))
    for a in range(p.size):
        x[p[a]] = mean_p[a]
        for b in range(p.size):
            P[p[a], p[b]] = cov_p[a, b]
    for a in range(k.size):
        x[k[a]] = mean_k[a]
        for b in range(k.size):
            P[k[a], k[b]] = cov_k[a, b]
    finite = math.isfinite(x.sum() + P.sum())
    return x, _sym(P), finite


@jit
def predict_step(x, fx, F, Q, p, k, kcov, phi, use_phi, m, lo, length, mean, cov, k_sigma,
                 min_halfwidth, kmean_out, Fkk_out):
    """One ``ProjectionFilter.predict`` (drift independent of the gridded states) after the
    model call ``(fx, F, Q)``: :func:`kalman_increment`, :func:`predict_shift` and
    :func:`assemble` in one call. Returns ``(m, lo, length, mass, x, P, finite)``; the
    predicted moments of the gridded block are written into ``mean``, ``cov`` and the
    velocities' mean, covariance and ``F_kk`` into ``kmean_out``, ``kcov``, ``Fkk_out``, in
    place (fewer arrays to return: Numba boxes each one)."""
    d, D, _, kmean, kcov2 = kalman_increment(x, fx, F, Q, p, k, kcov, phi, use_phi)
    m2, lo2, len2, mean2, cov2, mass = predict_shift(m, lo, length, mean, cov, d, D, k_sigma,
                                                     min_halfwidth)
    for a in range(k.size):
        for b in range(k.size):
            Fkk_out[a, b] = F[k[a], k[b]]
    x2, P2, finite = assemble(x.size, p, k, mean2, cov2, kmean, kcov2)
    _write_moments(mean2, cov2, kmean, kcov2, mean, cov, kmean_out, kcov)
    return m2, lo2, len2, mass, x2, P2, finite


@jit
def posterior_step(post, Tg, Tm, Tq, Tx, length, neg_limit, nx, p, k, mean, cov, kmean, kcov):
    """:func:`posterior_coefficients` and, when the series needs no repair, :func:`assemble`
    of ``(x, P)`` from the posterior moments: ``(m, values, neg, mass, x, P, finite)``."""
    cell = (length[0] / post.shape[0]) * (length[1] / post.shape[1])
    m, values, neg, mass = posterior_coefficients(post, sum2(post, False) * cell, Tg, Tm, Tq,
                                                  Tx, length, neg_limit)
    if math.isfinite(mass) and mass > 0.0:
        x, P, finite = assemble(nx, p, k, mean, cov, kmean, kcov)
    else:
        x, P, finite = np.zeros(nx), np.zeros((nx, nx)), False
    return m, values, neg, mass, x, P, finite


@jit
def bayes_step(values, E, S, vmin, lo, length, shift, thr, refine, k_sigma, min_halfwidth, Tg,
               Tm, Tq, Tx, neg_limit, nx, p, k, kmean, kcov, H, R, c, z, rows, F, active,
               mean_out, cov_out):
    """The common ``ProjectionFilter.update`` with one terrain row, after :func:`bayes_terms`
    and the exponential: :func:`bayes_posterior`, the log-likelihood ``log(Z) + shift``, the
    gate (``loglik >= thr``), the refinement test (the posterior box narrower than ``refine``
    times the prior box on some axis) and :func:`posterior_step` in one call.

    First the Kalman update of the velocities (:func:`kalman_step`, arguments ``kmean`` to
    ``active``). Returns ``(code, loglik, m, neg, x, P, finite, phi, nis)``; ``code`` 0: done
    (``m`` Hermitian and normalized, no repair needed; the gridded block's moments written
    into ``mean_out``, ``cov_out`` and the velocities' mean and covariance into ``kmean``,
    ``kcov``, in place: fewer arrays to return); 1: any other case (no posterior mass,
    non-finite moments, gate failed, refinement, positivity repair, failed Kalman update),
    which the caller runs on its general path: then nothing is written. The arithmetic is that
    of the separate kernels, in the same order."""
    km, kc, phi, nis, ok = kalman_step(kmean, kcov, H, R, c, z, rows, F, active)
    no = np.zeros((1, 1), np.complex128)
    X, Pz = np.zeros(nx), np.zeros((nx, nx))
    if not ok:
        return 1, np.nan, no, np.nan, X, Pz, False, phi, nis
    post, Z, mean, cov, status = bayes_posterior(values, E, S, vmin, lo, length)
    if status == 1 or status == 3:
        return 1, np.nan, no, np.nan, X, Pz, False, phi, nis
    loglik = math.log(Z) + shift
    if not loglik >= thr:
        return 1, loglik, no, np.nan, X, Pz, False, phi, nis
    if refine < 1.0:
        _, len2 = box(mean, cov, k_sigma, min_halfwidth)
        if len2[0] < refine * length[0] or len2[1] < refine * length[1]:
            return 1, loglik, no, np.nan, X, Pz, False, phi, nis
    m, _, neg, mass = posterior_coefficients(post, Z, Tg, Tm, Tq, Tx, length, neg_limit)
    if not (math.isfinite(mass) and mass > 0.0):
        return 1, loglik, no, neg, X, Pz, False, phi, nis
    x, P, finite = assemble(nx, p, k, mean, cov, km, kc)
    _write_moments(mean, cov, km, kc, mean_out, cov_out, kmean, kcov)
    return 0, loglik, m, neg, x, P, finite, phi, nis


@jit
def _write_moments(mean, cov, km, kc, mean_out, cov_out, kmean, kcov):
    """Copy the gridded block's moments and the velocities' Kalman state into the caller's
    arrays (``km``, ``kc`` may be ``kmean``, ``kcov`` themselves)."""
    mean_out[:] = mean
    cov_out[:, :] = cov
    kmean[:] = km
    kcov[:, :] = kc


@jit
def kalman_step(kmean, kcov, H, R, c, z, rows, F, active):
    """:func:`kalman_update` of the velocities with the rows ``rows`` of ``z`` when ``active``
    (else the block unchanged): ``(mean, cov, phi, nis, ok)``."""
    if not active:
        return kmean, kcov, F, 0.0, True
    zk = np.empty(rows.size)
    for a in range(rows.size):
        zk[a] = z[rows[a]]
    return kalman_update(kmean, kcov, H, R, c, zk, F)


@jit
def prior_step(m, Tq, Tx, lo, length, neg_limit, nx, p, k, kmean, kcov, H, R, c, z, rows, F,
               active, mean_out, cov_out):
    """``ProjectionFilter.update`` without a grid measurement row: the posterior is the prior.

    The prior's grid values and negative mass (:func:`prior_values`), their moments (those of
    :func:`bayes_posterior` with unit factors, bit for bit: the factors multiply by exactly 1)
    and ``(x, P)``, after the Kalman update of the velocities (:func:`kalman_step`). The
    series is kept as it is: the general path re-projects the grid values
    onto the basis, which gives the (Hermitian, normalized) series back to round-off, and
    recomputes the same grid values. Returns ``(ok, neg, x, P, finite, phi, nis)`` and writes
    the moments and the Kalman state in place as :func:`bayes_step`; ``ok`` False (the caller
    runs its general path; nothing written) when the Kalman update fails, the values have no
    positive mass, their moments are not finite, or ``neg > neg_limit`` (a positivity repair
    follows)."""
    km, kc, phi, nis, ok = kalman_step(kmean, kcov, H, R, c, z, rows, F, active)
    values, neg = prior_values(m, Tq, Tx, length)
    m0, m1 = _marginals2(values)
    _, mean, cov, status = _posterior_moments(values, m0, m1, lo, length)
    if not ok or status != 0 or not neg <= neg_limit:
        return False, neg, np.zeros(nx), np.zeros((nx, nx)), False, phi, nis
    x, P, finite = assemble(nx, p, k, mean, cov, km, kc)
    _write_moments(mean, cov, km, kc, mean_out, cov_out, kmean, kcov)
    return True, neg, x, P, finite, phi, nis
