"""The report of a plain co-simulation run (no estimators): status, timing, the signal figures.

Reads only the run directory's files (``log.parquet``, ``summary.json`` when there is one).
"""

from __future__ import annotations

import json
from pathlib import Path

from uwcosim.plots.signals import signal_figures
from uwcosim.runlog import read_log


def write_signal_report(run_dir: str | Path, out: str | Path | None = None,
                        summary: dict | None = None) -> Path:
    """``report.md`` of a run without estimators: status, timing and the signal figures, into
    ``out`` (default: the run directory). ``summary``: default the run's ``summary.json``."""
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir
    out.mkdir(parents=True, exist_ok=True)
    log_path = run_dir / "log.parquet"
    figures, text = signal_figures(log_path, out)
    _, meta = read_log(log_path)
    summary_path = run_dir / "summary.json"
    s = summary if summary is not None else \
        json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    seed = s.get("seed", meta.get("seed", "N"))
    lines = [
        f"# Run report: {s.get('scenario', run_dir.name)}\n",
        f"Seed {seed}, {s.get('steps', '?')} steps of {s.get('step_s', float('nan')):g} s, "
        f"status **{s.get('status', '?')}**. Reproduce with "
        f"`uwcosim run {meta.get('scenario_path', 'SCENARIO')} --seed {seed}"
        f"{''.join(' --set ' + o for o in meta.get('overrides', []))}`.\n",
    ]
    stop = s.get("termination")
    if stop:
        lines.append(f"FMU `{stop['fmu']}` requested termination at t = {stop['time_s']:g} s"
                     f"{': ' + stop['reason'] if stop.get('reason') else ''}.\n")
    if s.get("error"):
        lines.append(f"Error: {s['error']}\n")
    timing = s.get("timing", {})
    per_fmu = [(k[4:-2], v) for k, v in timing.items() if k.startswith("fmu.")]
    if per_fmu:
        lines.append("| FMU | wall time (s) |\n|---|---|\n"
                     + "".join(f"| {n} | {v:.4f} |\n" for n, v in per_fmu))
    if "master_s" in timing:
        lines.append(f"Master (outside the FMUs): {timing['master_s']:.4f} s.\n")
    lines += [f"![{p.stem}]({p.name})\n" for p in figures]
    if text:
        lines.append("String signals (in the log, not drawn): "
                     + ", ".join(f"`{n}`" for n in text) + "\n")
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
