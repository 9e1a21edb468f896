"""Table 1 runs with this tree and with an earlier commit, interleaved: cost and accuracy.

Extracts ``REF`` (``git archive``) into a temporary directory (with this tree's built FMUs) and
runs the same Table 1 tasks (``scenarios/campaigns/table1.toml``, same seeds) with both trees,
alternating, each run in a fresh process after one warm-up run (imports, FMU instances, caches
and compiled kernels are then loaded, as in a campaign worker). Prints per run the CPU and wall
time and each filter's time and position RMSE, then the mean CPU time per run of each tree and
the largest difference of a filter's RMSE between the trees (the speed-ups must not change the
results).

    .venv/bin/python benchmarks/bench_compare_ref.py REF [--runs 2] [--variants with_terrain]

CPU time is the process time of the run: what it costs on a core of its own; the wall time
also counts waiting for a core on a loaded machine.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, os, sys, tempfile, time
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
root, run, variant = sys.argv[1], int(sys.argv[2]), sys.argv[3]
sys.path.insert(0, root)
from pathlib import Path
from uwcosim.campaign import load_campaign
from uwcosim.campaign.execute import execute_run
spec = load_campaign(Path(root) / "scenarios/campaigns/table1.toml")
tasks = [t for t in spec.tasks(run + 2, Path(tempfile.mkdtemp())) if t.variant == variant]
execute_run(tasks[run + 1])  # warm-up on another run of the same variant
a, c = time.perf_counter(), time.process_time()
rec = execute_run(tasks[run])
out = {"wall": time.perf_counter() - a, "cpu": time.process_time() - c, "status": rec["status"],
       "time": {k: v["total_time_s"] for k, v in rec["estimators"].items()},
       "rmse": {k: v["rmse_position_m"] for k, v in rec["estimators"].items()}}
print(json.dumps(out))
"""


def run_child(root: Path, run: int, variant: str) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(root), str(run), variant],
                         capture_output=True, text=True, cwd=root)
    if out.returncode != 0:
        raise SystemExit(f"{root}: run {run} {variant} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ref", help="git commit to compare with (e.g. the one before a change)")
    ap.add_argument("--runs", type=int, default=2, help="runs per variant")
    ap.add_argument("--variants", nargs="+", default=["with_terrain", "without_terrain"])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="uwcosim_ref_") as tmp:
        ref_root = Path(tmp)
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.ref],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(ref_root)], input=archive, check=True)
        (ref_root / "fmus").mkdir(exist_ok=True)
        for fmu in (ROOT / "fmus").glob("*.fmu"):
            shutil.copy(fmu, ref_root / "fmus" / fmu.name)
        trees = {args.ref[:10]: ref_root, "this tree": ROOT}
        results: dict[str, list[dict]] = {k: [] for k in trees}
        for run in range(args.runs):
            for variant in args.variants:
                for name, root in trees.items():
                    r = run_child(root, run, variant)
                    results[name].append(r)
                    times = " ".join(f"{k} {v:.2f}" for k, v in r["time"].items())
                    print(f"{name:10s} {variant:16s} run {run}: cpu {r['cpu']:.2f} s, wall "
                          f"{r['wall']:.2f} s; filters (s): {times}", flush=True)
    print()
    for name, rs in results.items():
        print(f"{name:10s} CPU time per run: mean {statistics.mean(r['cpu'] for r in rs):.2f} s"
              f" (wall {statistics.mean(r['wall'] for r in rs):.2f} s)")
    old, new = results.values()
    for est in new[0]["rmse"]:
        diff = max(abs(a["rmse"][est] - b["rmse"][est]) for a, b in zip(old, new, strict=True)
                   if est in a["rmse"])
        print(f"  {est:12s} largest difference of a run's position RMSE: {diff:.2e} m")


if __name__ == "__main__":
    main()
