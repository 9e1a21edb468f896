"""Compiled terrain lookups of :class:`uwcosim.models.tan.FastTerrain` (Numba, optional).

:func:`depth_rows` is :meth:`FastTerrain.depth_xy` point by point: the same clamping, cell
and fraction, and the same two Horner schemes in the same order, in IEEE arithmetic (no
fast-math, no contraction), so it gives the same bits as the numpy code
(``tests/test_terrain_kernels.py``). It saves numpy's per-call overhead (about 20 operations
per lookup): for the 9 sigma points of a UKF the lookup is most of the cost, for 1000 particles
the gather and the temporaries.

:class:`FastTerrain` calls it only when Numba is already imported (by the grid filters'
kernels, :mod:`uwcosim.core.jit`): importing Numba costs about 0.5 s, more than the
kernel saves over a few thousand steps of a UKF or a PF alone. :func:`point` is
:meth:`FastTerrain._point` (depth and gradient at one point, the EKF's ``h`` and ``H``).
"""

from __future__ import annotations

import math

from uwcosim.core.jit import jit


@jit
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


@jit
def point(table, x, y, x0, y0, idx, idy, nx, ny):
    """``(h_d, dh_d/dx, dh_d/dy)`` at one point: :meth:`FastTerrain._point` compiled (the same
    operations in the same order; the derivative across a clamped edge is zero)."""
    u = (x - x0) * idx
    v = (y - y0) * idy
    flat_u = not 0.0 <= u <= nx - 1.0
    flat_v = not 0.0 <= v <= ny - 1.0
    u = min(max(u, 0.0), nx - 1.0)
    v = min(max(v, 0.0), ny - 1.0)
    iu = min(int(u), nx - 2)
    iv = min(int(v), ny - 2)
    u -= iu
    v -= iv
    cell = iv * (nx - 1) + iu
    t = table
    q0 = ((t[12, cell] * u + t[8, cell]) * u + t[4, cell]) * u + t[0, cell]
    q1 = ((t[13, cell] * u + t[9, cell]) * u + t[5, cell]) * u + t[1, cell]
    q2 = ((t[14, cell] * u + t[10, cell]) * u + t[6, cell]) * u + t[2, cell]
    q3 = ((t[15, cell] * u + t[11, cell]) * u + t[7, cell]) * u + t[3, cell]
    d0 = (3.0 * t[12, cell] * u + 2.0 * t[8, cell]) * u + t[4, cell]
    d1 = (3.0 * t[13, cell] * u + 2.0 * t[9, cell]) * u + t[5, cell]
    d2 = (3.0 * t[14, cell] * u + 2.0 * t[10, cell]) * u + t[6, cell]
    d3 = (3.0 * t[15, cell] * u + 2.0 * t[11, cell]) * u + t[7, cell]
    h = ((q3 * v + q2) * v + q1) * v + q0
    hu = 0.0 if flat_u else (((d3 * v + d2) * v + d1) * v + d0) * idx
    hv = 0.0 if flat_v else ((3.0 * q3 * v + 2.0 * q2) * v + q1) * idy
    return h, hu, hv
