"""Georeferenced maps and runs: the local transverse Mercator frame (pyproj), a GEBCO-style
NetCDF projected and resampled, ``[geo] start``, latitude/longitude log columns and
``[[replay.geographic]]`` columns."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.csv as pcsv
import pytest

from uwcosim.api import run_scenario
from uwcosim.models.geo import LocalFrame
from uwcosim.models.terrain import load_map, map_frame
from uwcosim.runlog import columns, read_log

h5netcdf = pytest.importorskip("h5netcdf")


def test_round_trip_of_the_local_frame_within_a_millimetre():
    frame = LocalFrame(43.05, 5.1)
    assert "+proj=tmerc" in frame.proj and "+lat_0=43.05" in frame.proj
    g = np.linspace(-60_000.0, 60_000.0, 41)
    X, Y = np.meshgrid(g, g)
    lat, lon = frame.to_latlon(X, Y)
    x, y = frame.to_xy(lat, lon)
    assert np.max(np.hypot(x - X, y - Y)) < 1e-3
    # and from degrees: the origin is (0, 0), a point 0.1 deg north about 11.1 km north
    x0, y0 = frame.to_xy(43.05, 5.1)
    assert abs(x0) < 1e-9 and abs(y0) < 1e-9
    _, yn = frame.to_xy(43.15, 5.1)
    assert yn == pytest.approx(11_113, rel=1e-3)
    la, lo = frame.to_latlon(*frame.to_xy(np.array([43.2, 42.9]), np.array([5.3, 4.8])))
    np.testing.assert_allclose(la, [43.2, 42.9], atol=1e-11)  # 1e-11 deg is about 1 um
    np.testing.assert_allclose(lo, [5.3, 4.8], atol=1e-11)
    assert LocalFrame.from_metadata(frame.metadata()) == frame


def _gebco(path, lat, lon, elevation):
    with h5netcdf.File(path, "w") as f:
        f.dimensions = {"lat": lat.size, "lon": lon.size}
        f.create_variable("lat", ("lat",), data=lat)
        f.create_variable("lon", ("lon",), data=lon)
        f.create_variable("elevation", ("lat", "lon"), data=elevation.astype(np.float32))
    return path


def _field(lat, lon):
    """A smooth seafloor (m of elevation, negative down)."""
    return -1000.0 - 300.0 * np.sin(40.0 * (lon - 5.0)) * np.cos(30.0 * (lat - 43.0))


def test_a_gebco_netcdf_is_projected_and_resampled(tmp_path):
    lat = np.linspace(42.9, 43.2, 121)
    lon = np.linspace(4.95, 5.35, 161)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    nc = _gebco(tmp_path / "gebco.nc", lat, lon, _field(la, lo))
    frame = map_frame(nc)
    assert frame == LocalFrame(43.05, 5.15)
    m = load_map(nc)
    assert m.shape == (121, 161)
    xmin, xmax, ymin, ymax = m.extent
    assert xmin < 0 < xmax and ymin < 0 < ymax  # centred on the map
    assert xmax - xmin == pytest.approx(0.4 * 111_320 * np.cos(np.deg2rad(43.05)), rel=0.01)
    # every node holds the seafloor at its own latitude/longitude (the cubic spline of the
    # float32 grid: to a few centimetres of 300 m of relief inside; at the edges, where the
    # spline's mirror boundary flattens the slope, to a few metres)
    x = xmin + m.dx * np.arange(161)
    y = ymin + m.dy * np.arange(121)
    X, Y = np.meshgrid(x, y)
    nlat, nlon = frame.to_latlon(X, Y)
    exact = -_field(nlat, nlon)
    np.testing.assert_allclose(m.depth_grid[3:-3, 3:-3], exact[3:-3, 3:-3], atol=0.05)
    np.testing.assert_allclose(m.depth_grid, exact, atol=3.0)
    # another origin moves the frame, not the seafloor
    m2 = load_map(nc, origin=(43.0, 5.0))
    f2 = LocalFrame(43.0, 5.0)
    px, py = f2.to_xy(43.1, 5.2)
    assert float(m2.depth(px, py)) == pytest.approx(-_field(43.1, 5.2), abs=0.05)
    # the earlier projection stays available
    old = load_map(nc, projection="equirectangular")
    assert old.x0 == 0.0 and old.y0 == 0.0


SCEN = "scenarios/tan_terrain.toml"


def test_a_simulation_over_a_latlon_map_starts_at_geo_start_and_logs_latlon(tmp_path, tan):
    lat = np.linspace(42.95, 43.15, 81)
    lon = np.linspace(4.9, 5.2, 101)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    nc = _gebco(tmp_path / "gebco.nc", lat, lon, _field(la, lo))
    loaded = tan(["run.duration=20", f'map={{kind = "file", file = "{nc}"}}',
                  "fmus.vehicle.start={vx = 0.5, vy = 0.0}",
                  "geo={start = {lat = 43.04, lon = 5.03}}",
                  "output.trajectory_axes='latlon'",
                  'estimators={ekf={type="ekf"}, pf={type="pf", n_particles=200}}'])
    run = run_scenario(loaded, tmp_path / "run").out_dir
    cols, meta = read_log(run / "log.parquet")
    frame = map_frame(nc)  # the map's centre
    assert meta["geo"]["origin"]["lat"] == pytest.approx(43.05)
    assert meta["geo"]["origin"]["lon"] == pytest.approx(5.05)
    assert meta["geo"]["crs"] == frame.proj
    x0, y0 = frame.to_xy(43.04, 5.03)
    assert cols["vehicle.x"][0] == pytest.approx(float(x0), abs=1e-9)
    assert cols["vehicle.y"][0] == pytest.approx(float(y0), abs=1e-9)
    assert cols[columns.latitude()][0] == pytest.approx(43.04, abs=1e-10)
    assert cols[columns.longitude()][0] == pytest.approx(5.03, abs=1e-10)
    for e in ("ekf", "pf"):
        lat_e, lon_e = frame.to_latlon(cols[columns.estimate(e, "x")],
                                       cols[columns.estimate(e, "y")])
        np.testing.assert_allclose(cols[columns.latitude(e)], lat_e, rtol=0, atol=1e-12)
        np.testing.assert_allclose(cols[columns.longitude(e)], lon_e, rtol=0, atol=1e-12)
    assert (run / "trajectory.png").is_file()
    from uwcosim.export import export_csv
    header = export_csv(run, tmp_path / "log.csv").read_text().splitlines()[0]
    assert '"truth.lat_deg [deg]"' in header and '"est.ekf.lon_deg [deg]"' in header


def test_geographic_columns_of_a_replay(tmp_path):
    from uwcosim.scenario import load_scenario

    frame = LocalFrame(60.0, 10.0)
    t = np.arange(20.0) * 3.0
    x, y = 100.0 + 1.0 * t, -50.0 + 0.5 * t
    lat, lon = frame.to_latlon(x, y)
    lat[5] = np.nan  # a lost fix
    pcsv.write_csv(pa.table({"t": t, "lat": lat, "lon": lon}), tmp_path / "fixes.csv")
    (tmp_path / "r.toml").write_text("""
