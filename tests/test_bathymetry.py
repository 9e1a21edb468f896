"""The terrain spline: numpy, CasADi and scipy.ndimage agree; map files load."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy import ndimage

from uwcosim.core.errors import MapError
from uwcosim.models.terrain import Bathymetry, load_map, synthetic_bathymetry


@pytest.fixture(scope="module")
def bathy():
    return synthetic_bathymetry(3, extent=(0.0, 5000.0, 0.0, 4000.0), resolution=50.0)


def test_spline_interpolates_grid_nodes(bathy):
    ny, nx = bathy.shape
    j, i = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    h = bathy.depth(bathy.x0 + i * bathy.dx, bathy.y0 + j * bathy.dy)
    np.testing.assert_allclose(h, bathy.depth_grid, rtol=0, atol=1e-9)


def test_numpy_matches_ndimage_and_casadi(bathy):
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 5000, 300)
    y = rng.uniform(0, 4000, 300)
    coef = ndimage.spline_filter(bathy.depth_grid, order=3, mode="mirror")
    ref = ndimage.map_coordinates(coef, [(y - bathy.y0) / bathy.dy, (x - bathy.x0) / bathy.dx],
                                  order=3, prefilter=False, mode="mirror")
    h, gx, gy = bathy.gradient(x, y)
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-9)
    f = bathy.casadi_function()
    xy = ca.MX.sym("xy", 2)
    jac = ca.Function("j", [xy], [f(xy), ca.jacobian(f(xy), xy)])
    for k in range(0, 300, 15):
        v, J = jac([x[k], y[k]])
        assert float(v) == pytest.approx(h[k], abs=1e-9)
        np.testing.assert_allclose(np.asarray(J).ravel(), [gx[k], gy[k]], rtol=0, atol=1e-9)


def test_gradient_matches_finite_differences(bathy):
    x, y, d = np.array([1234.5]), np.array([2345.6]), 1e-4
    _, gx, gy = bathy.gradient(x, y)
    fdx = (bathy.depth(x + d, y) - bathy.depth(x - d, y)) / (2 * d)
    fdy = (bathy.depth(x, y + d) - bathy.depth(x, y - d)) / (2 * d)
    np.testing.assert_allclose([gx[0], gy[0]], [fdx[0], fdy[0]], rtol=1e-6, atol=1e-8)


def test_synthetic_map_is_seeded_and_realistic():
    a = synthetic_bathymetry(7)
    b = synthetic_bathymetry(7)
    c = synthetic_bathymetry(8)
    np.testing.assert_array_equal(a.depth_grid, b.depth_grid)
    assert not np.allclose(a.depth_grid, c.depth_grid)
    assert np.all(a.depth_grid > 0)
    assert 20 < a.depth_grid.std() < 300


def test_npz_and_netcdf_round_trip(tmp_path, bathy):
    p = bathy.save_npz(tmp_path / "m.npz")
    back = load_map(p)
    np.testing.assert_allclose(back.depth_grid, bathy.depth_grid)
    assert (back.x0, back.dx) == (bathy.x0, bathy.dx)
    # a GEBCO-like NetCDF-4 file: lon/lat in degrees, elevation negative below sea level
    h5netcdf = pytest.importorskip("h5netcdf")
    nc = tmp_path / "gebco.nc"
    lon = np.linspace(10.0, 10.1, 25)
    lat = np.linspace(60.0, 60.05, 13)
    elev = -1000.0 - 10 * np.add.outer(np.arange(13), np.arange(25)).astype(float)
    with h5netcdf.File(nc, "w") as f:
        f.dimensions = {"lat": lat.size, "lon": lon.size}
        f.create_variable("lat", ("lat",), data=lat)
        f.create_variable("lon", ("lon",), data=lon)
        f.create_variable("elevation", ("lat", "lon"), data=elev)
    m = load_map(nc, projection="equirectangular")  # the nodes kept (tmerc: tests/test_geo.py)
    assert m.shape == (13, 25)
    np.testing.assert_allclose(m.depth_grid, -elev)
    # 0.1 degree of longitude at 60.025 N is about 5.55 km
    assert m.extent[1] == pytest.approx(5550, rel=0.01)


def test_bad_maps_are_refused(tmp_path):
    with pytest.raises(MapError, match="map file not found"):
        load_map(tmp_path / "none.npz")
    np.savez(tmp_path / "bad.npz", x=np.arange(5.0), y=np.arange(4.0), depth=np.zeros((3, 3)))
    with pytest.raises(MapError, match="does not match"):
        load_map(tmp_path / "bad.npz")
    with pytest.raises(MapError, match="NaN"):
        Bathymetry(0, 0, 1, 1, np.full((5, 5), np.nan))
    (tmp_path / "m.txt").write_text("x")
    with pytest.raises(MapError, match="unknown map format"):
        load_map(tmp_path / "m.txt")


def test_large_grid_2000_squared():
    rng = np.random.default_rng(1)
    b = Bathymetry(0.0, 0.0, 10.0, 10.0, 1000 + rng.standard_normal((2000, 2000)))
    h = b.depth(np.array([5000.0, 12345.0]), np.array([100.0, 19990.0]))
    assert np.all(np.isfinite(h))
