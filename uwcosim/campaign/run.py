"""``run_campaign``: tasks -> results/ -> runs.parquet, table.md/csv, figures, report.md."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

from uwcosim.campaign.aggregate import (
    aggregate,
    read_records,
    run_rows,
    write_runs_parquet,
    write_tables,
)
from uwcosim.campaign.execute import pending_tasks, run_tasks
from uwcosim.campaign.spec import LoadedCampaign
from uwcosim.errors import UwcosimError


def run_campaign(campaign: LoadedCampaign, out: Path, runs: int | None = None,
                 workers: int | None = None, scheduler: str | None = None,
                 resume: bool = False, figures: bool = True) -> dict:
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UwcosimError(f"{out}: cannot create the campaign directory ({exc.strerror})"
                           ) from None
    results = out / "results"
    results.mkdir(exist_ok=True)
    tasks = campaign.tasks(runs, out)
    todo = pending_tasks(tasks, results, resume)
    shutil.copyfile(campaign.path, out / "campaign.toml")
    workers = workers if workers is not None else (os.cpu_count() or 1)
    start = time.perf_counter()
    failures = 0
    try:
        failures = run_tasks(todo, results, workers, scheduler, total=len(tasks))
    finally:
        # whatever happened, what finished is aggregated
        summary = collect(out, figures=figures)
    summary["wall_time_s"] = time.perf_counter() - start
    summary["failed_runs_this_session"] = failures
    summary["workers"] = workers if not scheduler else scheduler
    return summary


def collect(campaign_dir: Path, figures: bool = True, out: Path | None = None) -> dict:
    """Aggregate ``campaign_dir/results`` into ``runs.parquet``, ``table.md``/``.csv`` and
    figures, written to ``out`` (default: the campaign directory)."""
    rows = run_rows(read_records(Path(campaign_dir) / "results"))
    out = Path(campaign_dir) if out is None else Path(out)
    if not rows:
        return {"runs": 0, "table": []}
    write_runs_parquet(rows, out / "runs.parquet")
    agg = aggregate(rows)
    md, _ = write_tables(agg, out)
    if figures:
        from uwcosim.plots.campaign_figures import rmse_per_run, summary_chart

        figs = rmse_per_run(rows, out) + [summary_chart(rows, out)]
        text = f"# Campaign results\n\n{md.read_text()}\n" + "".join(
            f"![{p.stem}]({p.name})\n\n" for p in figs)
        (out / "report.md").write_text(text)
    failed = sorted({(r["variant"], r["run"], r["error"]) for r in rows if r["status"] != "ok"})
    return {"runs": len({(r["variant"], r["run"]) for r in rows}), "table": agg,
            "failed": [{"variant": v, "run": i, "error": e} for v, i, e in failed]}
