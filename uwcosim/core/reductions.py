"""Reductions of the compiled kernels in an order fixed in the source (deterministic without
fast-math, and vectorizable).

A sum written as one accumulator is a chain of dependent additions (4 cycles each): 16 us for
a 64 x 64 grid, and without reassociation LLVM may not split it. These sums keep eight partial
sums over the columns ``j mod 8`` (row after row), combined as ``((s0 + s1) + (s2 + s3)) +
((s4 + s5) + (s6 + s7))``: the order is in the source, so the result is the same however the
kernel was compiled (:mod:`uwcosim.core.jit`), and the eight independent chains vectorize
without fast-math. Extremes are exact in any order; they keep several running extremes (or
one per column) for the same reason.

Used by the grid filters' kernels (:mod:`uwcosim.filters.grid`, :mod:`uwcosim.filters.projection`,
:mod:`uwcosim.filters.point_mass`) and the marginalized particle filter's
(:mod:`uwcosim.filters.rbpf_kernels`).
"""

from __future__ import annotations

import numpy as np

from uwcosim.core.jit import jit


@jit
def sum2(a, neg):
    """``a.sum()`` (``np.minimum(a, 0).sum()`` when ``neg``) of a 2-D array: row sums in the
    fixed order above, added row after row."""
    s = 0.0
    for i in range(a.shape[0]):
        s += row_sum(a, i, neg)
    return s


@jit
def row_dot(a, i, x):
    """``a[i] @ x`` in the fixed order above (``x`` of length ``a.shape[1]``)."""
    n1 = a.shape[1]
    m = n1 - n1 % 8
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for j in range(0, m, 8):
        s0 += a[i, j] * x[j]
        s1 += a[i, j + 1] * x[j + 1]
        s2 += a[i, j + 2] * x[j + 2]
        s3 += a[i, j + 3] * x[j + 3]
        s4 += a[i, j + 4] * x[j + 4]
        s5 += a[i, j + 5] * x[j + 5]
        s6 += a[i, j + 6] * x[j + 6]
        s7 += a[i, j + 7] * x[j + 7]
    for j in range(m, n1):
        s0 += a[i, j] * x[j]
    return ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7))


@jit
def _clip(v, neg):
    return min(v, 0.0) if neg else v


@jit
def row_sum(a, i, neg):
    """``a[i].sum()`` (of ``min(a[i], 0)`` when ``neg``) in the fixed order above."""
    n1 = a.shape[1]
    m = n1 - n1 % 8
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for j in range(0, m, 8):
        s0 += _clip(a[i, j], neg)
        s1 += _clip(a[i, j + 1], neg)
        s2 += _clip(a[i, j + 2], neg)
        s3 += _clip(a[i, j + 3], neg)
        s4 += _clip(a[i, j + 4], neg)
        s5 += _clip(a[i, j + 5], neg)
        s6 += _clip(a[i, j + 6], neg)
        s7 += _clip(a[i, j + 7], neg)
    for j in range(m, n1):
        s0 += _clip(a[i, j], neg)
    return ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7))


@jit
def max2(a):
    """``a.max()`` of a 2-D array (exact in any order; four running maxima)."""
    n0, n1 = a.shape
    m = n1 - n1 % 4
    a0 = a1 = a2 = a3 = -np.inf
    for i in range(n0):
        for j in range(0, m, 4):
            a0 = max(a0, a[i, j])
            a1 = max(a1, a[i, j + 1])
            a2 = max(a2, a[i, j + 2])
            a3 = max(a3, a[i, j + 3])
        for j in range(m, n1):
            a0 = max(a0, a[i, j])
    return max(max(a0, a1), max(a2, a3))


@jit
def col_min_max(lo, hi, a, i):
    """``lo = minimum(lo, a[i])``, ``hi = maximum(hi, a[i])`` in place (elementwise: a loop
    that vectorizes, where a running extreme is a chain of dependent comparisons)."""
    for j in range(a.shape[1]):
        lo[j] = min(lo[j], a[i, j])
        hi[j] = max(hi[j], a[i, j])


@jit
def col_max(hi, a, i):
    """``hi = maximum(hi, a[i])`` in place (see :func:`col_min_max`)."""
    for j in range(a.shape[1]):
        hi[j] = max(hi[j], a[i, j])


@jit
def max1(a):
    """``a.max()`` of a 1-D array (exact in any order)."""
    r = -np.inf
    for j in range(a.size):
        r = max(r, a[j])
    return r


@jit
def min1(a):
    """``a.min()`` of a 1-D array (exact in any order)."""
    r = np.inf
    for j in range(a.size):
        r = min(r, a[j])
    return r


@jit
def neg_sum2(a):
    """``np.minimum(a, 0).sum()`` of a 2-D array: column sums (row after row, an elementwise
    loop that vectorizes), then their sum in the fixed order of :func:`row_sum`."""
    n0, n1 = a.shape
    acc = np.zeros((1, n1))
    for i in range(n0):
        for j in range(n1):
            acc[0, j] += min(a[i, j], 0.0)
    return row_sum(acc, 0, False)