[geo]
origin = {lat = 60.0, lon = 10.0}
start = {lat = 60.0, lon = 10.0}
[replay]
file = "fixes.csv"
time = "t"
[[replay.geographic]]
lat = "lat"
lon = "lon"
x = "gps_x"
y = "gps_y"
[replay.measurements]
"gps.px_m" = "gps_x"
"gps.py_m" = "gps_y"
[replay.reference]
"ref.px" = "gps_x"
[sensors.gps]
outputs = ["gps.px_m", "gps.py_m"]
sigma = [2.0, 2.0]
[model]
kind = "cv"
truth = ["ref.px", "ref.vx", "ref.py", "ref.vy"]
sensors = ["gps"]
q_psd = [0.0, 0.01, 0.0, 0.01]
[estimation]
initial_std = [10.0, 1.0, 10.0, 1.0]
initial_error = "zero"
initial_state = {vx = 0.0, vy = 0.0}
[estimators.kf]
type = "kf"
""")
    loaded = load_scenario(tmp_path / "r.toml")
    run = run_scenario(loaded, tmp_path / "run", figures=False).out_dir
    cols, meta = read_log(run / "log.parquet")
    np.testing.assert_allclose(cols["z.gps.px_m"][6:], x[6:], atol=1e-6)
    assert not cols["z.gps.px_m.received"][5]
    # the first row: px from the reference (the fix), py from geo.start (0 at the origin)
    assert cols[columns.estimate("kf", "px")][0] == pytest.approx(x[0], abs=1e-6)
    assert cols[columns.estimate("kf", "py")][0] == pytest.approx(0.0, abs=1e-6)
    assert meta["replay"]["columns"]["measurements.gps.px_m"] == "gps_x (from lat)"
    s = json.loads((run / "summary.json").read_text())
    assert s["replay"]["rows"] == 20
    np.testing.assert_allclose(cols[columns.latitude("kf")][-1], lat[-1], atol=1e-4)
