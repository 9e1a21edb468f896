"""Compiled kernels of the marginalized particle filter (:mod:`uwcosim.filters.rbpf`).

One call per half step does what the numpy code of :class:`~uwcosim.filters.rbpf.
RaoBlackwellizedPF` does in some thirty numpy calls on 4x4 matrices and 1000-particle rows
(the step of ``benchmarks/bench_rbpf.py``: 78-81 us median against 112 with the numpy code;
``docs/benchmarks.md``):

* :func:`predict_step`: ``S = F blockdiag(0, P) F' + Q`` in ``(p, k)`` order, its
  Cholesky factor ``L``, ``P' = L_k L_k'`` and the particles' noise ``X[perm] += L[:, :n_p] e``;
* :func:`update_step`: ``M = [[C, H_k P], [P H_k', P]]`` and its factor, the predictive NIS
  moments of the residuals ``E_i = zhat_i - z`` (prior weights), their whitening by ``L_11``,
  every particle's Kalman correction ``L_21 L_11^-1 E_i`` and the log-likelihoods.

Same maths as the numpy code (see that module's docstrings), different rounding: the small
products are loops, the per-particle work runs row by row over the particles (vectorizable)
and the sums over particles are :func:`~uwcosim.core.reductions.row_dot`'s fixed-order
partial sums (IEEE, no fast-math, registered with :func:`~uwcosim.core.jit.jit`
like the grid filters' kernels: the same bits whether compiled afresh or loaded from the
cache). A matrix that is not positive definite is reported (return code) before anything
is written to the particles; the filter then runs its numpy code, with its repairs, for that
step.
``tests/test_rbpf_kernels.py`` checks both paths against each other.
"""

from __future__ import annotations

import math

from uwcosim.core.jit import ENABLED, jit
from uwcosim.core.reductions import row_dot

__all__ = ["ENABLED", "predict_step", "update_step"]


@jit
def _cholesky(A, L, n):
    """Lower Cholesky factor of ``A[:n, :n]`` into ``L[:n, :n]`` (upper part zeroed); False
    when ``A`` is not (numerically) positive definite."""
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:  # also NaN
            return False
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d
        for i in range(j):
            L[i, j] = 0.0
    return True


@jit
def _lower_inverse(L, Li, n):
    """``Li[:n, :n] = L[:n, :n]^-1`` of a lower triangular ``L`` (forward substitution of the
    identity; upper part zeroed)."""
    for j in range(n):
        for i in range(j):
            Li[i, j] = 0.0
        Li[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, n):
            s = 0.0
            for k in range(j, i):
                s += L[i, k] * Li[k, j]
            Li[i, j] = -s / L[i, i]


@jit
def _outer_lower(L, r0, n, out):
    """``out = L[r0:r0+n, r0:r0+n] L[r0:r0+n, r0:r0+n]'`` of a lower triangular block."""
    for c in range(n):
        for d in range(n):
            s = 0.0
            for j in range(min(c, d) + 1):
                s += L[r0 + c, r0 + j] * L[r0 + d, r0 + j]
            out[c, d] = s


@jit
def predict_step(F, Q, Pk, perm, n_p, noise, X, L, Pk_out, t):
    """Steps 1-2 of the RBPF (see :meth:`RaoBlackwellizedPF.predict`). ``perm`` orders the
    states ``(p, k)``; ``noise`` holds ``n_p`` rows of standard normals; ``X`` the particles'
    predicted means, to which ``L[:, :n_p] noise`` is added; ``t`` is a scratch row. Returns
    ``(factored, finite)``: nothing is written to ``X`` or ``Pk_out`` (which may be ``Pk``)
    unless ``S`` was factored; ``finite``: no particle is NaN or infinite."""
    nx = F.shape[0]
    nk = nx - n_p
    S = L  # S in L's buffer, factored in place below
    for a in range(nx):
        ra = perm[a]
        for b in range(a + 1):
            rb = perm[b]
            s = 0.0
            for c in range(nk):
                u = 0.0
                for d in range(nk):
                    u += Pk[c, d] * F[rb, perm[n_p + d]]
                s += F[ra, perm[n_p + c]] * u
            S[a, b] = s + Q[ra, rb]
            S[b, a] = S[a, b]
    if not _cholesky(S, L, nx):
        return False, True
    _outer_lower(L, n_p, nk, Pk_out)
    n = X.shape[1]
    bad = False
    for a in range(nx):
        row = perm[a]
        la = L[a, 0]
        for i in range(n):
            t[i] = la * noise[0, i]
        for j in range(1, min(a + 1, n_p)):
            la = L[a, j]
            for i in range(n):
                t[i] += la * noise[j, i]
        for i in range(n):
            v = X[row, i] + t[i]
            X[row, i] = v
            d = v - v  # NaN unless v is finite
            bad |= d != d
    return True, not bad


