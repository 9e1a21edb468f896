"""The up-front memory estimates (``uwcosim/core/memory.py``) against what runs take.

Each measurement is a fresh process (``python -m uwcosim run`` or a map load); its own peak
resident memory is read by ``os.wait4`` when it ends. The
difference between a large and a small setting, divided by the size difference, is the
measured cost per particle / per map node; the estimate's per-unit cost is printed beside it.

    .venv/bin/python benchmarks/bench_memory_estimates.py [--particles 1000 1000000]
        [--map-sizes 1500 3000]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"

MAP_SCRIPT = """
import sys, numpy as np, h5netcdf
from uwcosim.models.terrain import load_map
n, path = int(sys.argv[1]), sys.argv[2]
with h5netcdf.File(path, "w") as f:
    f.dimensions = {"y": n, "x": n}
    f.create_variable("x", ("x",), data=np.arange(n) * 50.0)
    f.create_variable("y", ("y",), data=np.arange(n) * 50.0)
    v = f.create_variable("elevation", ("y", "x"), "i2", compression="gzip")
    v[...] = np.full((n, n), -1000, "i2")
b = load_map(path)
b.write_coefficients(path + ".bin")
b.casadi_function()
"""


def peak_mb(args: list[str]) -> float:
    """Peak RSS (MB) of the process ``args``, which must succeed."""
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{args[:4]}...: exit status {proc.returncode}")
    return usage.ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, nargs=2, default=[1000, 1_000_000])
    ap.add_argument("--map-sizes", type=int, nargs=2, default=[1500, 3000])
    a = ap.parse_args()
    from uwcosim.models.map_decode import BYTES_PER_CELL

    with tempfile.TemporaryDirectory() as tmp:
        rss = []
        for n in a.map_sizes:
            rss.append(peak_mb([sys.executable, "-c", MAP_SCRIPT, str(n), f"{tmp}/m{n}.nc"]))
        cells = [n * n for n in a.map_sizes]
        per = (rss[1] - rss[0]) * 2**20 / (cells[1] - cells[0])
        print(f"map: peak RSS {rss[0]:.0f} MB ({a.map_sizes[0]}^2), {rss[1]:.0f} MB "
              f"({a.map_sizes[1]}^2): {per:.0f} bytes per node to load it, write map.bin and "
              f"make the CasADi spline; estimate {BYTES_PER_CELL:.0f} per node in a run")
        rss = []
        for n in a.particles:
            rss.append(peak_mb([sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out",
                                f"{tmp}/pf{n}", "--no-figures", "--set", "run.duration=5",
                                "--set", f'estimators={{pf={{type="pf", n_particles={n}}}}}']))
        per = (rss[1] - rss[0]) * 2**20 / (a.particles[1] - a.particles[0])
        nx, nz = 4, 3  # tan_terrain's model
        print(f"pf: peak RSS {rss[0]:.0f} MB ({a.particles[0]} particles), {rss[1]:.0f} MB "
              f"({a.particles[1]}): {per:.0f} bytes per particle; estimate "
              f"{8 * (6 * nx + 2 * nz + 12)} (8 x (6 nx + 2 nz + 12))")


if __name__ == "__main__":
    main()
