"""The estimator bank's per-step scan of its estimates: the common case of
:meth:`uwcosim.run.divergence.DivergenceCheck.assess` in scalar code.

For each of ``k`` estimates ``(x, P)`` with error ``e`` (truth minus estimate), :func:`scan`
checks what a healthy estimate satisfies (finite, ``max |P - P'| <= SYM_RTOL max |P|``,
``P != 0``, NIS not negative, position inside the bound, and a Cholesky factorization of
``S = (P + P')/2`` in which no pivot loses more than twelve digits: ``d_j > PIVOT_RTOL S_jj``)
and writes its NEES ``|L^-1 e|^2`` (``L L' = S``) to ``out``; an estimate that fails a check
gets NaN there and goes through the bank's per-estimate path, which words the reason with the
numpy checks of :mod:`uwcosim.run.divergence`.

The arrays are flat (``X`` ``k n``, ``Ps`` ``k n n``, ``E`` ``k n``, row-major). When the grid
filters have loaded Numba anyway, :func:`scan` runs compiled (through
:mod:`uwcosim.core.jit`, IEEE arithmetic); otherwise the checks run batched in numpy
(exact: extremes and comparisons) and :func:`_chol_nees`, the same function on Python lists,
gives the NEES with the same operations in the same order: both paths give the same bits
(``tests/test_estimate_scan.py``), so a log does not depend on whether Numba was loaded.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from uwcosim.core.jit import ENABLED as JIT_ENABLED
from uwcosim.core.jit import jit

SYM_RTOL = 1e-6  # relative asymmetry a covariance may have (uwcosim.run.divergence)
PIVOT_RTOL = 1e-12


def _scan(X, Ps, E, nis, k, n, ix, iy, bound, has_bound, L, Y, out):
    """``out[i]`` = NEES of estimate ``i``, or NaN where a check fails (module docstring);
    ``L`` (``n n``) and ``Y`` (``n``) are scratch; ``bound`` = ``[xmin, xmax, ymin, ymax]``."""
    for i in range(k):
        out[i] = math.nan
        xo = i * n
        po = i * n * n
        ok = True
        for a in range(n):
            if not math.isfinite(X[xo + a]):
                ok = False
        scale = 0.0
        asym = 0.0
        for a in range(n):
            for b in range(n):
                v = Ps[po + a * n + b]
                if not math.isfinite(v):
                    ok = False
                scale = max(scale, abs(v))
                asym = max(asym, abs(v - Ps[po + b * n + a]))
        if not ok or scale == 0.0 or asym > SYM_RTOL * scale or nis[i] < 0.0:
            continue
        if has_bound:
            px = X[xo + ix]
            py = X[xo + iy]
            if not (bound[0] <= px <= bound[1] and bound[2] <= py <= bound[3]):
                continue
        out[i] = _chol_nees(Ps, E, po, xo, n, L, Y)


def _chol_nees(Ps, E, po, xo, n, L, Y):
    """``|L^-1 e|^2`` with ``L L' = S = (P + P')/2`` (the estimate at offsets ``po``, ``xo``),
    Cholesky row by row with the forward solve ``L y = e`` alongside; NaN when a pivot
    ``d_j`` is not above ``PIVOT_RTOL S_jj``."""
    nees = 0.0
    for r in range(n):
        for c in range(r + 1):
            s = 0.5 * (Ps[po + r * n + c] + Ps[po + c * n + r])
            for m in range(c):
                s -= L[r * n + m] * L[c * n + m]
            if c < r:
                L[r * n + c] = s / L[c * n + c]
            elif s > PIVOT_RTOL * Ps[po + r * n + r]:
                L[r * n + r] = math.sqrt(s)
            else:
                return math.nan
        t = E[xo + r]
        for m in range(r):
            t -= L[r * n + m] * Y[m]
        Y[r] = t / L[r * n + r]
        nees += Y[r] * Y[r]
    return nees


chol_nees_py = _chol_nees
scan = jit(_scan)
_chol_nees = jit(_chol_nees)


def scan_estimates(X: np.ndarray, Ps: np.ndarray, E: np.ndarray, nis: np.ndarray,
                   pos: tuple[int, ...], bound) -> np.ndarray:
    """NEES of each estimate that passes the checks, NaN for the others (module docstring).

    Compiled when Numba is already imported (and enabled), plain Python otherwise."""
    k, n = X.shape
    has_bound = bound is not None and len(pos) >= 2
    ix, iy = (pos[0], pos[1]) if has_bound else (0, 0)
    b = (tuple(bound) if has_bound else (0.0, 0.0, 0.0, 0.0))
    if "numba" in sys.modules and _jit_enabled():
        out = np.empty(k)
        scan(np.ascontiguousarray(X, dtype=float).ravel(),
             np.ascontiguousarray(Ps, dtype=float).ravel(),
             np.ascontiguousarray(E, dtype=float).ravel(), np.asarray(nis, dtype=float), k, n,
             ix, iy, np.asarray(b, dtype=float), has_bound, np.zeros(n * n), np.zeros(n), out)
        return out
    # plain Python: the same checks batched in numpy (exact: extremes and comparisons), the
    # same scalar Cholesky and NEES for the estimates that pass them
    out = np.full(k, np.nan)
    fin = np.isfinite(X).all(axis=1) & np.isfinite(Ps).all(axis=(1, 2))
    with np.errstate(invalid="ignore"):
        scale = np.abs(Ps).max(axis=(1, 2))
        asym = np.abs(Ps - Ps.transpose(0, 2, 1)).max(axis=(1, 2))
        ok = fin & (scale != 0.0) & ~(asym > SYM_RTOL * scale) & ~(np.asarray(nis) < 0.0)
        if has_bound:
            px, py = X[:, ix], X[:, iy]
            ok &= (b[0] <= px) & (px <= b[1]) & (b[2] <= py) & (py <= b[3])
    idx = np.flatnonzero(ok).tolist()
    if idx:
        P_l, E_l = Ps.ravel().tolist(), E.ravel().tolist()
        L, Y = [0.0] * (n * n), [0.0] * n
        for i in idx:
            out[i] = chol_nees_py(P_l, E_l, i * n * n, i * n, n, L, Y)
    return out


def _jit_enabled() -> bool:
    return JIT_ENABLED
