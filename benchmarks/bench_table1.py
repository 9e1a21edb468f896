"""Cost of the Table 1 campaign (seed 000) on this machine, measured on a few runs.

Default: runs ``--runs N`` runs of each variant of ``scenarios/campaigns/table1.toml`` (default
2) in this process, one at a time (one worker, one BLAS thread), and reports the wall time of a
run (co-simulation, the five filters, log), each filter's time per 5000-step run beside the
paper's CPU times (PFM-PSI 25.3 s, PF 31.1 s, UKF 65.6 s), the filters' share of the run, and
the campaign's wall time extrapolated to its 200 runs on W workers:
``200 x (mean wall time of a run) / W`` (runs are independent and of equal length; the scaling
with W is what ``--scheduler`` measures). The goal is 6 minutes on 2 cores.

``--scheduler``: the same runs (``--runs N`` per variant) on a local Dask cluster of 1 and then
2 worker processes (one thread each), and the throughput ratio (goal >= 1.8x). The first run of
each worker pays its start-up (imports, FMU instances, compiled kernels loaded from cache): use
``--runs 4`` or more for a fair ratio.

    .venv/bin/python benchmarks/bench_table1.py [--runs 2] [--workers 2]
    .venv/bin/python benchmarks/bench_table1.py --scheduler [--runs 4]

The machine is shared and noisy: repeat and compare medians; the full campaign
(``uwcosim campaign scenarios/campaigns/table1.toml --out runs/table1``) is the final word.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from uwcosim.campaign import load_campaign  # noqa: E402
from uwcosim.campaign.driver import run_campaign  # noqa: E402

PAPER_S = {"pfm_psi": 25.257, "pf": 31.100, "ukf": 65.6224}
SPEC = ROOT / "scenarios" / "campaigns" / "table1.toml"


def _records(out: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((out / "results").glob("*.json"))]


def per_run(args) -> None:
    spec = load_campaign(SPEC)
    full = spec.spec.runs * len(spec.spec.variants)
    with tempfile.TemporaryDirectory() as tmp:
        a = time.perf_counter()
        run_campaign(spec, Path(tmp), runs=args.runs, workers=1, figures=False)
        wall = time.perf_counter() - a
        recs = _records(Path(tmp))
    walls = [r["wall_s"] for r in recs]
    cpus = [r["cpu_s"] for r in recs]
    n = len(recs)
    print(f"{n} runs ({args.runs} per variant, 1 worker in this process): {wall:.1f} s; "
          f"run wall time mean {statistics.mean(walls):.2f} s, median "
          f"{statistics.median(walls):.2f} s (first run includes start-up: "
          f"{walls[0] if recs else float('nan'):.2f} s)")
    per: dict[str, list[float]] = {}
    for r in recs:
        for name, m in r["estimators"].items():
            per.setdefault(name, []).append(m["total_time_s"])
    filt = sum(statistics.mean(v) for v in per.values())
    print("filter time per 5000-step run (mean over runs), ours vs paper:")
    for name, times in sorted(per.items()):
        paper = f"{PAPER_S[name]:7.1f} s" if name in PAPER_S else "      -"
        print(f"  {name:12s} {statistics.mean(times):6.2f} s   paper {paper}")
    cost = statistics.median(walls)
    cpu = statistics.median(cpus)
    print(f"filters {filt:.2f} s of a {cost:.2f} s run ({100 * filt / cost:.0f}%); "
          f"co-simulation, log and bookkeeping {cost - filt:.2f} s")
    print(f"CPU time of a run: median {cpu:.2f} s (wall {cost:.2f} s: the difference is "
          f"waiting for a core; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)")
    for w in sorted({1, 2, args.workers}):
        goal = " (goal <= 6 min on 2 cores)" if w == 2 else ""
        print(f"extrapolated: {full} runs on {w} worker(s): {full * cost / w / 60:.1f} min from "
              f"the wall time, {full * cpu / w / 60:.1f} min from the CPU time (a core per "
              f"worker){goal}")
    peak = max((r.get("peak_rss_mb", 0.0) for r in recs), default=float("nan"))
    print(f"peak RSS of the worker: {peak:.0f} MB (goal <= 1024 MB)")


def scale_out(args) -> None:
    from distributed import LocalCluster

    spec = load_campaign(SPEC)
    rates, per_run_wall = {}, {}
    for n_workers in (1, 2):
        with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, \
                tempfile.TemporaryDirectory() as tmp:
            load0 = os.getloadavg()[0]
            a = time.perf_counter()
            s = run_campaign(spec, Path(tmp), runs=args.runs, scheduler=cluster.scheduler_address,
                             figures=False)
            wall = time.perf_counter() - a
            walls = [r["wall_s"] for r in _records(Path(tmp))]
            rates[n_workers] = s["runs"] / wall
            per_run_wall[n_workers] = statistics.median(walls)
            print(f"Dask, {n_workers} worker(s): {s['runs']} runs in {wall:.1f} s = "
                  f"{rates[n_workers]:.3f} runs/s; run wall time median "
                  f"{per_run_wall[n_workers]:.2f} s; load average {load0:.1f} -> "
                  f"{os.getloadavg()[0]:.1f}")
    ratio = rates[2] / rates[1]
    print(f"throughput 2 workers / 1 worker: {ratio:.2f} (goal >= 1.8: "
          f"{'met' if ratio >= 1.8 else 'NOT met'}) on {os.cpu_count()} CPUs")
    print(f"a run took {per_run_wall[2] / per_run_wall[1]:.2f}x as long with 2 workers as with "
          f"1: above 1, the workers did not get a core each (other load on the machine)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2, help="runs per variant")
    ap.add_argument("--workers", type=int, default=2, help="workers to extrapolate to")
    ap.add_argument("--scheduler", action="store_true",
                    help="measure 1 vs 2 workers of a local Dask cluster")
    args = ap.parse_args()
    if args.scheduler:
        scale_out(args)
    else:
        per_run(args)


if __name__ == "__main__":
    main()
