"""The series <-> grid transforms of the projection filter's kernels (two gridded states): the
folded quadratures :func:`to_grid2` / :func:`to_grid2_into` / :func:`from_grid2` and their
trigonometric :func:`tables`. Reached through :mod:`uwcosim.filters.grid.projection_kernels`
(see its docstring for the arithmetic rules: IEEE, sums in a fixed order)."""

from __future__ import annotations

import numpy as np

from uwcosim.core.jit import jit

TWO_PI = 2.0 * np.pi


# ---------------------------------------------------------------------------------------------
# tables (computed once per (K, M))

_TABLES: dict = {}


def tables(K: int, M: int):
    """Trigonometric tables of the folded transforms for ``q = -K..K`` on ``M`` points.

    Both grid directions are folded by the symmetry of the points ``n`` and ``M - n`` (equal
    cosines, opposite sines): only ``n = 0..R-1``, ``R = M // 2 + 1``, enter the products (half
    the arithmetic). With ``C[q, n] = cos(2 pi q n / M)``, ``S`` the sines (``q = -K..K``,
    ``n < R``) and ``C0``, ``S0`` their rows ``q = 0..K``, returns ``(Tq, Tx, Tg, Tm)``:
    ``Tq = [C | S]`` (``(2K+1, 2R)``); ``Tx`` (``(2, M, K+1)``, ``M`` read from its shape) with
    ``Tx[0, :R] = (w C0)'``, ``Tx[1, :R] = (w S0)'``, ``w = 1, 2, 2, ...``; ``Tg = [C', S']``
    (``(2, R, 2K+1)``); ``Tm = [C0, S0]`` (``(2, K+1, R)``).
    """
    key = (K, M)
    out = _TABLES.get(key)
    if out is None:
        R = M // 2 + 1
        n = np.arange(R)
        q = np.arange(-K, K + 1)
        ang = TWO_PI * np.outer(q, n) / M
        C, S = np.cos(ang), np.sin(ang)
        Tq = np.ascontiguousarray(np.hstack([C, S]))
        q0 = np.arange(K + 1)
        ang0 = TWO_PI * np.outer(q0, n) / M
        C0, S0 = np.cos(ang0), np.sin(ang0)
        w = np.where(q0 == 0, 1.0, 2.0)[:, None]
        Tx = np.zeros((2, M, K + 1))
        Tx[0, :R] = (w * C0).T
        Tx[1, :R] = (w * S0).T
        Tg = np.ascontiguousarray(np.stack([C.T, S.T]))
        Tm = np.ascontiguousarray(np.stack([C0, S0]))
        out = _TABLES[key] = (Tq, Tx, Tg, Tm)
    return out



# ---------------------------------------------------------------------------------------------
# series <-> grid (two gridded states)


@jit
def to_grid2(m, Tq, Tx, scale):
    """:func:`to_grid2_into` a new ``M x M`` array."""
    M = Tx.shape[1]
    out = np.empty((M, M))
    to_grid2_into(m, Tq, Tx, scale, out)
    return out


@jit
def to_grid2_into(m, Tq, Tx, scale, out):
    """Real values on the ``M x M`` grid of the Hermitian series ``m`` (``(2K+1, 2K+1)``),
    written into ``out``.

    The rows ``q_0 >= 0`` (Hermitian symmetry), the points ``n < R`` of both directions (the
    fold of :func:`tables`): ``A(n_1) = [m_r | m_i] (C + iS)`` from the four real products
    ``EC = m_r C``, ``ES = m_i S``, ``FS = m_r S``, ``FC = m_i C`` (``A(M - n_1)`` flips the
    sines), then ``P = w C0' A_r``, ``Q = w S0' A_i``: ``out[n_0] = P - Q``,
    ``out[M - n_0] = P + Q``."""
    K = (m.shape[0] - 1) // 2
    n = m.shape[1]
    M = Tx.shape[1]
    R = M // 2 + 1
    H = (M - 1) // 2  # points n = 1..H have a mirror M - n
    half = np.empty((2 * (K + 1), n))
    for j in range(K + 1):
        for q in range(n):
            v = m[K + j, q]
            half[j, q] = v.real
            half[K + 1 + j, q] = v.imag
    E = half @ Tq  # [[EC, FS], [FC, ES]], (2(K+1), 2R)
    Ar = np.empty((K + 1, M))
    Ai = np.empty((K + 1, M))
    for j in range(K + 1):
        for c in range(R):
            Ar[j, c] = E[j, c] - E[K + 1 + j, R + c]
            Ai[j, c] = E[j, R + c] + E[K + 1 + j, c]
        for c in range(1, H + 1):
            Ar[j, M - c] = E[j, c] + E[K + 1 + j, R + c]
            Ai[j, M - c] = E[K + 1 + j, c] - E[j, R + c]
    P = Tx[0, :R] @ Ar
    Q = Tx[1, :R] @ Ai
    for r in range(R):
        for c in range(M):
            out[r, c] = (P[r, c] - Q[r, c]) * scale
    for r in range(1, H + 1):
        for c in range(M):
            out[M - r, c] = (P[r, c] + Q[r, c]) * scale


