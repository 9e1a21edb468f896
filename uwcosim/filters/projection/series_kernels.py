"""Compiled kernels of PFM-PSI's series (two gridded states): the series <-> grid quadratures,
the box, the normalization and the exact re-projection onto another box with the Gaussian
decay; :class:`CompiledSeriesOps`, the compiled form of
:class:`~uwcosim.filters.projection.series.SeriesOps`.

- :func:`to_grid2` / :func:`to_grid2_into` / :func:`from_grid2` (eqs. 37-38, 45-46): the
  quadratures of :func:`~uwcosim.filters.projection.series.to_grid` / ``from_grid`` with the
  Hermitian symmetry of the series and the ``n <-> M - n`` symmetry of the quadrature points
  folded (a quarter of the products of the plain transforms), as BLAS matrix products, on the
  trigonometric :func:`folded_tables` (a :class:`Tables` bundle);
- :func:`box` (eq. 33) and :func:`hermitian_normalize` (eqs. 40, 44, 48);
- :func:`shift_decay`: the re-projection ``T0 m T1'`` of a :class:`Series` onto another
  :class:`Box` (:func:`~uwcosim.filters.projection.series.reproject`), times the decay
  ``exp(-w' D w / 2)`` of the prediction (:func:`~uwcosim.filters.projection.series.
  diffusion_decay`). The one-dimensional transfer matrices are
  ``T[q', q] = l[q'] S[q', q] r[q]``: a real matrix ``S`` (the ``sin(x) / x`` of the frequency
  differences, scaled) between two diagonals of unit phases. So ``T0 m T1' = diag(l0) S0
  (diag(r0) m diag(r1)) S1' diag(l1)``: the phases cost a few products per coefficient, and
  the two complex matrix products become two real ones (BLAS ``dgemm``) on the real and
  imaginary parts side by side, half the multiplications of the complex products (``zgemm``).
  Only the rows ``q0 >= 0`` of the result are computed; the rows ``-q0`` are their conjugates
  (the result of a Hermitian series is Hermitian). The decay is separated into per-index
  factors (see :func:`_decay_rows`) and applied with the phases.

Every kernel computes what the numpy form computes, in another summation order: results agree
to round-off (``tests/test_projection_kernels.py``). IEEE arithmetic, sums in an order fixed in
the source (:mod:`uwcosim.core.jit`); bundles as NamedTuples or plain tuples of their fields.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from uwcosim.core.jit import jit
from uwcosim.filters.projection.series import TWO_PI, SeriesOps, SpectralBasis


class Series(NamedTuple):
    """A series on its box as the kernels take it."""

    m: np.ndarray  #: coefficients ``(2K+1, 2K+1)``, complex, indexed by ``q + K``
    lo: np.ndarray  #: lower corner of the box
    length: np.ndarray  #: its side lengths


class Box(NamedTuple):
    """A box: lower corner and side lengths."""

    lo: np.ndarray
    length: np.ndarray


class Tables(NamedTuple):
    """Trigonometric tables of the folded transforms (see :func:`folded_tables`)."""

    Tq: np.ndarray  #: ``[C | S]``, ``(2K+1, 2R)``
    Tx: np.ndarray  #: ``(w C0)'`` and ``(w S0)'``, ``(2, M, K+1)``
    Tg: np.ndarray  #: ``[C', S']``, ``(2, R, 2K+1)``
    Tm: np.ndarray  #: ``[C0, S0]``, ``(2, K+1, R)``


# ---------------------------------------------------------------------------------------------
# tables (computed once per (K, M))

_TABLES: dict = {}


def folded_tables(K: int, M: int) -> Tables:
    """Trigonometric tables of the folded transforms for ``q = -K..K`` on ``M`` points.

    Both grid directions are folded by the symmetry of the points ``n`` and ``M - n`` (equal
    cosines, opposite sines): only ``n = 0..R-1``, ``R = M // 2 + 1``, enter the products (half
    the arithmetic). With ``C[q, n] = cos(2 pi q n / M)``, ``S`` the sines (``q = -K..K``,
    ``n < R``) and ``C0``, ``S0`` their rows ``q = 0..K``, returns :class:`Tables`
    ``(Tq, Tx, Tg, Tm)``:
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
        out = _TABLES[key] = Tables(Tq, Tx, Tg, Tm)
    return out


