"""Compiled kernel of the projection filter's prediction: the exact re-projection of the series
onto a moved box with the Gaussian decay (:func:`shift_decay`; the fused prediction step is in
:mod:`uwcosim.filters.grid.projection_kalman`, which re-exports this module's kernels).

The re-projection is ``T0 m T1'`` with the one-dimensional transfer matrices of
:func:`~uwcosim.filters.grid.spectral.transfer_matrix`, ``T[q', q] = l[q'] S[q', q] r[q]``: a
real matrix ``S`` (the ``sin(x) / x`` of the frequency differences, scaled) between two
diagonals of unit phases. So ``T0 m T1' = diag(l0) S0 (diag(r0) m diag(r1)) S1' diag(l1)``:
the phases cost a few products per coefficient, and the two complex matrix products become
two real ones (BLAS ``dgemm``) on the real and imaginary parts side by side, half the
multiplications of the complex products (``zgemm``). Only the rows ``q0 >= 0`` of the result
are computed; the rows ``-q0`` are their conjugates (the result of a Hermitian series is
Hermitian). The decay ``exp(-w' D w / 2)`` is separated into per-index factors (see
:func:`_decay_rows`) and applied with the phases. Same conventions and lazy compilation as
:mod:`uwcosim.filters.grid.projection_kernels`.
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit
from uwcosim.filters.grid.spectral import TWO_PI

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
    """One dimension of :func:`~uwcosim.filters.grid.spectral.transfer_matrix` as
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
    (:func:`~uwcosim.filters.grid.spectral.diffusion_decay`) by a few ulps per step of the
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
def _shift_decay(m, lo, length, lo2, length2, D, decay, sv, normalize):
    """:func:`shift_decay` and the mass ``sv * out[K, K].real`` of the result (``sv`` the
    square root of the new box's volume). When ``normalize`` and the mass is finite and
    positive, the result is also made Hermitian and divided by the mass (as
    :func:`~uwcosim.filters.grid.projection_kernels.hermitian_normalize`, here only the
    centre row needs it: the others are mirrored exactly; the division is a multiplication
    by ``1 / mass`` folded into the row factors)."""
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
def shift_decay(m, lo, length, lo2, length2, D, decay):
    """Re-projection of ``m`` from the box ``(lo, length)`` onto ``(lo2, length2)`` (exact
    integrals, :func:`~uwcosim.filters.grid.spectral.reproject`), times ``exp(-w' D w / 2)``
    on the new box when ``decay`` (:func:`~uwcosim.filters.grid.spectral.diffusion_decay`,
    separated as in :func:`_decay_rows`). Agrees with those to round-off (relative to the
    largest coefficient, ``tests/test_projection_kernels.py``)."""
    out, _ = _shift_decay(m, lo, length, lo2, length2, D, decay, 1.0, False)
    return out
