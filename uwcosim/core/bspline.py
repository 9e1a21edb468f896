"""The uniform cubic B-spline of the terrain maps, written once.

A map's depth ``h_d`` (seed 000 eq. 55) is ``sum_ab wu[a] wv[b] c[iv + b - 1, iu + a - 1]``
over the 4 x 4 coefficients around the cell ``(iu, iv)`` that holds the point, with the cubic
B-spline weights :func:`basis` of the fractions ``(fu, fv)`` within the cell and the clamping
of :func:`cell` (a point outside the grid takes the value at the nearest edge).

The weights as polynomials of the fraction are one table, :data:`MONOMIAL`; every other form
of the spline in Python or Numba evaluates that table, and each is checked against
:func:`basis`:

- :func:`weights` / :func:`cell_weights`, the compiled forms (Numba, :mod:`uwcosim.core.jit`):
  the terrain depth on a grid of :mod:`uwcosim.filters.grid.likelihood` (``terrain_depth``)
  and the point mass's spline shift (:mod:`uwcosim.filters.point_mass.prediction_kernels`;
  ``tests/test_bspline.py``, ``tests/test_projection_kernels.py``);
- the tabulated per-cell polynomials of :class:`uwcosim.models.tan.FastTerrain`, the
  tensor-grid evaluation of :class:`uwcosim.filters.grid.likelihood.TerrainGrid` and the point
  mass's sparse spline matrices (:mod:`uwcosim.filters.point_mass.prediction`) multiply by
  :data:`MONOMIAL` (``tests/test_bspline.py``);
- ``basis`` / ``cell`` in ``uwcosim/fmu/templates/uwc_map.c``, the DepthSounder FMU's kernel
  (``tests/test_bathymetry_kernel.py``: the compiled C against
  :meth:`uwcosim.models.terrain.Bathymetry.depth`);
- ``casadi.bspline`` in :meth:`uwcosim.models.terrain.Bathymetry.casadi_function` (the EKF's
  exact Jacobians; ``tests/test_bathymetry.py``).
"""

from __future__ import annotations

import numpy as np

from uwcosim.core.jit import jit

# the weights times 6 as polynomials of the fraction: 6 w_a(f) = sum_i f^i _SIXFOLD[i, a]
_SIXFOLD = np.array([[1, 4, 1, 0], [-3, 0, 3, 0], [3, -6, 3, 0], [-1, 3, -3, 1]], float)
_SIXFOLD.setflags(write=False)

#: the weights as polynomials of the fraction: ``w_a(f) = sum_i f^i MONOMIAL[i, a]``
MONOMIAL = _SIXFOLD / 6.0


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


@jit
def _weight(a, f, f2, f3):
    """``w_a(f)``: column ``a`` of the table, Horner-free in the order ``1, f, f^2, f^3``."""
    C = _SIXFOLD
    return (((C[0, a] + C[1, a] * f) + C[2, a] * f2) + C[3, a] * f3) / 6.0


@jit
def weights(f):
    """The four weights ``(w_0, w_1, w_2, w_3)`` at one fraction ``f`` (compiled)."""
    f2 = f * f
    f3 = f2 * f
    return _weight(0, f, f2, f3), _weight(1, f, f2, f3), _weight(2, f, f2, f3), _weight(
        3, f, f2, f3)


@jit
def cell_weights(s, n):
    """:func:`cell` and the weights of the points ``s`` (compiled): cell indices ``(N,)`` and
    weights ``(N, 4)``, clamped as the map."""
    N = s.size
    idx = np.empty(N, np.int64)
    w = np.empty((N, 4))
    for a in range(N):
        v = min(max(s[a], 0.0), n - 1.0)
        i = min(int(v), n - 2)
        idx[a] = i
        w0, w1, w2, w3 = weights(v - i)
        w[a, 0] = w0
        w[a, 1] = w1
        w[a, 2] = w2
        w[a, 3] = w3
    return idx, w