# ---------------------------------------------------------------------------------------------
# series <-> grid (two gridded states)


@jit
def to_grid2(m, tables, scale):
    """:func:`to_grid2_into` a new ``M x M`` array."""
    _, Tx, _, _ = tables
    M = Tx.shape[1]
    out = np.empty((M, M))
    to_grid2_into(m, tables, scale, out)
    return out


@jit
def to_grid2_into(m, tables, scale, out):
    """Real values times ``scale`` on the ``M x M`` grid of the Hermitian series ``m``
    (``(2K+1, 2K+1)``) with the :class:`Tables` ``tables``, written into ``out``.

    The rows ``q_0 >= 0`` (Hermitian symmetry), the points ``n < R`` of both directions (the
    fold of :func:`folded_tables`): ``A(n_1) = [m_r | m_i] (C + iS)`` from the four real products
    ``EC = m_r C``, ``ES = m_i S``, ``FS = m_r S``, ``FC = m_i C`` (``A(M - n_1)`` flips the
    sines), then ``P = w C0' A_r``, ``Q = w S0' A_i``: ``out[n_0] = P - Q``,
    ``out[M - n_0] = P + Q``."""
    Tq, Tx, _, _ = tables
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
def from_grid2(g, tables, scale):
    """Coefficients ``<g, phi_q>`` times ``scale`` (FFT quadrature) of real grid values ``g``
    (``M x M``) with the :class:`Tables` ``tables``.

    Folded as :func:`to_grid2`: the rows ``n_0`` and ``M - n_0`` of ``g`` are added (cosine
    part) and subtracted (sine part) before the products with ``C0``, ``S0`` (``q_0 >= 0``:
    Hermitian symmetry), then the columns of those products likewise before ``C'``, ``S'``."""
    _, _, Tg, Tm = tables
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


# ---------------------------------------------------------------------------------------------
# re-projection onto another box, with the Gaussian decay

# exponents up to this size (|log| of every separated decay factor and of their products)
# keep the separated decay within the normal doubles (e^-700 ~ 1e-304, e^700 ~ 1e304)
_SEPARABLE_LIMIT = 700.0


@jit
def _sinc(d):
    """``sin(d) / d`` for ``|d| < 0.5`` by its Taylor series (Horner in ``d^2``; the first
    omitted term is below ``5e-17``)."""
    x = d * d
    return 1.0 - x / 6.0 * (1.0 - x / 20.0 * (1.0 - x / 42.0 * (1.0 - x / 72.0 * (
        1.0 - x / 110.0 * (1.0 - x / 156.0 * (1.0 - x / 210.0))))))


@jit
def _powers(K, angle, out_c, out_s):
    """``cos(q angle)``, ``sin(q angle)`` for ``q = 0..K`` into ``out_c[K + q]``,
    ``out_s[K + q]`` and the mirrored ``-q`` (``out_c[K - q]``, ``-out_s[K + q]``): by the
    recurrence ``e^{i q a} = e^{i (q-1) a} e^{i a}`` (``|error| <= 2 q eps``, two trigonometric
    calls instead of ``2 (K + 1)``)."""
    c1, s1 = math.cos(angle), math.sin(angle)
    c, s = 1.0, 0.0
    for q in range(K + 1):
        out_c[K + q] = c
        out_s[K + q] = s
        out_c[K - q] = c
        out_s[K - q] = -s
        c, s = c * c1 - s * s1, s * c1 + c * s1


