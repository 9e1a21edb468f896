"""Two finished runs of one campaign side by side: their cost and whether their tables agree.

For each output folder of ``uwcosim campaign`` (e.g. one made by the tree before a change and
one by the tree after it, back to back on the same machine) prints the session's wall time and
runs/s (``session.json``), the mean CPU and wall time of a run (``results/*.json``: the worker's
process time and wall clock of each run) and the filter time per run of each estimator; then
compares the two tables (``table.md``) in the columns both have, except the filter-time column:
every cell as printed, so "identical" means the same table to the printed precision.

    .venv/bin/python benchmarks/compare_campaigns.py BEFORE_DIR AFTER_DIR
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

TIME_COLUMNS = {"filter time per run (s)"}


def cost(out: Path) -> dict:
    recs = [json.loads(p.read_text()) for p in sorted((out / "results").glob("*.json"))]
    session = json.loads((out / "session.json").read_text())
    per: dict[str, list[float]] = {}
    for r in recs:
        for name, m in r.get("estimators", {}).items():
            per.setdefault(f"{r['variant']}/{name}", []).append(m["total_time_s"])
    return {"runs": len(recs), "session wall s": session["wall_time_s"],
            "runs/s": session["runs_per_s"],
            "CPU s per run": statistics.mean(r["cpu_s"] for r in recs),
            "wall s per run": statistics.mean(r["wall_s"] for r in recs),
            "filters": {k: statistics.mean(v) for k, v in sorted(per.items())}}


def table(out: Path) -> dict[tuple[str, str], dict[str, str]]:
    lines = [ln for ln in (out / "table.md").read_text().splitlines() if ln.startswith("|")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    rows = {}
    for ln in lines[2:]:
        cells = [c.strip() for c in ln.strip("|").split("|")]
        row = dict(zip(head, cells, strict=True))
        rows[(row["variant"], row["estimator"])] = row
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    args = ap.parse_args()
    a, b = cost(args.before), cost(args.after)
    for key in ("runs", "session wall s", "runs/s", "CPU s per run", "wall s per run"):
        ratio = f"  ({b[key] / a[key] - 1:+.1%})" if key != "runs" else ""
        print(f"{key:16s} {a[key]:10.3f} -> {b[key]:10.3f}{ratio}")
    print("filter time per run (s, wall):")
    for k in sorted(set(a["filters"]) | set(b["filters"])):
        print(f"  {k:28s} {a['filters'].get(k, float('nan')):7.3f} -> "
              f"{b['filters'].get(k, float('nan')):7.3f}")
    ta, tb = table(args.before), table(args.after)
    differ = []
    for key in sorted(set(ta) | set(tb)):
        if key not in ta or key not in tb:
            differ.append(f"{key}: only in {'after' if key in tb else 'before'}")
            continue
        for col in sorted((set(ta[key]) & set(tb[key])) - TIME_COLUMNS):
            if ta[key][col] != tb[key][col]:
                differ.append(f"{key} {col}: {ta[key][col]} -> {tb[key][col]}")
    common = sorted(set.intersection(*(set(r) for r in (*ta.values(), *tb.values())))
                    - TIME_COLUMNS)
    print(f"tables: {len(ta)} rows; compared columns: {', '.join(common)} (not the filter time)")
    print("tables identical to the printed precision" if not differ else
          "tables DIFFER:\n  " + "\n  ".join(differ))


if __name__ == "__main__":
    main()
