"""The terrain spline is defined once (:mod:`uwcosim.core.bspline`); its other Python/Numba forms
(polynomial table, tensor-grid evaluation, compiled weights) agree with it to round-off.
The C kernel of the DepthSounder FMU is checked in ``tests/test_bathymetry_kernel.py``."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core import bspline
from uwcosim.filters.grid.likelihood import TerrainGrid, terrain_depth
from uwcosim.models import tan as tan_module
from uwcosim.models.tan import FastTerrain
from uwcosim.models.terrain import Bathymetry, synthetic_bathymetry


def _powers(f):
    return np.stack([np.ones_like(f), f, f * f, f**3])


def test_monomial_form_equals_the_definition():
    f = np.random.default_rng(0).uniform(0.0, 1.0, 500)
    w, dw = bspline.basis(f)
    np.testing.assert_allclose(bspline.MONOMIAL.T @ _powers(f), w, rtol=0, atol=1e-15)
    dpow = np.stack([np.zeros_like(f), np.ones_like(f), 2 * f, 3 * f * f])
    np.testing.assert_allclose(bspline.MONOMIAL.T @ dpow, dw, rtol=0, atol=1e-15)
    # a partition of unity whose derivative sums to zero; continuous joins between cells:
    # node i + a - 1 has weight w_a(1) in cell i and w_{a-1}(0) in cell i + 1
    np.testing.assert_allclose(w.sum(axis=0), 1.0, atol=1e-15)
    np.testing.assert_allclose(dw.sum(axis=0), 0.0, atol=1e-15)
    w0, dw0 = bspline.basis(np.array(0.0))
    w1, dw1 = bspline.basis(np.array(1.0))
    np.testing.assert_allclose(w1[1:], w0[:3], atol=1e-15)
    np.testing.assert_allclose(dw1[1:], dw0[:3], atol=1e-15)
    assert w1[0] == 0.0 and w0[3] == 0.0


def test_cell_clamps_to_the_grid():
    i, f = bspline.cell(np.array([-3.0, 0.0, 2.5, 9.0, 12.0]), 10)
    np.testing.assert_array_equal(i, [0, 0, 2, 8, 8])
    np.testing.assert_array_equal(f, [0.0, 0.0, 0.5, 1.0, 1.0])


def test_compiled_weights_equal_the_definition():
    s = np.random.default_rng(1).uniform(-2.0, 12.0, 400)
    idx, w = bspline.cell_weights(s, 11)
    i, f = bspline.cell(s, 11)
    np.testing.assert_array_equal(idx, i)
    np.testing.assert_allclose(w, bspline.basis(f)[0].T, rtol=0, atol=1e-12)


@pytest.fixture(scope="module")
def terrain() -> Bathymetry:
    return synthetic_bathymetry(5, extent=(0.0, 3000.0, -500.0, 2500.0), resolution=60.0)


def test_table_and_tensor_forms_equal_the_definition(terrain):
    rng = np.random.default_rng(2)
    xmin, xmax, ymin, ymax = terrain.extent
    x = rng.uniform(xmin - 200.0, xmax + 200.0, 300)  # some outside: clamped alike
    y = rng.uniform(ymin - 200.0, ymax + 200.0, 300)
    ref = terrain.depth(x, y)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(FastTerrain(terrain).depth(x, y), ref, rtol=0, atol=1e-12 * scale)
    xs, ys = np.sort(x[:40]), np.sort(y[:30])
    grid = TerrainGrid(terrain).depth(xs, ys)
    np.testing.assert_allclose(grid, terrain.depth(*np.meshgrid(xs, ys, indexing="ij")),
                               rtol=0, atol=1e-12 * scale)
    out = terrain_depth(xs, ys, TerrainGrid(terrain).map)
    np.testing.assert_allclose(out, grid, rtol=0, atol=1e-12 * scale)


def test_polynomial_table_has_the_bits_of_the_plain_stencil_sums():
    """The table is built in place (start-up: no temporary per term); its bits are those of
    the plain formula ``sum(M[a, i] * c[..., a:]) ...``, -0.0 turned into 0.0 by the sum's
    ``0 +`` included (a map with zero and negative coefficients)."""
    rng = np.random.default_rng(3)
    depth = np.round(rng.standard_normal((23, 31)), 1) * 10.0
    depth[rng.random(depth.shape) < 0.2] = 0.0
    bathy = Bathymetry(0.0, 0.0, 10.0, 10.0, depth)
    m, pad = bspline.MONOMIAL.T, tan_module.PAD
    ny, nx = bathy.shape
    c = bathy.coefficients[pad - 1 : pad + ny + 1, pad - 1 : pad + nx + 1]
    ci = [sum(m[a, i] * c[:, a : a + nx - 1] for a in range(4)) for i in range(4)]
    ref = np.stack([sum(m[b, j] * ci[i][b : b + ny - 1, :] for b in range(4))
                    for i in range(4) for j in range(4)]).reshape(16, -1)
    table = FastTerrain(bathy)._table
    np.testing.assert_array_equal(table.view(np.int64), ref.view(np.int64))
