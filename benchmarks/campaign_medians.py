"""Mean, median and lost runs per variant and estimator of a campaign's ``runs.parquet``.

``table.md`` of a campaign gives means; with a few runs that lose the track a mean is one run
away from another ranking, so the robustness sections of ``docs/results/table1.md`` also give
the median position RMSE and the number of runs whose position RMSE is above ``--lost-m``
(default 50 m), and the mean ANEES (1 = consistent). Run:

    .venv/bin/python benchmarks/campaign_medians.py runs/table1_truthmap/runs.parquet
"""

from __future__ import annotations

import argparse

import numpy as np
import pyarrow.parquet as pq


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", help="a campaign's runs.parquet")
    ap.add_argument("--lost-m", type=float, default=50.0,
                    help="a run is lost when its position RMSE is above this (m)")
    args = ap.parse_args()
    t = pq.read_table(args.runs).to_pydict()
    rows = [dict(zip(t, vals, strict=True)) for vals in zip(*t.values(), strict=True)]
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    ests = list(dict.fromkeys(r["estimator"] for r in rows if r["estimator"]))
    print("| variant (runs) | " + " | ".join(ests) + " |")
    print("|---|" + "---|" * len(ests))
    anees = []
    for v in variants:
        cells, line = [], []
        for e in ests:
            ok = [r for r in rows if r["variant"] == v and r["estimator"] == e
                  and r["status"] == "ok"]
            rmse = np.array([r["rmse_position_m"] for r in ok], dtype=float)
            lost = int(np.sum(rmse > args.lost_m))
            cells.append(f"{np.nanmean(rmse):.2f} / {np.nanmedian(rmse):.2f}, {lost}")
            line.append(f"{e} {np.nanmean([r['anees'] for r in ok]):.3g}")
        n = len({r["run"] for r in rows if r["variant"] == v})
        print(f"| {v} ({n}) | " + " | ".join(cells) + " |")
        anees.append(f"{v}: " + ", ".join(line))
    print("\ncells: mean / median position RMSE (m), runs lost (RMSE above "
          f"{args.lost_m:g} m)\n\nmean ANEES (1 = consistent):")
    print("\n".join(anees))


if __name__ == "__main__":
    main()
