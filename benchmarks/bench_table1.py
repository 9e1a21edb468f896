"""Time of the Table 1 campaign (seed 000) on this machine, with the per-filter breakdown.

Runs ``scenarios/campaigns/table1.toml`` with ``--runs N`` (default 4) on all cores, measures
the wall time, and extrapolates linearly to the spec's 100 runs (runs are independent and of
equal length, so the extrapolation is the measured rate times the run count). Prints each
filter's time per 5000-step run beside the paper's CPU times (PFM-PSI 25.3 s, PF 31.1 s,
UKF 65.6 s), and the campaign total beside the goal (10 minutes) and the paper (~3.4 hours for
600 filter runs). Run: ``.venv/bin/python benchmarks/bench_table1.py [N]``.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from uwcosim.campaign import load_campaign  # noqa: E402
from uwcosim.campaign.run import run_campaign  # noqa: E402

PAPER_S = {"pfm_psi": 25.257, "pf": 31.100, "ukf": 65.6224}


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 4
    spec = load_campaign(ROOT / "scenarios" / "campaigns" / "table1.toml")
    workers = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as tmp:
        a = time.perf_counter()
        summary = run_campaign(spec, Path(tmp), runs=n, workers=workers, figures=False)
        wall = time.perf_counter() - a
    full = spec.spec.runs
    print(f"{n} runs x {len(spec.spec.variants)} variants on {workers} workers: {wall:.1f} s")
    est = wall * full / n
    print(f"extrapolated to {full} runs: {est / 60:.1f} min (goal <= 10 min; paper ~3.4 h "
          f"for the 600 runs of its three filters)")
    per: dict[str, list[float]] = {}
    for row in summary["table"]:
        per.setdefault(row["estimator"], []).append(row["total_time_s"])
    print("filter time per 5000-step run (mean over variants), ours vs paper:")
    total = 0.0
    for name, times in sorted(per.items()):
        t = sum(times) / len(times)
        total += t
        paper = f"{PAPER_S[name]:7.1f} s" if name in PAPER_S else "      -"
        print(f"  {name:15s} {t:7.2f} s   paper {paper}")
    paper3 = sum(sum(per[k]) / len(per[k]) for k in PAPER_S if k in per)
    print(f"three paper filters together: {paper3:.2f} s per run; all filters {total:.2f} s")
    print(f"campaign without the extra rows (EKF, point mass), extrapolated: "
          f"{est * paper3 / total / 60:.1f} min (filter share only)")


if __name__ == "__main__":
    main()
