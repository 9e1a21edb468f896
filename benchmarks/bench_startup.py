"""Start-up and exit of the command line: what a short ``uwcosim run`` costs before and after
its work.

Measured in one run, side by side (the machine is shared: compare the rows, not the seconds):

1. the wall time of whole commands, median of ``--repeat`` runs with warm caches (the FMUs
   built, the Numba kernels in their on-disk cache, the OS file cache warm after one untimed
   run of each): ``python -c pass`` (the interpreter alone), ``uwcosim --version``,
   ``uwcosim run SCENARIO --set run.duration=10 --no-figures`` for the shipped scenarios
   (``lost_measurements``: Kalman filters only, no compiled kernel; ``tan_dead_reckoning`` and
   ``tan_terrain``: six filters, four of them with compiled kernels), each also with
   ``UWCOSIM_FAST_EXIT=0`` (the interpreter's normal teardown after the last line);
   with ``--compare SRC`` (an unpacked older source tree, e.g. ``git archive main``, with its
   FMUs in ``SRC/fmus``) the same ``--version`` and ``lost_measurements`` commands run from it
   (``PYTHONPATH=SRC``) in the same loop: the before/after ratio;
2. the import time of a 10-step ``lost_measurements`` run (``python -X importtime``), the
   self time of every module summed by top-level package (numba, scipy, casadi, ...): where the
   fixed cost of a run is; and which of numba, matplotlib and pandas a run imports.

Goal (issue 22): ``uwcosim run --no-figures`` of a 10-step scenario <= 1.0 s wall on a quiet
2-core machine with warm caches; no Numba import without compiled filters; no matplotlib
without figures. Run: ``.venv/bin/python benchmarks/bench_startup.py [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UWCOSIM = [sys.executable, "-m", "uwcosim"]
SCENARIOS = ("lost_measurements", "tan_dead_reckoning", "tan_terrain")


def wall(cmd: list[str], env: dict | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env=env, cwd=(env or {}).get("BENCH_CWD", ROOT))
    return time.perf_counter() - t0


def run_cmd(scenario: str, out: Path) -> list[str]:
    return [*UWCOSIM, "-q", "run", scenario, "--set", "run.duration=10", "--no-figures",
            "--out", str(out), "--force"]


def import_breakdown(cmd: list[str]) -> tuple[dict[str, float], set[str]]:
    """Self import time (s) by top-level package, and the top-level packages imported."""
    proc = subprocess.run([sys.executable, "-X", "importtime", *cmd[1:]], check=True,
                          capture_output=True, text=True, cwd=ROOT)
    by_top: dict[str, float] = defaultdict(float)
    seen: set[str] = set()
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        self_us, _, name = line[len("import time:"):].split("|")
        top = name.strip().split(".")[0]
        seen.add(top)
        by_top[top] += int(self_us) / 1e6
    return dict(by_top), seen


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per command")
    ap.add_argument("--compare", default=None, metavar="SRC",
                    help="an older source tree to time side by side (PYTHONPATH=SRC)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_startup_"))
    slow_exit = {**os.environ, "UWCOSIM_FAST_EXIT": "0"}
    rows = [("python -c pass", [sys.executable, "-c", "pass"], None),
            ("uwcosim --version", [*UWCOSIM, "--version"], None)]
    for s in SCENARIOS:
        rows.append((f"run {s} (10 steps, --no-figures)", run_cmd(s, tmp / s), None))
        rows.append((f"run {s}, normal interpreter exit", run_cmd(s, tmp / s), slow_exit))
    if args.compare:
        src = Path(args.compare).resolve()
        old = {**os.environ, "PYTHONPATH": str(src), "BENCH_CWD": str(src)}
        rows.append((f"before ({src.name}): uwcosim --version", [*UWCOSIM, "--version"], old))
        rows.append((f"before ({src.name}): run lost_measurements (10 steps, --no-figures)",
                     run_cmd(str(src / "scenarios" / "lost_measurements.toml"),
                             tmp / "before"), old))
    for _, cmd, env in rows:  # warm: FMUs, kernel cache, file cache
        wall(cmd, env)
    times: dict[str, list[float]] = {label: [] for label, _, _ in rows}
    for _ in range(args.repeat):  # interleaved: the load of the machine hits every row alike
        for label, cmd, env in rows:
            times[label].append(wall(cmd, env))
    print(f"## whole commands (median of {args.repeat}, s; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)\n")
    print("| command | median wall (s) | min (s) |\n|---|---|---|")
    for label, ts in times.items():
        print(f"| {label} | {statistics.median(ts):.2f} | {min(ts):.2f} |")

    by_top, seen = import_breakdown(run_cmd("lost_measurements", tmp / "imports"))
    total = sum(by_top.values())
    print(f"\n## imports of `run lost_measurements` (10 steps): {total:.2f} s in all\n")
    print("| package | self import time (s) | share |\n|---|---|---|")
    for top, t in sorted(by_top.items(), key=lambda kv: -kv[1])[:12]:
        print(f"| {top} | {t:.3f} | {t / total:.0%} |")
    for lib in ("numba", "matplotlib", "pandas"):
        print(f"\n{lib} imported: {'yes' if lib in seen else 'no'}", end="")
    _, seen_tan = import_breakdown(run_cmd("tan_terrain", tmp / "imports_tan"))
    print(f"\ntan_terrain (compiled filters): numba imported: "
          f"{'yes' if 'numba' in seen_tan else 'no'}, matplotlib imported: "
          f"{'yes' if 'matplotlib' in seen_tan else 'no'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