@jit
def from_grid2(g, Tg, Tm, scale):
    """Coefficients ``<g, phi_q>`` (FFT quadrature) of real grid values ``g`` (``M x M``).

    Folded as :func:`to_grid2`: the rows ``n_0`` and ``M - n_0`` of ``g`` are added (cosine
    part) and subtracted (sine part) before the products with ``C0``, ``S0`` (``q_0 >= 0``:
    Hermitian symmetry), then the columns of those products likewise before ``C'``, ``S'``."""
    n = Tg.shape[2]
    K = (n - 1) // 2
    M = g.shape[0]
    R = M // 2 + 1
    H = (M - 1) // 2
    Ge = np.empty((R, M))
    Go = np.empty((R, M))
    for r in range(H + 1, R):  # the rows without mirror: 0, and M/2 when M is even
        for c in range(M):
            Ge[r, c] = g[r, c]
            Go[r, c] = g[r, c]
    for c in range(M):
        Ge[0, c] = g[0, c]
        Go[0, c] = g[0, c]
    for r in range(1, H + 1):
        for c in range(M):
            Ge[r, c] = g[r, c] + g[M - r, c]
            Go[r, c] = g[r, c] - g[M - r, c]
    X0 = Tm[0] @ Ge  # C0 g, (K+1, M)
    X1 = Tm[1] @ Go  # S0 g
    Xe = np.empty((2 * (K + 1), R))  # [C0 g; S0 g], columns folded: even, odd
    Xo = np.empty((2 * (K + 1), R))
    for j in range(K + 1):
        _fold_columns(Xe, Xo, j, X0, j)
        _fold_columns(Xe, Xo, K + 1 + j, X1, j)
    PC = Xe @ Tg[0]  # [C0 g C'; S0 g C'], (2(K+1), 2K+1)
    PS = Xo @ Tg[1]  # [C0 g S'; S0 g S']
    m = np.empty((n, n), np.complex128)
    for j in range(K + 1):
        for q in range(n):
            re = PC[j, q] - PS[K + 1 + j, q]
            im = -PS[j, q] - PC[K + 1 + j, q]
            m[K + j, q] = complex(re * scale, im * scale)
    for j in range(1, K + 1):
        for q in range(n):
            m[K - j, q] = m[K + j, n - 1 - q].conjugate()
    return m


@jit
def _fold_columns(Xe, Xo, k, X, j):
    """Row ``k`` of ``Xe`` / ``Xo``: sums / differences of the columns ``c`` and ``M - c`` of
    ``X[j]`` (the columns without mirror as they are). A function of its own: its loops
    vectorize."""
    M = X.shape[1]
    R = Xe.shape[1]
    H = (M - 1) // 2
    Xe[k, 0] = X[j, 0]
    Xo[k, 0] = X[j, 0]
    for c in range(1, H + 1):
        a = X[j, c]
        b = X[j, M - c]
        Xe[k, c] = a + b
        Xo[k, c] = a - b
    for c in range(H + 1, R):
        Xe[k, c] = X[j, c]
        Xo[k, c] = X[j, c]
