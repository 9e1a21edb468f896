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


def _gebco(path, elev_raw, attrs=None, axes_attrs=None, classic=False, dtype="i2"):
    """A NetCDF map in metres: ``x``/``y`` (50 m apart) and a packed ``elevation``."""
    ny, nx = elev_raw.shape
    x, y = np.arange(nx) * 50.0, np.arange(ny) * 50.0
    if classic:
        from scipy.io import netcdf_file

        with netcdf_file(path, "w") as f:
            f.createDimension("y", ny)
            f.createDimension("x", nx)
            for name, data in (("x", x), ("y", y)):
                v = f.createVariable(name, "f8", (name,))
                v[:] = data
                for k, a in (axes_attrs or {}).items():
                    setattr(v, k, a)
            v = f.createVariable("elevation", dtype, ("y", "x"))
            v[:] = elev_raw
            for k, a in (attrs or {}).items():
                setattr(v, k, a)
        return path
    import h5netcdf

    with h5netcdf.File(path, "w") as f:
        f.dimensions = {"y": ny, "x": nx}
        for name, data in (("x", x), ("y", y)):
            v = f.create_variable(name, (name,), data=data)
            v.attrs.update(axes_attrs or {})
        attrs = dict(attrs or {})
        fill = attrs.pop("_FillValue", None)
        v = f.create_variable("elevation", ("y", "x"), dtype, fillvalue=fill)
        v[...] = elev_raw
        v.attrs.update(attrs)
    return path


@pytest.mark.parametrize("classic", [False, True], ids=["netcdf4", "netcdf3"])
def test_netcdf_packing_fill_values_and_units(tmp_path, classic):
    """Issue 24, item 5: GEBCO's ``_FillValue`` -32767 was read as an elevation (32767 m
    depths, run ok), ``units = "km"`` as metres, and scale_factor/add_offset ignored."""
    raw = np.full((6, 8), -1000, np.int16)
    raw[2, 3] = -1200
    m = load_map(_gebco(tmp_path / "p.nc", raw, {"scale_factor": 0.5, "add_offset": -10.0,
                                                   "units": "m"}, classic=classic))
    assert m.depth_grid[0, 0] == 510.0 and m.depth_grid[2, 3] == 610.0  # -(raw/2 - 10)
    m = load_map(_gebco(tmp_path / "k.nc", raw, {"units": "km"},
                        {"units": "km"}, classic=classic))
    assert m.depth_grid[0, 0] == 1_000_000.0 and m.dx == 50_000.0
    holes = raw.copy()
    holes[4, 5] = holes[5, 7] = -32767
    with pytest.raises(MapError, match=r"h\.nc: 2 of the 48 cells of 'elevation' hold its fill "
                       r"value -32767 \(no data\), the first at row 4, column 5"):
        load_map(_gebco(tmp_path / "h.nc", holes, {"_FillValue": np.int16(-32767)},
                        classic=classic))
    with pytest.raises(MapError, match=r"f\.nc: variable 'elevation' has units 'fathoms'; "
                       r"expected a length in m, km or ft"):
        load_map(_gebco(tmp_path / "f.nc", raw, {"units": "fathoms"}, classic=classic))


def test_a_map_above_the_memory_limit_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """Issue 24, item 8: a 6 MB NetCDF map of 12000 x 12000 cells took 23 GB and 4 minutes.
    Its size is known from the file's header: refused at once; the limit can be raised."""
    import time

    h5netcdf = pytest.importorskip("h5netcdf")
    path = tmp_path / "big.nc"
    n = 12000
    with h5netcdf.File(path, "w") as f:  # chunked and compressed: a few MB on disk
        f.dimensions = {"y": n, "x": n}
        f.create_variable("x", ("x",), data=np.arange(n) * 10.0)
        f.create_variable("y", ("y",), data=np.arange(n) * 10.0)
        f.create_variable("elevation", ("y", "x"), "i2", chunks=(1000, 1000),
                          compression="gzip", fillvalue=-1000)
    assert path.stat().st_size < 10e6
    start = time.perf_counter()
    with pytest.raises(MapError, match=r"big\.nc: a map of 12000 x 12000 cells needs about "
                       r"21\.5 GiB \(limit 4 GiB; raise it with UWCOSIM_MEMORY_LIMIT_GIB=N\)"):
        load_map(path)
    assert time.perf_counter() - start < 5.0  # nothing of the grid was read
    np.savez(tmp_path / "m.npz", x=np.arange(100.0), y=np.arange(100.0),
             depth=np.full((100, 100), 50.0))
    monkeypatch.setenv("UWCOSIM_MEMORY_LIMIT_GIB", "0.001")
    with pytest.raises(MapError, match=r"m\.npz: a map of 100 x 100 cells needs about 0\.00149 "
                       r"GiB \(limit 0\.001 GiB"):
        load_map(tmp_path / "m.npz")
    monkeypatch.setenv("UWCOSIM_MEMORY_LIMIT_GIB", "0.01")
    assert load_map(tmp_path / "m.npz").shape == (100, 100)
