"""Write the small recorded mission of ``docs/replay.md``: ``seafloor.nc`` and ``mission.csv``.

Both are generated here, from a seed (nothing is copied from real data):

- ``seafloor.nc``: a GEBCO-style NetCDF (``lat``, ``lon`` in degrees, ``elevation`` in metres,
  negative below sea level) off the Provence coast, about 21 x 22 km, a uwcosim synthetic
  seafloor placed on a latitude/longitude grid;
- ``mission.csv``: what an AUV's logger would have written over 10 minutes: irregular time
  stamps (DVL pings 0.7 to 1.3 s apart), the DVL's velocity (forward and lateral: the body
  frame of eq. 54, rotated by the heading) in knots (bottom lock lost for 40 s: empty
  cells), the depth sounder every second ping (metres), the compass heading (degrees
  clockwise from north) and the commanded acceleration, and GPS fixes
  (latitude/longitude) at the start and every two minutes when the vehicle surfaces.

The vehicle moves with the filters' own TAN model (``uwcosim.models.tan``, the map projected
as a run projects it), so a filter matched to it is consistent. Run ``python
examples/replay/make_mission.py [OUT_DIR]`` (default: this folder); the test of
``docs/replay.md`` checks that the committed files are what this script writes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import h5netcdf
import numpy as np
import pyarrow as pa
import pyarrow.csv as pcsv

from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import load_map, map_frame, synthetic_bathymetry

SEED = 2024
LAT = (43.00, 43.19)
LON = (5.00, 5.26)
NODES = (77, 85)  # lat, lon
DURATION = 600.0
Q_PSD = np.array([0.05, 0.05, 1e-5, 1e-5])
DVL_SIGMA, DEPTH_SIGMA = 0.03, 1.0
KNOT = 1852.0 / 3600.0


def write_map(path: Path) -> Path:
    relief = synthetic_bathymetry(SEED, (0.0, 21_000.0, 0.0, 21_000.0), 250.0, mean_depth=600.0,
                                  relief_std=50.0)
    depth = relief.depth_grid[:NODES[0], :NODES[1]]
    with h5netcdf.File(path, "w") as f:
        f.dimensions = {"lat": NODES[0], "lon": NODES[1]}
        f.create_variable("lat", ("lat",), data=np.linspace(*LAT, NODES[0]))
        f.create_variable("lon", ("lon",), data=np.linspace(*LON, NODES[1]))
        f.create_variable("elevation", ("lat", "lon"),
                          data=np.round(-depth).astype(np.int16))  # GEBCO: whole metres
    return path


def write_mission(out: Path, seafloor: Path) -> Path:
    rng = np.random.default_rng(SEED)
    frame = map_frame(seafloor)
    bathy = load_map(seafloor)
    model = tan_model(Q_PSD, DVL_SIGMA, DEPTH_SIGMA, bathy)
    gaps = rng.uniform(0.7, 1.3, size=int(DURATION / 0.7))
    t = np.round(np.concatenate([[0.0], np.cumsum(gaps)]), 3)
    t = t[t <= DURATION]
    n = t.size
    x = np.array([-3000.0, -4000.0, 1.2, 0.3])  # south-west of the map's centre, heading ENE
    psi = np.where(t < 200, 0.25, np.where(t < 400, 0.9, -0.2))  # rad from east
    acc = np.zeros(n)
    rows = np.zeros((n, 4))
    rows[0] = x
    for k in range(1, n):
        dt = t[k] - t[k - 1]
        u = np.array([psi[k - 1], acc[k - 1]])
        w = rng.standard_normal(4) * np.sqrt(Q_PSD / dt)
        G = np.array([[dt, 0, 0, 0], [0, dt, 0, 0], [0, 0, dt, 0], [0, 0, 0, dt]])
        x = model.f(x, u, dt) + G @ w
        rows[k] = x
    z = np.array([model.h(r) for r in rows])
    ve = (z[:, 0] + rng.normal(0, DVL_SIGMA, n)) / KNOT
    vn = (z[:, 1] + rng.normal(0, DVL_SIGMA, n)) / KNOT
    depth = z[:, 2] + rng.normal(0, DEPTH_SIGMA, n)
    lock_lost = (t > 300) & (t < 340)
    ve[lock_lost] = vn[lock_lost] = np.nan
    depth[np.arange(n) % 2 == 1] = np.nan
    fix = np.zeros(n, dtype=bool)
    for tf in np.arange(0.0, DURATION + 1, 120.0):
        fix[np.argmin(np.abs(t - tf))] = True
    lat, lon = frame.to_latlon(rows[:, 0] + rng.normal(0, 3.0, n),
                               rows[:, 1] + rng.normal(0, 3.0, n))
    heading = (90.0 - np.rad2deg(psi)) % 360.0  # compass: clockwise from north
    table = pa.table({
        "t": t, "heading": np.round(heading, 2), "accel": acc,
        "dvl_fwd_kn": np.round(ve, 4), "dvl_lat_kn": np.round(vn, 4), "depth": np.round(depth, 2),
        "gps_lat": np.where(fix, np.round(lat, 7), np.nan),
        "gps_lon": np.where(fix, np.round(lon, 7), np.nan),
    })
    path = out / "mission.csv"
    pcsv.write_csv(table, path)
    return path


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    seafloor = write_map(out / "seafloor.nc")
    print(seafloor)
    print(write_mission(out, seafloor))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent)
