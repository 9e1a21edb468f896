"""Collect a campaign's run records into ``runs.parquet`` and the aggregate table.

``runs.parquet``: one row per (run, estimator) with the run's RMSEs, ANEES, time per step, total
filter time, divergence and lost-track flags (:mod:`uwcosim.evaluation.trackloss`), seed,
variant, status and error. The aggregate (seed 000 eq. 56:
the mean over runs of each run's RMSE) goes to ``table.md`` and ``table.csv``, with the number
of runs that lost the track over the number run (``track lost``).

Nothing is averaged away: ``runs`` counts only the runs in the means (finished, not diverged,
a finite position RMSE); ``failed`` counts the variant's runs that did not finish (a variant
whose every run failed still has its row, estimator ``-``), ``nan`` the finished runs whose
position RMSE is NaN, and ``diverged`` the diverged ones.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

METRICS = ("rmse_position_m", "rmse_x_m", "rmse_y_m", "rmse_velocity_mps", "rmse_vx_mps",
           "rmse_vy_mps", "anees", "time_per_step_s", "total_time_s")


def read_record(path: Path) -> dict | None:
    """A finished run's record, or None if the file is not a complete record (truncated)."""
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(record, dict) or not {"variant", "run", "seed", "status"} <= set(record):
        return None
    return record


def read_records(results: Path) -> list[dict]:
    """Every complete record (a truncated file, e.g. of a killed campaign, is skipped)."""
    records = (read_record(p) for p in sorted(results.glob("*.json")))
    return [r for r in records if r is not None]


def run_rows(records: list[dict]) -> list[dict]:
    rows = []
    for r in records:
        base = {"variant": r["variant"], "run": r["run"], "seed": r["seed"],
                "status": r["status"], "error": r["error"]}
        if not r["estimators"]:
            rows.append({**base, "estimator": "", **{m: float("nan") for m in METRICS},
                         "diverged": False, "track_lost": False})
        for name, m in r["estimators"].items():
            rows.append({**base, "estimator": name,
                         **{k: float(m.get(k, float("nan"))) for k in METRICS},
                         "diverged": bool(m.get("diverged", False)),
                         "track_lost": bool(m.get("track_lost", m.get("diverged", False)))})
    return rows


def write_runs_parquet(rows: list[dict], path: Path) -> Path:
    cols = {k: [r[k] for r in rows] for k in rows[0]} if rows else {}
    pq.write_table(pa.table(cols), path)
    return path


def aggregate(rows: list[dict]) -> list[dict]:
    """Mean over finished, non-diverged runs with a finite position RMSE of each run's
    metrics, per (variant, estimator); with the failed, NaN and diverged runs counted."""
    groups: dict[tuple[str, str], list[dict]] = {}
    failed: dict[str, set] = {}
    for r in rows:
        failed.setdefault(r["variant"], set())
        if r["status"] != "ok":
            failed[r["variant"]].add(r["run"])
        if r["estimator"]:
            groups.setdefault((r["variant"], r["estimator"]), []).append(r)
    for variant in failed:  # every run of it failed before any estimate: still a row
        if not any(v == variant for v, _ in groups):
            groups[(variant, "-")] = []
    out = []
    for (variant, est), rs in groups.items():
        ok = [r for r in rs if r["status"] == "ok" and not r["diverged"]]
        good = [r for r in ok if np.isfinite(r["rmse_position_m"])]
        row = {"variant": variant, "estimator": est, "runs": len(good),
               "failed": len(failed[variant]), "nan": len(ok) - len(good),
               "diverged": sum(r["diverged"] for r in rs),
               "track_lost": sum(r.get("track_lost", r["diverged"]) for r in rs),
               "runs_total": len(rs)}
        for m in METRICS:
            vals = np.array([r[m] for r in good], dtype=float)
            vals = vals[np.isfinite(vals)]
            row[m] = float(vals.mean()) if vals.size else float("nan")
            if m == "rmse_position_m":
                row["rmse_position_std_m"] = float(vals.std(ddof=1)) if vals.size > 1 else 0.0
        out.append(row)
    return out


def resource_lines(records: list[dict]) -> list[str]:
    """Peak RSS per campaign worker and the mean wall time of a run (for ``table.md``)."""
    rss: dict[int, float] = {}
    walls = []
    n_failed = sum(r.get("status") != "ok" for r in records)
    for r in records:
        if "peak_rss_mb" in r:
            w = int(r.get("worker", 0))
            rss[w] = max(rss.get(w, 0.0), float(r["peak_rss_mb"]))
        if "wall_s" in r:
            walls.append(float(r["wall_s"]))
    if not rss and not walls:
        return []
    out = [""]
    if rss:
        out.append(f"Peak RSS per worker process: max {max(rss.values()):.0f} MB, "
                   f"median {float(np.median(list(rss.values()))):.0f} MB "
                   f"({len(rss)} worker processes).")
    if walls:
        failed = f", {n_failed} of them failed" if n_failed else ""
        out.append(f"Wall time of a run (co-simulation, filters, log): mean "
                   f"{float(np.mean(walls)):.2f} s over {len(walls)} runs{failed}.")
    return out


def write_tables(agg: list[dict], out: Path) -> tuple[Path, Path]:
    md = out / "table.md"
    lines = ["| variant | estimator | runs | failed | NaN | pos. RMSE (m) | x RMSE (m) | "
             "y RMSE (m) | vx RMSE (m/s) | vy RMSE (m/s) | ANEES | filter time per run (s) | "
             "diverged | track lost |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in agg:
        lines.append(
            f"| {r['variant']} | {r['estimator']} | {r['runs']} | {r['failed']} | {r['nan']} | "
            f"{r['rmse_position_m']:.2f} "
            f"± {r['rmse_position_std_m']:.2f} | {r['rmse_x_m']:.2f} | {r['rmse_y_m']:.2f} | "
            f"{r['rmse_vx_mps']:.4f} | {r['rmse_vy_mps']:.4f} | {r['anees']:.2f} | "
            f"{r['total_time_s']:.2f} | {r['diverged']} | "
            f"{r.get('track_lost', 0)}/{r.get('runs_total', r['runs'])} |")
    lines += resource_lines(read_records(out / "results"))
    md.write_text("\n".join(lines) + "\n")
    path_csv = out / "table.csv"
    with open(path_csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(agg[0]) if agg else ["variant"])
        w.writeheader()
        w.writerows(agg)
    return md, path_csv