@jit
def _transfer(K, lo, length, lo2, length2, S, full, ph):
    """One dimension of :func:`~uwcosim.filters.projection.series.transfer_matrix` as
    ``T[q', q] = l[q'] S[q', q] r[q]``: the real ``S`` and the phases ``l = ph[0] + i ph[1]``,
    ``r = ph[2] + i ph[3]`` (index ``K + q``; ``ph`` has 10 rows, the others scratch).

    Not ``full``: the rows ``q' = 0..K`` of ``S`` into ``S`` (``K + 1`` rows). ``full``: all of
    ``S`` transposed (``S[q, q']``, the layout a BLAS product takes fastest), the rows ``-q'``
    mirrored, ``S[-q', -q] = S[q', q]`` exactly. ``S = 0`` when
    the intervals do not overlap. The sine of the difference ``sin(x_i - y_j)`` is
    ``sin x cos y - cos x sin y`` from per-index factors (``|error| <= 2 (2K + 3) eps /
    |delta|``), ``sin(d) / d`` near the diagonal its series (:func:`_sinc`); the factors are
    powers of unit complex numbers (:func:`_powers`)."""
    n = 2 * K + 1
    a = max(lo, lo2)
    w = min(lo + length, lo2 + length2) - a
    if not w > 0.0:
        S[:, :] = 0.0
        ph[:4] = 0.0
        return
    c = w / math.sqrt(length * length2)
    hw = -0.5 * w
    b2 = TWO_PI / length2  # om2 of q = 1
    b1 = TWO_PI / length
    _powers(K, -b2 * (a - lo2 + 0.5 * w), ph[0], ph[1])
    _powers(K, b1 * (a - lo + 0.5 * w), ph[2], ph[3])
    _powers(K, hw * b2, ph[4], ph[5])  # cos, sin of x_i = -w om2[i] / 2
    _powers(K, hw * b1, ph[6], ph[7])  # cos, sin of y_j = -w om[j] / 2
    ca, sa, cb, sb, om = ph[4], ph[5], ph[6], ph[7], ph[8]
    for j in range(K, n):
        om[j] = TWO_PI * (j - K) / length
        om[n - 1 - j] = -om[j]
    near = 0.5 / abs(hw) * (length / TWO_PI)  # |delta| < 0.5: |j - K - om2 L / 2 pi| < near
    for q in range(K + 1):
        om2 = TWO_PI * q / length2
        cq, sq = ca[K + q], sa[K + q]
        row = ph[9]
        for j in range(n):  # no branch: vectorizes; the near-diagonal entries are redone below
            row[j] = (sq * cb[j] - cq * sb[j]) / ((om2 - om[j]) * hw) * c
        # the candidates j (one more on each side against rounding): a loop over all j would
        # be vectorized with _sinc computed for every j (speculated), 3x the time of the above
        centre = K + om2 * (length / TWO_PI)
        lo_j, hi_j = centre - near - 1.0, centre + near + 1.0  # NaN: all j
        j0 = 0 if not lo_j > 0.0 else (n if lo_j >= n else int(lo_j))
        j1 = n - 1 if not hi_j < n - 1.0 else (-1 if hi_j < 0.0 else int(math.ceil(hi_j)))
        for j in range(j0, j1 + 1):
            delta = (om2 - om[j]) * hw
            if abs(delta) < 0.5:  # sin(x - y) from the factors cancels: its series
                row[j] = _sinc(delta) * c
        if full:
            for j in range(n):
                S[j, K + q] = row[j]
                S[n - 1 - j, K - q] = row[j]
        else:
            S[q] = row


