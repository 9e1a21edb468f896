"""The compiled terrain lookup gives the numpy lookup's bits, and is never the reason Numba
is imported.

:func:`uwcosim.models.terrain_kernels.depth_rows` replays :meth:`FastTerrain.depth_xy` point
by point (same clamping, cell, fraction and Horner order, IEEE arithmetic): the particle filter's
results must not change by a bit whether the grid filters loaded Numba or not.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from uwcosim.core import jit
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry

needs_numba = pytest.mark.skipif(not jit.ENABLED, reason="Numba not installed or disabled")


@pytest.fixture(scope="module")
def model():
    return tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7))


def _points(n, seed, spread):
    rng = np.random.default_rng(seed)
    X = np.zeros((n, 4))
    if spread is None:  # the whole map and beyond it (clamped to the edge)
        X[:, 0] = rng.uniform(-2000.0, 27000.0, n)
        X[:, 1] = rng.uniform(-2000.0, 27000.0, n)
    else:  # a particle cloud
        X[:, 0] = 2000.0 + spread * rng.standard_normal(n)
        X[:, 1] = 18000.0 + spread * rng.standard_normal(n)
    return X


@needs_numba
@pytest.mark.parametrize("n, spread", [(9, 30.0), (1000, 30.0), (2000, None), (1, None)])
@pytest.mark.parametrize("order", ["C", "F"])
def test_compiled_lookup_gives_the_numpy_bits(model, n, spread, order):
    from uwcosim.models import terrain_kernels as tk

    ft = model._fast_terrain
    X = np.asarray(_points(n, n, spread), order=order)
    # grid nodes, edges and corners exactly (fractions 0, clamping at both ends)
    nx, ny = ft._nx, ft._ny
    b = ft.bathy
    X[:4, 0] = b.x0 + b.dx * np.array([0, nx - 1, nx - 2, 17])[: min(n, 4)]
    X[:4, 1] = b.y0 + b.dy * np.array([ny - 1, 0, ny - 2, 5])[: min(n, 4)]
    ref = ft.depth_xy(X.T[:2])
    out = np.full(n, np.nan)
    tk.depth_rows(ft._table, X, ft._x0, ft._y0, ft._idx, ft._idy, nx, ny, out)
    assert np.array_equal(out, ref)
    # the model's h_batch takes this path once Numba is loaded (it is, in this process)
    assert np.array_equal(model.h_batch(X)[:, 2], ref)
    assert np.array_equal(model.h_batch(X)[:, :2], X[:, 2:4])


@needs_numba
def test_compiled_lookup_nan_point_gives_nan(model):
    from uwcosim.models import terrain_kernels as tk

    ft = model._fast_terrain
    X = _points(3, 0, 30.0)
    X[1, 0] = np.nan
    out = np.zeros(3)
    tk.depth_rows(ft._table, X, ft._x0, ft._y0, ft._idx, ft._idy, ft._nx, ft._ny, out)
    assert np.isnan(out[1]) and np.isfinite(out[[0, 2]]).all()


_NO_NUMBA = r"""
import sys
import numpy as np
import uwcosim.filters  # noqa: F401
from uwcosim.filters.base import ESTIMATORS
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry

model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(3))
x0 = np.array([2000.0, 18000.0, 0.5, 0.0])
out = []
for name, kw in (("ukf", {}), ("ekf", {}), ("pf", {"n_particles": 200})):
    est = ESTIMATORS.get(name).from_settings(model, x0, np.diag([900.0, 900.0, 0.01, 0.01]), kw,
                                             rng=np.random.default_rng(0))
    for k in range(5):
        est.predict(np.array([0.1 * k, 0.0]), 1.0)
        est.update(model.h(x0) + 0.5)
    out.append(est.x)
if len(sys.argv) > 2:
    import numba  # noqa: F401  (as the grid filters do): the compiled lookup from now on
    assert sys.argv[2] == "numba"
    for name, kw in (("ukf", {}), ("ekf", {}), ("pf", {"n_particles": 200})):
        est = ESTIMATORS.get(name).from_settings(model, x0, np.diag([900.0, 900.0, 0.01, 0.01]),
                                                 kw, rng=np.random.default_rng(0))
        for k in range(5):
            est.predict(np.array([0.1 * k, 0.0]), 1.0)
            est.update(model.h(x0) + 0.5)
        assert np.array_equal(est.x, out.pop(0)), name
np.save(sys.argv[1], np.array(out))
print("numba" in sys.modules)
"""


def test_terrain_filters_do_not_import_numba(tmp_path):
    """A UKF, EKF and PF on the terrain model leave Numba unimported (0.5 s saved)."""
    done = subprocess.run([sys.executable, "-c", _NO_NUMBA, str(tmp_path / "x.npy")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-1] == "False"


@needs_numba
def test_filters_give_the_same_bits_with_the_compiled_lookup(tmp_path):
    """The same UKF, EKF and PF steps after Numba is imported (compiled lookup): same bits."""
    done = subprocess.run([sys.executable, "-c", _NO_NUMBA, str(tmp_path / "x.npy"), "numba"],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-1] == "True"


@needs_numba
def test_compiled_point_gives_the_python_bits(model):
    from uwcosim.models import terrain_kernels as tk

    ft = model._fast_terrain
    X = _points(500, 5, None)
    b = ft.bathy
    X[:3, 0] = b.x0 + b.dx * np.array([0, ft._nx - 1, 3])  # on the edges: one-sided, flat
    X[:3, 1] = b.y0 + b.dy * np.array([ft._ny - 1, 0, -2])
    for x, y in X[:, :2].tolist():
        got = tk.point(ft._table, x, y, ft._x0, ft._y0, ft._idx, ft._idy, ft._nx, ft._ny)
        assert got == ft._point(x, y)
        assert ft.point(x, y) == got  # the model's path (Numba is loaded here)
