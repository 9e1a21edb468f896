"""Compiled evaluation of a surface stored as per-cell bicubic polynomials (Numba, optional).

A surface ``s(x, y)`` on a regular grid of ``nx`` by ``ny`` nodes (first node ``(x0, y0)``,
inverse spacings ``idx``, ``idy``) is stored as a table ``table[4 i + j, cell]`` of the
coefficients of ``u^i v^j`` in each cell (``cell = iv (nx - 1) + iu``, ``u``, ``v`` the
fractions within the cell); outside the grid the value is the one at the nearest edge and the
derivative across that edge is zero. This is how the TAN model stores its bathymetry spline
(``uwcosim.models.tan``); the compiled Kalman steps (:mod:`uwcosim.filters.kalman_kernels`)
evaluate the model's terrain row with :func:`value_gradient` and :func:`value`, which repeat
the operations of the model's own compiled lookup (``uwcosim.models.terrain_kernels.point``) in
the same order (IEEE arithmetic, :mod:`uwcosim.core.jit`): the same bits.

:func:`locate` (the cell and fractions of a point) and :func:`cubics_in_u` (the cell's four
cubics in ``u``) are what both lookups share. :class:`Surface` is the grid's geometry as the
kernels take it (the table travels apart: it is the one large array).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from uwcosim.core.jit import jit


class Surface(NamedTuple):
    """The geometry of a table surface: first node, inverse spacings, numbers of nodes."""

    x0: float
    y0: float
    idx: float  #: 1 / dx
    idy: float  #: 1 / dy
    nx: int
    ny: int


@jit
def locate(x0, y0, idx, idy, nx, ny, x, y):
    """The cell of ``(x, y)`` and its fractions in it, clamped to the grid: ``(cell, u, v,
    flat_u, flat_v)``, ``flat_*`` True where the point lies outside the grid along that axis
    (the value is the edge's, the derivative across it zero); ``cell`` -1 when a coordinate is
    NaN."""
    u = (x - x0) * idx
    v = (y - y0) * idy
    if math.isnan(u) or math.isnan(v):
        return -1, u, v, True, True
    flat_u = not 0.0 <= u <= nx - 1.0
    flat_v = not 0.0 <= v <= ny - 1.0
    u = min(max(u, 0.0), nx - 1.0)
    v = min(max(v, 0.0), ny - 1.0)
    iu = min(int(u), nx - 2)
    iv = min(int(v), ny - 2)
    return iv * (nx - 1) + iu, u - iu, v - iv, flat_u, flat_v


@jit
def cubics_in_u(t, cell, u):
    """``q_j(u) = sum_i t[4 i + j, cell] u^i`` for ``j = 0..3`` (Horner in ``u``): the cell's
    polynomial is ``sum_j q_j(u) v^j``."""
    q0 = ((t[12, cell] * u + t[8, cell]) * u + t[4, cell]) * u + t[0, cell]
    q1 = ((t[13, cell] * u + t[9, cell]) * u + t[5, cell]) * u + t[1, cell]
    q2 = ((t[14, cell] * u + t[10, cell]) * u + t[6, cell]) * u + t[2, cell]
    q3 = ((t[15, cell] * u + t[11, cell]) * u + t[7, cell]) * u + t[3, cell]
    return q0, q1, q2, q3


@jit
def value_gradient(table, x0, y0, idx, idy, nx, ny, x, y):
    """``(s, ds/dx, ds/dy)`` at ``(x, y)``; NaN in a coordinate gives NaN everywhere."""
    cell, u, v, flat_u, flat_v = locate(x0, y0, idx, idy, nx, ny, x, y)
    if cell < 0:
        return math.nan, math.nan, math.nan
    t = table
    q0, q1, q2, q3 = cubics_in_u(t, cell, u)
    d0 = (3.0 * t[12, cell] * u + 2.0 * t[8, cell]) * u + t[4, cell]  # d q_j / du
    d1 = (3.0 * t[13, cell] * u + 2.0 * t[9, cell]) * u + t[5, cell]
    d2 = (3.0 * t[14, cell] * u + 2.0 * t[10, cell]) * u + t[6, cell]
    d3 = (3.0 * t[15, cell] * u + 2.0 * t[11, cell]) * u + t[7, cell]
    h = ((q3 * v + q2) * v + q1) * v + q0  # Horner in v
    hu = 0.0 if flat_u else (((d3 * v + d2) * v + d1) * v + d0) * idx
    hv = 0.0 if flat_v else ((3.0 * q3 * v + 2.0 * q2) * v + q1) * idy
    return h, hu, hv


@jit
def value(table, x0, y0, idx, idy, nx, ny, x, y):
    """``s(x, y)`` (the value of :func:`value_gradient` without the derivatives: the PF's
    per-particle lookup)."""
    cell, u, v, _, _ = locate(x0, y0, idx, idy, nx, ny, x, y)
    if cell < 0:
        return math.nan
    q0, q1, q2, q3 = cubics_in_u(table, cell, u)
    return ((q3 * v + q2) * v + q1) * v + q0