@jit
def _decay_rows(K, length2, D, f0r, f0i, f1r, f1i, cross):
    """Multiply the factors ``f0`` (rows ``q0 = 0..K``) and ``f1`` (columns ``q1 = -K..K``) by
    the separable parts of ``exp(-w' D w / 2)`` and put the rest in ``cross[q0, K + q1]``
    (ones on entry).

    With ``a = 2 pi q0 / L0``, ``b = 2 pi q1 / L1``: ``exp(-D00 a^2 / 2)`` goes to ``f0``,
    ``exp(-D11 b^2 / 2)`` to ``f1`` and ``exp(-D01 a b) = rho^q1``, ``rho =
    exp(-D01 a 2 pi / L1)``, is a chain of products (both signs of ``q1``): 3K + 1 + 2K
    exponentials instead of ``(K + 1) (2K + 1)``. It differs from the direct ``exp(-quad)``
    (:func:`~uwcosim.filters.projection.series.diffusion_decay`) by a few ulps per step of the
    chain (``K + 2`` at most) plus, as the direct form, the rounding of the exponents (relative
    ``|exponent| eps``). When a separated exponent could leave the normal doubles (``|D00|
    a^2 / 2 + |D11| b^2 / 2 + |D01 a b| > 700`` on the highest modes; or not finite), the
    separated factors could underflow to 0 while the cross term overflows: then every entry
    is the direct ``exp(-quad)`` (``cross``; ``f0``, ``f1`` unchanged)."""
    n = 2 * K + 1
    L0, L1 = length2[0], length2[1]
    h00, h11, d01 = 0.5 * D[0, 0], 0.5 * D[1, 1], D[0, 1]
    aK, bK = TWO_PI * K / L0, TWO_PI * K / L1
    bound = abs(h00) * (aK * aK) + abs(h11) * (bK * bK) + abs(d01) * aK * bK
    if not bound <= _SEPARABLE_LIMIT:
        for i in range(K + 1):
            a = TWO_PI * i / L0
            for j in range(n):
                b = TWO_PI * (j - K) / L1
                cross[i, j] = math.exp(-(h00 * (a * a) + h11 * (b * b) + (d01 * a) * b))
        return
    for t in range(K + 1):
        b = TWO_PI * t / L1
        e = math.exp(-(h11 * (b * b)))
        f1r[K + t] *= e
        f1i[K + t] *= e
        if t > 0:
            f1r[K - t] *= e
            f1i[K - t] *= e
    beta = TWO_PI / L1
    for i in range(K + 1):
        a = TWO_PI * i / L0
        e = math.exp(-(h00 * (a * a)))
        f0r[i] *= e
        f0i[i] *= e
        if i == 0 or d01 == 0.0:
            continue
        row = cross[i]
        g = (d01 * a) * beta
        rho, rinv = math.exp(-g), math.exp(g)
        for t in range(1, K + 1):
            row[K + t] = row[K + t - 1] * rho
            row[K - t] = row[K - t + 1] * rinv


@jit
def shift_decay_mass(series, new, D, decay, sv, normalize):
    """:func:`shift_decay` and the mass ``sv * out[K, K].real`` of the result (``sv`` the
    square root of the new box's volume). When ``normalize`` and the mass is finite and
    positive, the result is also made Hermitian and divided by the mass (as
    :func:`hermitian_normalize`, here only the centre row needs it: the others are mirrored
    exactly; the division is a multiplication by ``1 / mass`` folded into the row factors)."""
    m, lo, length = series
    lo2, length2 = new
    K = (m.shape[0] - 1) // 2
    n = 2 * K + 1
    h = K + 1
    S0 = np.empty((h, n))
    S1 = np.empty((n, n))
    ph = np.empty((2, 10, n))
    _transfer(K, lo[0], length[0], lo2[0], length2[0], S0, False, ph[0])  # rows q0 >= 0
    _transfer(K, lo[1], length[1], lo2[1], length2[1], S1, True, ph[1])  # S1'
    # diag(r0) m diag(r1), real parts then imaginary parts of each row
    M = np.empty((n, 2 * n))
    r0c, r0s, r1c, r1s = ph[0, 2], ph[0, 3], ph[1, 2], ph[1, 3]
    for i in range(n):
        for j in range(n):
            v = m[i, j]
            xr = r0c[i] * v.real - r0s[i] * v.imag
            xi = r0c[i] * v.imag + r0s[i] * v.real
            M[i, j] = xr * r1c[j] - xi * r1s[j]
            M[i, n + j] = xr * r1s[j] + xi * r1c[j]
    # S0 M: rows [re | im]; as (2h, n) the rows alternate re, im; times S1'
    Y = (S0 @ M).reshape((2 * h, n)) @ S1
    mass = sv * Y[0, K]  # l0[0] = l1[K] = 1 and the decay of (0, 0) is 1: exact
    scale = 1.0
    normalize = normalize and math.isfinite(mass) and mass > 0.0
    if normalize:
        scale = 1.0 / mass
    f = np.empty((4, n))  # l0 (rows q0 >= 0: entries 0..K), l1
    cross = np.ones((h, n))
    for i in range(h):
        f[0, i] = ph[0, 0, K + i] * scale
        f[1, i] = ph[0, 1, K + i] * scale
    for j in range(n):
        f[2, j] = ph[1, 0, j]
        f[3, j] = ph[1, 1, j]
    if decay:
        _decay_rows(K, length2, D, f[0], f[1], f[2], f[3], cross)
    out = np.empty((n, n), np.complex128)
    for i in range(h):
        f0 = complex(f[0, i], f[1, i])
        for j in range(n):
            v = complex(Y[2 * i, j], Y[2 * i + 1, j]) * f0 * complex(f[2, j] * cross[i, j],
                                                                     f[3, j] * cross[i, j])
            out[K + i, j] = v
            if i > 0:
                out[K - i, n - 1 - j] = v.conjugate()
    if normalize:  # the centre row: (out + conj(out mirrored)) / 2
        for j in range(K + 1):
            a, b = out[K, j], out[K, n - 1 - j]
            out[K, j] = 0.5 * (a + b.conjugate())
            out[K, n - 1 - j] = 0.5 * (b + a.conjugate())
    return out, mass


