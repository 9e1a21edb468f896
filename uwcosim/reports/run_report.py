"""The report stage of one run: figures and ``report.md`` from the run directory's files.

``uwcosim run`` calls :func:`report_run` at the end of a run (a run without estimators gets the
report of its logged signals, :func:`uwcosim.reports.signal_report.write_signal_report`);
``uwcosim report RUN`` calls it on any existing run directory (also one interrupted, or written
by an older version whose log carries the metadata). Nothing but the files of the run
directory is read.
"""

from __future__ import annotations

from pathlib import Path

from uwcosim.models.geo import LocalFrame
from uwcosim.models.states import position_velocity_indices
from uwcosim.plots.density_figures import draw_densities
from uwcosim.plots.run_figures import error_figure, error_norm_figure, trajectory_figure
from uwcosim.reports.html import run_html
from uwcosim.reports.reproduce import reproduce_command, user_code_lines
from uwcosim.reports.runfiles import RunFiles, load_run
from uwcosim.reports.signal_report import write_signal_report
from uwcosim.reports.table import results_table


def _fmt_us(timing: dict, key: str) -> str:
    v = timing.get(key)
    return f"{1e6 * v:.1f} µs" if isinstance(v, int | float) else "unknown"


def write_figures(run: RunFiles, out: Path) -> list[Path]:
    """``trajectory.png``, ``position_error.png``, ``position_error_norm.png`` and the density
    snapshots (``density_t*.png``, from ``densities.npz``) of ``run`` into ``out``."""
    paths: list[Path] = []
    rows = len(run.cols.get("time", ()))  # a log with no rows (ended before its first step)
    if rows and run.has_estimates and position_velocity_indices(run.states)[0]:
        args = (run.cols, run.truth, run.estimators, run.states)
        geo = run.meta.get("geo") or {}
        frame = LocalFrame.from_metadata(geo) if geo.get("trajectory_axes") == "latlon" \
            else None
        paths.append(trajectory_figure(*args, run.bathymetry, out / "trajectory.png",
                                       frame=frame))
        paths.append(error_figure(*args, out / "position_error.png"))
        paths.append(error_norm_figure(*args, out / "position_error_norm.png"))
    if run.density_file is not None:
        paths += draw_densities(run.density_file, out)
    return paths


def markdown_report(run: RunFiles, figures: list[Path]) -> str:
    """The text of ``report.md``: header, reproduce command, table, timing, figures."""
    s = run.summary
    status = s.get("status", "unknown")
    lines = [f"# Run report: {s.get('scenario', run.meta.get('scenario_name', '?'))}", ""]
    step = s.get("step_s")
    lines.append(f"Seed {s.get('seed')}, {s.get('steps')} steps of "
                 f"{step:g} s, status {status}." if isinstance(step, int | float)
                 else f"Seed {s.get('seed')}, status {status}.")
    rp = s.get("replay")
    if rp:
        lines.append(f"Replay of `{rp['file']}` (sha256 {rp['sha256'][:12]}): {rp['rows']} rows "
                     f"(of {rp['rows_in_file']}), steps of {rp['dt_min_s']:g} to "
                     f"{rp['dt_max_s']:g} s (median {rp['dt_median_s']:g} s).")
    geo = run.meta.get("geo")
    if geo:
        lines.append(f"Georeferenced: local frame `{geo['crs']}`.")
    if s.get("error"):
        lines.append(f"Error: {s['error']}")
    if s.get("notes"):
        lines += ["", *(f"Note: {n}" for n in s["notes"])]
    lines += ["", "Reproduce (the same log, byte for byte):", "", "```sh",
              reproduce_command(s, run.meta, run.run_dir), "```", ""]
    code = user_code_lines(run.meta)
    if code:  # the same log needs the same code: the files' hashes say which
        lines += ["User code of this run:", "", *(f"- {c}" for c in code), ""]
    if s.get("estimators"):
        lines.append(results_table(s))
    timing = s.get("timing", {})
    if timing:
        lines.append(("Replay overhead per step: " if rp else "Master overhead per step: ")
                     + f"{_fmt_us(timing, 'master_overhead_per_step_s')}; FMUs per step: "
                     f"{_fmt_us(timing, 'fmus_per_step_s')}.\n")
    lines += [f"![{p.stem.replace('_', ' ')}]({p.name})\n" for p in figures]
    if run.notes:
        lines += ["", *(f"- {n}" for n in run.notes)]
    return "\n".join(lines) + "\n"


def report_run(run_dir: str | Path, out: str | Path | None = None, html: bool = False,
               summary: dict | None = None) -> Path:
    """Figures and ``report.md`` (and ``report.html`` with ``html``) of a run directory into
    ``out`` (default: the run directory). Returns the report's path. ``summary``: the run's
    summary (default: its ``summary.json``)."""
    run = load_run(run_dir, summary)
    out = Path(out) if out is not None else run.run_dir
    if not run.estimators and not html:  # a plain co-simulation run: its signals
        return write_signal_report(run.run_dir, out, run.summary)
    out.mkdir(parents=True, exist_ok=True)
    figures = write_figures(run, out)
    path = out / "report.md"
    path.write_text(markdown_report(run, figures), encoding="utf-8")
    if html:
        path = run_html(run, figures, out / "report.html")
    return path