@jit
def update_step(Zt, z, idx, R, Hk, kpos, Pk, nkb, w, particles, sk, small, work, ll):
    """Steps 3-4 of the RBPF (see :meth:`RaoBlackwellizedPF.update`) for the available rows
    ``idx`` of the predicted measurements ``Zt`` (``(nz, N)``) and of ``z``. ``R`` is their
    measurement covariance, ``Hk`` the rows ``kpos`` (positions in ``idx``) that measure the
    linear states ``sk`` (``nkb`` of them; 0 when no Kalman row is available). ``small`` holds
    six ``q x q`` scratch matrices (``q = m + nkb``), ``work`` ``2 m + 1`` scratch rows of
    ``N``. Writes the log-likelihoods into ``ll``, corrects the particles and writes the
    updated covariance into ``Pk``. Returns ``(code, nis)``: code 0 done, 1 ``M`` and 2 the
    NIS covariance not positive definite (nothing written to the particles or ``Pk``)."""
    m = idx.shape[0]
    nr = kpos.shape[0]
    q = m + nkb
    M, L, S, LS, Li = small[0], small[1], small[2], small[3], small[4]
    for a in range(q):
        for b in range(q):
            M[a, b] = 0.0
    for a in range(m):
        for b in range(m):
            M[a, b] = R[a, b]
    if nkb:
        for r in range(nr):
            for c in range(nkb):
                s = 0.0
                for d in range(nkb):
                    s += Hk[r, d] * Pk[d, c]
                M[kpos[r], m + c] = s  # H_k P
                M[m + c, kpos[r]] = s
        for r in range(nr):
            for c in range(nr):
                s = 0.0
                for d in range(nkb):
                    s += M[kpos[r], m + d] * Hk[c, d]
                M[kpos[r], kpos[c]] += s  # + H_k P H_k'
        for c in range(nkb):
            for d in range(nkb):
                M[m + c, m + d] = Pk[c, d]
    if not _cholesky(M, L, q):
        return 1, 0.0
    n = w.shape[0]
    E, W, t = work[:m], work[m:2 * m], work[2 * m]
    for a in range(m):
        za = z[idx[a]]
        ra = idx[a]
        for i in range(n):
            E[a, i] = Zt[ra, i] - za  # E_i = zhat_i - z
    # predictive NIS: y = sum w_i E_i, S = sum w_i E_i E_i' - y y' + C (sums in fixed order)
    y = small[5, 0]
    for a in range(m):
        y[a] = row_dot(E, a, w)
        for i in range(n):
            t[i] = w[i] * E[a, i]
        for b in range(a + 1):
            S[a, b] = row_dot(E, b, t)
    for a in range(m):
        for b in range(a + 1):
            S[a, b] = S[a, b] - y[a] * y[b] + M[a, b]
            S[b, a] = S[a, b]
    if not _cholesky(S, LS, m):
        return 2, 0.0
    nis = 0.0
    for a in range(m):  # y' S^-1 y by forward substitution (y[b < a] hold the solution)
        u = y[a]
        for b in range(a):
            u -= LS[a, b] * y[b]
        u /= LS[a, a]
        y[a] = u
        nis += u * u
    # whitened residuals W = L_11^-1 E; particles -= L_21 W; ll_i = -|W_i|^2 / 2
    _lower_inverse(L, Li, m)
    for i in range(n):
        ll[i] = 0.0
    for a in range(m):
        la = Li[a, 0]
        for i in range(n):
            W[a, i] = la * E[0, i]
        for b in range(1, a + 1):
            la = Li[a, b]
            for i in range(n):
                W[a, i] += la * E[b, i]
        for i in range(n):
            ll[i] += 0.5 * (W[a, i] * W[a, i])
    for i in range(n):
        ll[i] = -ll[i]
    for c in range(nkb):
        la = L[m + c, 0]
        for i in range(n):
            t[i] = la * W[0, i]
        for a in range(1, m):
            la = L[m + c, a]
            for i in range(n):
                t[i] += la * W[a, i]
        row = sk[c]
        for i in range(n):
            particles[row, i] -= t[i]
    _outer_lower(L, m, nkb, Pk)
    return 0, nis