@jit
def shift_decay(series, new, D, decay):
    """Re-projection of the :class:`Series` ``series`` onto the :class:`Box` ``new`` (exact
    integrals, :func:`~uwcosim.filters.projection.series.reproject`), times
    ``exp(-w' D w / 2)`` on the new box when ``decay``
    (:func:`~uwcosim.filters.projection.series.diffusion_decay`, separated as in
    :func:`_decay_rows`). Agrees with those to round-off (relative to the largest coefficient,
    ``tests/test_projection_kernels.py``)."""
    out, _ = shift_decay_mass(series, new, D, decay, 1.0, False)
    return out


# ---------------------------------------------------------------------------------------------
# box, normalization, quadrature grid


@jit
def box(mean, cov, k_sigma, min_halfwidth):
    """:func:`~uwcosim.filters.projection.series.symmetric_interval` (eq. 33): ``(lo, length)``
    of ``mean -+ max(k_sigma sigma, floor)``."""
    n = mean.size
    lo = np.empty(n)
    length = np.empty(n)
    for d in range(n):
        sig = math.sqrt(max(cov[d, d], 0.0))
        floor = max(min_halfwidth, 1e-9 * max(1.0, abs(mean[d])))
        half = max(k_sigma * sig, floor)
        lo[d] = mean[d] - half
        length[d] = 2.0 * half
    return lo, length


@jit
def hermitian_normalize(m, sqrt_volume):
    """``m = (m + conj(m_-q)) / 2`` in place; divide by the mass ``sqrt_volume m_0`` when it is
    finite and > 0 (eqs. 40, 44, 48). Returns the mass
    (:func:`~uwcosim.filters.projection.series.normalize`)."""
    n0, n1 = m.shape
    for f in range((n0 * n1 + 1) // 2):  # each entry and its mirror (the centre alone) once
        i, j = f // n1, f % n1
        a, b = m[i, j], m[n0 - 1 - i, n1 - 1 - j]
        m[i, j] = 0.5 * (a + b.conjugate())
        m[n0 - 1 - i, n1 - 1 - j] = 0.5 * (b + a.conjugate())
    c = m[(n0 - 1) // 2, (n1 - 1) // 2]
    mass = sqrt_volume * c.real
    if math.isfinite(mass) and mass > 0.0:
        m /= mass
    return mass


@jit
def grid_axes(lo, length, M):
    """:meth:`~uwcosim.filters.projection.series.SpectralBasis.axes`: ``lo + L n / M``,
    ``n = 0..M-1``, per dimension (eq. 34)."""
    xs = np.empty(M)
    ys = np.empty(M)
    for i in range(M):
        xs[i] = lo[0] + length[0] * i / M
        ys[i] = lo[1] + length[1] * i / M
    return xs, ys


_NO_D = np.zeros((2, 2))  # no decay


class CompiledSeriesOps(SeriesOps):
    """:class:`~uwcosim.filters.projection.series.SeriesOps` by the kernels above (two gridded
    states)."""

    compiled = True

    def box(self, mean, cov) -> tuple[np.ndarray, np.ndarray]:
        return box(mean, cov, self.k_sigma, self.min_halfwidth)

    def _normalize(self, m: np.ndarray, basis: SpectralBasis) -> float:
        return hermitian_normalize(m, basis.sqrt_volume())

    def reproject(self, m: np.ndarray, basis: SpectralBasis, new: SpectralBasis) -> np.ndarray:
        return shift_decay((m, basis.lo, basis.length), (new.lo, new.length), _NO_D, False)
