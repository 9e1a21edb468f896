"""Paired comparison of filters over the runs of a campaign (or of two campaigns on the same runs).

Every run of a campaign variant gives all its filters the same truth and measurements, so the
per-run differences of position RMSE are far less noisy than the difference of the means. For
each variant this prints, per filter: the mean position RMSE, the mean paired difference to the
reference filter (``--against``, default ``ekf``) with its standard error, and in how many runs
the filter was the most accurate. With ``--other DIR`` (a second campaign with the same seed and
run numbers, e.g. the same truths with other filter settings) it also prints, per filter, the
mean paired difference ``other - first`` and the median run ANEES of each.

    .venv/bin/python benchmarks/paired_rmse.py /tmp/uwcosim_paper_campaign
    .venv/bin/python benchmarks/paired_rmse.py /tmp/uwcosim_paper_campaign \
        --other /tmp/uwcosim_paper_unaware

(docs/results/table1.md, "Table 1 as the paper describes it").
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq


def _runs(directory: Path) -> dict[tuple[str, str], dict[int, tuple[float, float]]]:
    """``{(variant, estimator): {run: (position RMSE, ANEES)}}`` of the finished runs."""
    out: dict[tuple[str, str], dict[int, tuple[float, float]]] = {}
    for r in pq.read_table(directory / "runs.parquet").to_pylist():
        if r["status"] == "ok" or r["rmse_position_m"] is not None:
            out.setdefault((r["variant"], r["estimator"]), {})[r["run"]] = (
                r["rmse_position_m"], r["anees"])
    return out


def _se(d: np.ndarray) -> float:
    return float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("nan")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", type=Path, help="campaign directory (with runs.parquet)")
    ap.add_argument("--against", default="ekf", help="reference filter of the paired differences")
    ap.add_argument("--other", type=Path, help="a second campaign on the same runs")
    args = ap.parse_args(argv)
    first = _runs(args.campaign)
    other = _runs(args.other) if args.other else None
    for variant in sorted({v for v, _ in first}):
        names = sorted(e for v, e in first if v == variant)
        runs = sorted(set.intersection(*(set(first[(variant, e)]) for e in names)))
        A = np.array([[first[(variant, e)][i][0] for i in runs] for e in names])
        best = np.bincount(np.argmin(A, axis=0), minlength=len(names))
        ref = A[names.index(args.against)] if args.against in names else None
        print(f"{variant} ({len(runs)} runs)")
        for j, e in enumerate(names):
            line = f"  {e:12s} mean {A[j].mean():8.2f} m, best in {best[j]:3d} runs"
            if ref is not None:
                d = A[j] - ref
                line += f", minus {args.against}: {d.mean():+.2f} ± {_se(d):.2f} m (se)"
            if other is not None and (variant, e) in other:
                o = other[(variant, e)]
                common = [i for i in runs if i in o]
                d = np.array([o[i][0] - first[(variant, e)][i][0] for i in common])
                an1 = np.median([first[(variant, e)][i][1] for i in common])
                an2 = np.median([o[i][1] for i in common])
                line += (f"; other - first: {d.mean():+.2f} ± {_se(d):.2f} m, median ANEES "
                         f"{an1:.2f} -> {an2:.2f}")
            print(line)


if __name__ == "__main__":
    main()
