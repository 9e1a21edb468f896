"""Compiled loops for the small matrices (2 x 2 to 9 x 4) of the filters' compiled steps.

At these sizes a loop is cheaper than a BLAS call: products (into a new array, ``mm``/``mv``,
or into the caller's work array, ``mm_into``/``mv_into``: an allocation costs about 50 ns, as
much as a 4 x 4 product), a symmetric part, the Cholesky factor and its test, and a solve by
Gaussian elimination with partial pivoting (the pivots LAPACK's ``gesv`` chooses). Used by the
compiled Kalman steps (:mod:`uwcosim.filters.kalman_kernels`,
:mod:`uwcosim.filters.sigma_kernels`), the conditional Kalman block
(:mod:`uwcosim.filters.grid.conditional_kernels`) and the grid filters' predictions. IEEE
arithmetic in source order (:mod:`uwcosim.core.jit`): a product sums over the inner index in
order from 0.0, whichever form computes it.
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit


@jit
def sym(A):
    """``(A + A') / 2`` (a new array)."""
    n = A.shape[0]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.5 * (A[i, j] + A[j, i])
    return out


@jit
def cholesky(A, L):
    """Lower Cholesky factor of the symmetric ``A`` (its lower triangle) into ``L`` (zeros
    above the diagonal); False, ``L`` partly written, if ``A`` is not positive definite."""
    n = A.shape[0]
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return False
        ljj = math.sqrt(d)
        L[j, j] = ljj
        for i in range(j):
            L[i, j] = 0.0
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / ljj
    return True


@jit
def chol_ok(S):
    """Whether the symmetric ``S`` (lower triangle) is positive definite (Cholesky)."""
    n = S.shape[0]
    return cholesky(S, np.empty((n, n)))


@jit
def solve(A, B):
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
def mm_into(A, B, out):
    """``out = A @ B`` by loops (``out`` apart from ``A`` and ``B``); returns ``out``."""
    n, m, p = A.shape[0], A.shape[1], B.shape[1]
    for i in range(n):
        for j in range(p):
            out[i, j] = 0.0
    for i in range(n):
        for k in range(m):
            a = A[i, k]
            for j in range(p):
                out[i, j] += a * B[k, j]
    return out


@jit
def mm(A, B):
    """``A @ B`` by loops (a new array)."""
    return mm_into(A, B, np.empty((A.shape[0], B.shape[1])))


@jit
def mv_into(A, x, out):
    """``out = A @ x`` by loops (``out`` apart from ``x``); returns ``out``."""
    for i in range(A.shape[0]):
        out[i] = 0.0
        for k in range(A.shape[1]):
            out[i] += A[i, k] * x[k]
    return out


@jit
def mv(A, x):
    """``A @ x`` by loops (a new array)."""
    return mv_into(A, x, np.empty(A.shape[0]))


@jit
def sandwich(F, r, k, S, Q, add_q):
    """``sym(A S A' + B)`` with ``A = F[r][:, k]`` and ``B = Q[r][:, r]`` (no ``B`` unless
    ``add_q``): the arithmetic of ``sym(mm(mm(A, S), A.T) + B)`` without the copies."""
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
