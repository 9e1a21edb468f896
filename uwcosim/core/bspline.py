"""The uniform cubic B-spline of the terrain maps, written once.

A map's depth ``h_d`` (seed 000 eq. 55) is ``sum_ab wu[a] wv[b] c[iv + b - 1, iu + a - 1]``
over the 4 x 4 coefficients around the cell ``(iu, iv)`` that holds the point, with the cubic
B-spline weights :func:`basis` of the fractions ``(fu, fv)`` within the cell and the clamping
of :func:`cell` (a point outside the grid takes the value at the nearest edge).

The other forms of the same spline, kept for speed or for C, are checked against these:

- :data:`MONOMIAL` (the weights as polynomials in ``f``): the tabulated per-cell polynomials of
  :class:`uwcosim.models.tan.FastTerrain` and the tensor-grid evaluation of
  :class:`uwcosim.filters.grid.likelihood.TerrainGrid` (``tests/test_bspline.py``);
- ``_spline_weights`` / ``terrain_depth`` of :mod:`uwcosim.filters.grid.projection_kernels`
  (Numba; ``tests/test_bspline.py``, ``tests/test_projection_kernels.py``);
- ``basis`` / ``cell`` in ``uwcosim/fmu/templates/uwc_map.c``, the DepthSounder FMU's kernel
  (``tests/test_bathymetry_kernel.py``: the compiled C against :meth:`Bathymetry.depth`);
- ``casadi.bspline`` in :meth:`uwcosim.models.terrain.Bathymetry.casadi_function` (the EKF's
  exact Jacobians; ``tests/test_bathymetry.py``).
"""

from __future__ import annotations

import numpy as np

#: the weights as polynomials of the fraction: ``w_a(f) = sum_i f^i MONOMIAL[i, a]``
MONOMIAL = np.array([[1, 4, 1, 0], [-3, 0, 3, 0], [3, -6, 3, 0], [-1, 3, -3, 1]], float) / 6.0


def basis(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic B-spline weights and their derivatives at fraction ``f``: shape ``(4, ...)``.

    Weight ``a`` multiplies the coefficient of node ``i + a - 1`` of the cell ``i``.
    """
    g = 1.0 - f
    f2, f3 = f * f, f * f * f
    w = np.stack([g**3, 3 * f3 - 6 * f2 + 4, -3 * f3 + 3 * f2 + 3 * f + 1, f3]) / 6.0
    dw = np.stack([-(g**2), 3 * f2 - 4 * f, -3 * f2 + 2 * f + 1, f2]) / 2.0
    return w, dw


def cell(s: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell index and fraction at grid coordinates ``s`` (``0 .. n-1`` over ``n`` nodes),
    clamped to the grid: outside it the point moves to the nearest edge."""
    s = np.minimum(np.maximum(np.asarray(s, dtype=float), 0.0), n - 1.0)
    i = np.minimum(s.astype(np.intp), n - 2)
    return i, s - i
