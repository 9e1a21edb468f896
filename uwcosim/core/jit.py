"""Compilation of the grid filters' kernels (Numba), and the reductions they share.

Kernels are plain Python functions decorated with :func:`_jit` (or :func:`_jit_fast`); Numba
is imported, and every registered kernel bound to its compiled version, at the first call of
any kernel, not at import (about 0.5 s that scenarios without these filters do not pay).
Compiled kernels are cached on disk (``cache=True``). Without Numba, or with
``UWCOSIM_NUMBA=0``, :data:`ENABLED` is False and the filters run their numpy code.

The reductions (:func:`_sum2`, :func:`_row_sum`, ...) keep several partial sums combined in an
order fixed in the source: deterministic without fast-math (a freshly compiled kernel and a
cached one give the same bits, ``tests/test_kernel_determinism.py``) and still vectorizable.
"""

from __future__ import annotations

import functools
import importlib.util
import os

import numpy as np

ENABLED = (importlib.util.find_spec("numba") is not None
           and os.environ.get("UWCOSIM_NUMBA", "1") != "0")


# Numba is imported (about 0.5 s) and the kernels are bound to their compiled versions at the
# first call of any kernel, not at import: scenarios without these filters do not pay for it.
# Kernels live in projection_kernels, projection_kalman, projection_predict and
# point_mass_kernels (and the reductions below); all register here.
_PLAIN: list[tuple] = []  # (python function, fastmath flags, first-call stub)


def _compile_all() -> None:
    """Compile every registered kernel (lazily: Numba compiles or loads a kernel from its
    on-disk cache at its first call) and bind the compiled kernels wherever the modules hold
    the first-call stubs (their own names and the names they import from each other)."""
    import numba

    compiled = {}
    spaces = {}
    for fn, fastmath, stub in _PLAIN:
        jit = numba.njit(cache=True, nogil=True, error_model="numpy", fastmath=fastmath)
        compiled[id(stub)] = (stub, jit(fn))
        spaces[id(fn.__globals__)] = fn.__globals__
    for g in spaces.values():
        for name, value in list(g.items()):
            hit = compiled.get(id(value))
            if hit is not None and hit[0] is value:
                g[name] = hit[1]
    _PLAIN.clear()


def _register(fn, fastmath):
    @functools.wraps(fn)
    def first_call(*args):
        if _PLAIN:
            _compile_all()
        return fn.__globals__[fn.__name__](*args)

    _PLAIN.append((fn, fastmath, first_call))
    return first_call


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a KeyboardInterrupt that a compiled kernel wrapped: Ctrl-C landing in
    the Python code Numba runs while it returns arrays surfaces as a ``SystemError`` caused by
    the ``KeyboardInterrupt`` (callers re-raise it as the interrupt it is)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _jit_fast(fn):
    """Kernels that test nothing for finiteness (IEEE arithmetic, as :func:`_jit`; kept apart
    so that their flags can be revisited on their own)."""
    return _register(fn, False)


def _jit(fn):
    """IEEE arithmetic in source order: no fast-math. Reassociation and contraction let LLVM's
    result depend on what it inlines, and a kernel compiled afresh then differed in the last
    bits from the same kernel loaded from Numba's cache, so that the same scenario and seed
    gave different logs on a fresh machine (measured: 1e-11 m in PFM-PSI's estimate). What
    fast-math bought (vectorized sums) is written out instead: sums over grids keep several
    partial sums combined in a fixed order (:func:`_row_sum`), legal to vectorize as IEEE."""
    return _register(fn, False)


# ---------------------------------------------------------------------------------------------
# reductions in a fixed order (deterministic without fast-math, and vectorizable)
#
# A sum written as one accumulator is a chain of dependent additions (4 cycles each): 16 us for
# a 64 x 64 grid, and without reassociation LLVM may not split it. These sums keep eight partial
# sums over the columns ``j mod 8`` (row after row), combined as ``((s0 + s1) + (s2 + s3)) +
# ((s4 + s5) + (s6 + s7))``: the order is in the source, so the result is the same however
# the kernel was compiled, and the eight independent chains vectorize without fast-math.


@_jit
def _sum2(a, neg):
    """``a.sum()`` (``np.minimum(a, 0).sum()`` when ``neg``) of a 2-D array: row sums in the
    fixed order above, added row after row."""
    s = 0.0
    for i in range(a.shape[0]):
        s += _row_sum(a, i, neg)
    return s


@_jit
def _row_dot(a, i, x):
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


@_jit
def _clip(v, neg):
    return min(v, 0.0) if neg else v


@_jit
def _row_sum(a, i, neg):
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


@_jit
def _max2(a):
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


@_jit
def _col_min_max(lo, hi, a, i):
    """``lo = minimum(lo, a[i])``, ``hi = maximum(hi, a[i])`` in place (elementwise: a loop
    that vectorizes, where a running extreme is a chain of dependent comparisons)."""
    for j in range(a.shape[1]):
        lo[j] = min(lo[j], a[i, j])
        hi[j] = max(hi[j], a[i, j])


@_jit
def _col_max(hi, a, i):
    """``hi = maximum(hi, a[i])`` in place (see :func:`_col_min_max`)."""
    for j in range(a.shape[1]):
        hi[j] = max(hi[j], a[i, j])


@_jit
def _max1(a):
    """``a.max()`` of a 1-D array (exact in any order)."""
    r = -np.inf
    for j in range(a.size):
        r = max(r, a[j])
    return r


@_jit
def _min1(a):
    """``a.min()`` of a 1-D array (exact in any order)."""
    r = np.inf
    for j in range(a.size):
        r = min(r, a[j])
    return r

@_jit
def _neg_sum2(a):
    """``np.minimum(a, 0).sum()`` of a 2-D array: column sums (row after row, an elementwise
    loop that vectorizes), then their sum in the fixed order of :func:`_row_sum`."""
    n0, n1 = a.shape
    acc = np.zeros((1, n1))
    for i in range(n0):
        for j in range(n1):
            acc[0, j] += min(a[i, j], 0.0)
    return _row_sum(acc, 0, False)
