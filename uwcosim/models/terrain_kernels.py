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

from uwcosim.core import bicubic
from uwcosim.core.jit import jit


@jit
def depth_rows(table, X, x0, y0, idx, idy, nx, ny, out):
    """``out[n] = h_d(X[n, 0], X[n, 1])`` from the per-cell polynomial table ``table[4 i + j,
    cell]`` of ``u^i v^j`` (``tan._poly_table``), clamped to the grid as ``depth_xy``; a point
    with a NaN coordinate gives NaN (:func:`uwcosim.core.bicubic.value`)."""
    for n in range(X.shape[0]):
        out[n] = bicubic.value(table, x0, y0, idx, idy, nx, ny, X[n, 0], X[n, 1])


@jit
def point(table, x, y, x0, y0, idx, idy, nx, ny):
    """``(h_d, dh_d/dx, dh_d/dy)`` at one point: :meth:`FastTerrain._point` compiled (the same
    operations in the same order, :func:`uwcosim.core.bicubic.value_gradient`; the derivative
    across a clamped edge is zero)."""
    return bicubic.value_gradient(table, x0, y0, idx, idy, nx, ny, x, y)
