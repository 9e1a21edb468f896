"""``run_campaign``: tasks -> results/ -> runs.parquet, table.md/csv, figures, report.md.

``campaign.json`` in the output directory holds the campaign's fingerprint (seed, each
variant's scenario file, overrides and content hash) and its sha256; ``--resume`` refuses a
directory whose fingerprint differs, naming what changed. An interrupted campaign (Ctrl-C,
SIGTERM, SIGHUP) aggregates what finished, marks ``report.md`` partial, and raises
:class:`~uwcosim.core.errors.RunInterrupted` (exit status 128 + signal).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
from pathlib import Path

import numpy as np

from uwcosim.campaign.aggregate import (
    aggregate,
    read_records,
    run_rows,
    write_runs_parquet,
    write_tables,
)
from uwcosim.campaign.bound import bound_section, run_bounds
from uwcosim.campaign.execute import check_scheduler, pending_tasks, run_tasks
from uwcosim.campaign.spec import LoadedCampaign
from uwcosim.core.errors import RunInterrupted, ScenarioError, UwcosimError
from uwcosim.core.memory import memory_problem
from uwcosim.core.runguard import signal_name
from uwcosim.plots.campaign_figures import rmse_per_run, summary_chart

log = logging.getLogger(__name__)
MANIFEST = "campaign.json"


def _differences(old: dict, new: dict) -> list[str]:
    out = []
    if old.get("seed") != new["seed"]:
        out.append(f"seed {old.get('seed')} -> {new['seed']}")
    ov, nv = old.get("variants", {}), new["variants"]
    for name in sorted(set(ov) | set(nv)):
        if name not in nv:
            out.append(f"variant {name!r} removed")
        elif name not in ov:
            out.append(f"variant {name!r} added")
        else:
            for key, what in (("scenario", "scenario file"), ("set", "overrides"),
                              ("scenario_sha256", "scenario content")):
                if ov[name].get(key) != nv[name][key]:
                    out.append(f"variant {name!r}: {what} changed")
    return out


def check_manifest(campaign: LoadedCampaign, out: Path, resume: bool) -> None:
    """Refuse to resume into results of a different campaign; record the fingerprint."""
    path = out / MANIFEST
    new = campaign.fingerprint()
    if path.is_file():
        try:
            old = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            old = None
        if resume:
            try:  # a forged or damaged manifest ({"fingerprint": "garbage"}) is unreadable
                diff = _differences(old["fingerprint"], new)
            except (TypeError, KeyError, AttributeError):
                raise ScenarioError(f"{path}: unreadable campaign manifest: cannot check that "
                                    f"--resume continues the same campaign (use another --out)"
                                    ) from None
            if diff:
                raise ScenarioError(f"{campaign.path}: --resume into {out}: the campaign "
                                    f"changed ({'; '.join(diff)}); use another --out")
    elif resume and any((out / "results").glob("*.json")):
        raise ScenarioError(f"{out}: results without a campaign manifest ({MANIFEST}): cannot "
                            f"check that --resume continues the same campaign (use another "
                            f"--out)")
    tmp = path.with_name(MANIFEST + ".tmp")
    tmp.write_text(json.dumps({"sha256": campaign.sha256, "fingerprint": new}, indent=2,
                              sort_keys=True))
    os.replace(tmp, path)


#: what a campaign worker process takes (peak RSS of a tan_terrain run: 257 MB), for the
#: memory estimate of more workers than cores
WORKER_BYTES = 0.3 * 2**30


def worker_count(workers: int | None, n_tasks: int, oversubscribe: bool = False) -> int:
    """The local processes to start: ``workers`` (default: the cores), capped at the cores
    unless ``oversubscribe`` (then estimated against the memory limit), and at the runs."""
    cores = os.cpu_count() or 1
    if workers is None:
        workers = cores
    if workers < 1:
        raise ScenarioError(f"--workers {workers}: expected a positive number of processes")
    if workers > cores:
        if not oversubscribe:
            log.warning("--workers %d: capped at the %d cores of this machine "
                        "(--oversubscribe starts them all)", workers, cores)
            workers = cores
        else:
            why = memory_problem(workers * WORKER_BYTES, f"--workers {workers} --oversubscribe"
                                 f" (about {WORKER_BYTES / 2**30:g} GiB per process)",
                                 "use fewer workers")
            if why:
                raise ScenarioError(why)
    return max(1, min(workers, n_tasks))


def run_campaign(campaign: LoadedCampaign, out: Path, runs: int | None = None,
                 workers: int | None = None, scheduler: str | None = None,
                 resume: bool = False, figures: bool = True,
                 oversubscribe: bool = False) -> dict:
    """Run the campaign's pending tasks into ``out`` and collect them (see the module)."""
    out = Path(out)
    campaign.tasks(runs, out)  # refuses a bad --runs before anything is written
    if scheduler:
        check_scheduler(scheduler)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UwcosimError(f"{out}: cannot create the campaign directory ({exc.strerror})"
                           ) from None
    results = out / "results"
    tasks = campaign.tasks(runs, out)
    if workers is not None and workers < 1:
        raise ScenarioError(f"--workers {workers}: expected a positive number of processes")
    if not scheduler:
        workers = worker_count(workers, len(tasks), oversubscribe)
    if resume or not any(results.glob("*.json")):
        check_manifest(campaign, out, resume)
    results.mkdir(exist_ok=True)
    todo = pending_tasks(tasks, results, resume, campaign.scenario_hashes)
    shutil.copyfile(campaign.path, out / "campaign.toml")
    start = time.perf_counter()
    failures = 0
    interrupted = None
    try:
        failures = run_tasks(todo, results, workers, scheduler, total=len(tasks))
        run_bounds(campaign, out, len(tasks) // len(campaign.spec.variants))  # [evaluation]
    except (KeyboardInterrupt, RunInterrupted) as exc:
        interrupted = exc
    finally:
        # whatever happened, what finished is aggregated
        summary = collect(out, figures=figures, total=len(tasks) if interrupted else None)
    if interrupted is not None:
        signum = getattr(interrupted, "signum", None)
        code = 128 + signum if signum else getattr(interrupted, "exit_code", 130)
        by = f" by {signal_name(code - 128)}" if code > 128 else ""
        err = RunInterrupted(f"campaign interrupted{by}: {summary['runs']} of {len(tasks)} "
                             f"runs finished in {out} (report.md marked partial; --resume "
                             f"continues)")
        err.exit_code = code
        raise err
    summary["wall_time_s"] = time.perf_counter() - start
    summary["failed_runs_this_session"] = failures
    summary["workers"] = workers if not scheduler else scheduler
    return summary


def collect(campaign_dir: Path, figures: bool = True, out: Path | None = None,
            total: int | None = None) -> dict:
    """Aggregate ``campaign_dir/results`` into ``runs.parquet``, ``table.md``/``.csv`` and
    figures, written to ``out`` (default: the campaign directory). ``total``: the campaign was
    interrupted with this many runs planned (report.md says partial)."""
    rows = run_rows(read_records(Path(campaign_dir) / "results"))
    out = Path(campaign_dir) if out is None else Path(out)
    n_runs = len({(r["variant"], r["run"]) for r in rows})
    partial = ""
    if total is not None:
        partial = (f"**Partial results: the campaign was interrupted** ({n_runs} of {total} "
                   f"runs finished; `uwcosim campaign SPEC --out {campaign_dir} --resume` "
                   f"continues it).\n\n")
    if not rows:
        if partial:
            (out / "report.md").write_text(f"# Campaign results (partial)\n\n{partial}")
        return {"runs": 0, "table": []}
    write_runs_parquet(rows, out / "runs.parquet")
    agg = aggregate(rows)
    md, _ = write_tables(agg, out)
    figs = []
    if figures:
        figs = rmse_per_run(rows, out) + [summary_chart(rows, out)]
    title = "# Campaign results (partial)" if partial else "# Campaign results"
    failed = sorted({(r["variant"], r["run"], r["error"]) for r in rows if r["status"] != "ok"})
    nan = sorted({(r["variant"], r["run"], r["estimator"]) for r in rows
                  if r["status"] == "ok" and r["estimator"] and not r["diverged"]
                  and not np.isfinite(r["rmse_position_m"])})
    text = f"{title}\n\n{partial}{problems_text(agg, n_runs, len(failed), len(nan))}" \
        f"{md.read_text()}\n" + bound_section(rows, Path(campaign_dir)) \
        + "".join(f"![{p.stem}]({p.name})\n\n" for p in figs)
    (out / "report.md").write_text(text)
    return {"runs": n_runs, "table": agg,
            "failed": [{"variant": v, "run": i, "error": e} for v, i, e in failed],
            "nan": [{"variant": v, "run": i, "estimator": e} for v, i, e in nan]}


def problems_text(agg: list[dict], n_runs: int, n_failed: int, n_nan: int) -> str:
    """The report's first words when runs failed or gave a NaN RMSE (nothing otherwise)."""
    if not n_failed and not n_nan:
        return ""
    per = sorted({(r["variant"], r["failed"]) for r in agg if r["failed"]})
    nan = [f"{r['variant']}/{r['estimator']}: {r['nan']}" for r in agg if r["nan"]]
    parts = []
    if n_failed:
        parts.append(f"{n_failed} of {n_runs} runs failed (" +
                     ", ".join(f"{v}: {k}" for v, k in per) + "; see runs.parquet, column "
                     "error); they are not in the means")
    if n_nan:
        parts.append(f"{n_nan} finished runs have a NaN position RMSE (" + ", ".join(nan) +
                     "); not in the means")
    return "**" + "; ".join(parts) + ".**\n\n"
