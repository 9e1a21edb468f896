"""Compiled terrain lookups of :class:`uwcosim.models.tan.FastTerrain` (Numba, optional).

:func:`depth_rows` is :meth:`FastTerrain.depth_xy` point by point: the same clamping, cell
and fraction, and the same two Horner schemes in the same order, in IEEE arithmetic (no
fast-math, no contraction), so it gives the same bits as the numpy code
(``tests/test_terrain_kernels.py``). It saves numpy's per-call overhead (about 20 operations
per lookup): for the 9 sigma points of a UKF the lookup is most of the cost, for 1000 particles
the gather and the temporaries.

:class:`FastTerrain` calls it only when Numba is already imported (by the grid filters'
kernels, :mod:`uwcosim.filters.grid.jit`): importing Numba costs about 0.5 s, more than the
kernel saves over a few thousand steps of a UKF or a PF alone.
"""

from __future__ import annotations

import math

from uwcosim.filters.grid.jit import _jit


@_jit
def depth_rows(table, X, x0, y0, idx, idy, nx, ny, out):
    """``out[n] = h_d(X[n, 0], X[n, 1])`` from the per-cell polynomial table ``table[4 i + j,
    cell]`` of ``u^i v^j`` (``tan._poly_table``), clamped to the grid as ``depth_xy``; a point
    with a NaN coordinate gives NaN."""
    umax = nx - 1.0
    vmax = ny - 1.0
    for n in range(X.shape[0]):
        u = (X[n, 0] - x0) * idx
        v = (X[n, 1] - y0) * idy
        if math.isnan(u) or math.isnan(v):
            out[n] = math.nan
            continue
        u = min(max(u, 0.0), umax)
        v = min(max(v, 0.0), vmax)
        iu = min(int(u), nx - 2)
        iv = min(int(v), ny - 2)
        u -= iu
        v -= iv
        cell = iv * (nx - 1) + iu
        q0 = ((table[12, cell] * u + table[8, cell]) * u + table[4, cell]) * u + table[0, cell]
        q1 = ((table[13, cell] * u + table[9, cell]) * u + table[5, cell]) * u + table[1, cell]
        q2 = ((table[14, cell] * u + table[10, cell]) * u + table[6, cell]) * u + table[2, cell]
        q3 = ((table[15, cell] * u + table[11, cell]) * u + table[7, cell]) * u + table[3, cell]
        out[n] = ((q3 * v + q2) * v + q1) * v + q0
