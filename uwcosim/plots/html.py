"""Self-contained HTML reports (``report.html``) of a run or a campaign, with Plotly.

One file, nothing fetched from the network: Plotly's JavaScript is inlined once in the page
head, the PNG figures are inlined as data URIs, every plot has a fixed element id (the same
run gives the same page). A run's page holds the scenario text, seed, package versions and FMU
hashes from the log metadata, the result table and interactive plots of truth vs estimates and
of the position errors with their 3-sigma bands; a campaign's page holds its table, the RMSE of
every run and box plots of the RMSE over the runs. Long runs are thinned to at most
:data:`MAX_POINTS` points per trace (every k-th step, the last one kept) for the interactive
plots only; the table and the PNG figures use every step.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from uwcosim.report.runfiles import RunFiles

import numpy as np

MAX_POINTS = 2500

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
pre { background: #f5f5f5; padding: 0.7em; overflow-x: auto; font-size: 0.85em; }
img { max-width: 100%; }
details { margin: 0.5em 0; }
.plot { margin: 1em 0; }
"""


def _esc(x) -> str:
    return html.escape(str(x))


def _table(header: list[str], rows: list[list]) -> str:
    head = "".join(f"<th>{_esc(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _num(v, fmt: str) -> str:
    return format(v, fmt) if isinstance(v, int | float) and v == v else "–"


def _page(title: str, body: list[str]) -> str:
    from plotly.offline import get_plotlyjs

    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{_esc(title)}</title><style>{_CSS}</style>"
            f"<script type=\"text/javascript\">{get_plotlyjs()}</script></head><body>"
            + "\n".join(body) + "</body></html>\n")


def _plot(fig, div_id: str, height: int) -> str:
    fig.update_layout(height=height, margin={"l": 60, "r": 20, "t": 50, "b": 40},
                      template="plotly_white")
    return ('<div class="plot">' + fig.to_html(full_html=False, include_plotlyjs=False,
                                                div_id=div_id, default_height=f"{height}px",
                                                config={"responsive": True})
            + "</div>")


def _png(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return (f'<figure><img alt="{_esc(path.stem)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{_esc(path.name)}</figcaption></figure>")


def _thin(n: int) -> np.ndarray:
    stride = max(1, -(-n // MAX_POINTS))
    idx = np.arange(0, n, stride)
    return idx if idx.size == 0 or idx[-1] == n - 1 else np.append(idx, n - 1)


def _band(go, t, s, name: str, color: str, group: str, show: bool):
    ok = np.isfinite(s)
    t, s = t[ok], s[ok]
    return go.Scatter(x=np.concatenate([t, t[::-1]]), y=np.concatenate([s, -s[::-1]]),
                      fill="toself", fillcolor=color, line={"width": 0}, hoverinfo="skip",
                      name=name, legendgroup=group, showlegend=show)


def _run_plots(run) -> list[str]:
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from uwcosim.evaluation.metrics import position_velocity_indices

    cols, states, truth, names = run.cols, run.states, run.truth, run.estimators
    idx = _thin(cols["time"].size)
    t = cols["time"][idx]
    pos = position_velocity_indices(states)[0]
    out = []
    colors = [f"hsl({(40 + 360 * i / max(len(names), 1)) % 360:.0f},65%,45%)"
              for i in range(len(names))]
    if pos:
        ix, iy = pos
        fig = go.Figure()
        fig.add_trace(go.Scatter(x=cols[truth[ix]][idx], y=cols[truth[iy]][idx], name="truth",
                                 line={"color": "black", "width": 3}))
        for n, c in zip(names, colors):
            fig.add_trace(go.Scatter(x=cols[f"est.{n}.{states[ix]}"][idx],
                                     y=cols[f"est.{n}.{states[iy]}"][idx], name=n,
                                     line={"color": c, "width": 1.5}))
        fig.update_layout(title="Trajectory: truth and estimates (zoom with the mouse)",
                          xaxis_title="x (m)", yaxis_title="y (m)",
                          yaxis={"scaleanchor": "x", "scaleratio": 1})
        out.append(_plot(fig, "plot-trajectory", 600))
    fig = make_subplots(rows=len(states), cols=1, shared_xaxes=True, vertical_spacing=0.04,
                        subplot_titles=[f"{s}: truth and estimates" for s in states])
    for r, (s, tr) in enumerate(zip(states, truth), start=1):
        fig.add_trace(go.Scatter(x=t, y=cols[tr][idx], name="truth", legendgroup="truth",
                                 showlegend=r == 1, line={"color": "black", "width": 2.5}),
                      row=r, col=1)
        for n, c in zip(names, colors):
            fig.add_trace(go.Scatter(x=t, y=cols[f"est.{n}.{s}"][idx], name=n, legendgroup=n,
                                     showlegend=r == 1, line={"color": c, "width": 1.2}),
                          row=r, col=1)
    fig.update_xaxes(title_text="time (s)", row=len(states), col=1)
    out.append(_plot(fig, "plot-states", 260 * len(states) + 80))
    if pos:
        ix, iy = pos
        fig = make_subplots(rows=len(names), cols=1, shared_xaxes=True, shared_yaxes=True,
                            vertical_spacing=min(0.08, 0.3 / len(names)),
                            subplot_titles=[f"{n}: position error with ±3σ" for n in names])
        styles = (("x", ix, "rgba(31,119,180,0.18)", "#1f77b4", "solid"),
                  ("y", iy, "rgba(255,127,14,0.18)", "#ff7f0e", "dash"))
        for r, n in enumerate(names, start=1):
            for axis, i, fill, color, dash in styles:
                sig = 3 * np.sqrt(cols[f"est.{n}.var.{states[i]}"][idx])
                fig.add_trace(_band(go, t, sig, f"±3σ {axis}", fill, f"band-{axis}", r == 1),
                              row=r, col=1)
                err = cols[f"est.{n}.{states[i]}"][idx] - cols[truth[i]][idx]
                fig.add_trace(go.Scatter(x=t, y=err, name=f"error {axis}",
                                         legendgroup=f"err-{axis}", showlegend=r == 1,
                                         line={"color": color, "width": 1.2, "dash": dash}),
                              row=r, col=1)
            fig.update_yaxes(title_text="m", row=r, col=1)
        fig.update_xaxes(title_text="time (s)", row=len(names), col=1)
        out.append(_plot(fig, "plot-errors", 230 * len(names) + 100))
    return out


def _results_rows(summary: dict) -> list[list]:
    rows = []
    for name, m in summary.get("estimators", {}).items():
        rows.append([name, _num(m.get("rmse_position_m"), ".2f"), _num(m.get("rmse_x_m"), ".2f"),
                     _num(m.get("rmse_y_m"), ".2f"), _num(m.get("rmse_velocity_mps"), ".4f"),
                     _num(m.get("anees"), ".2f"),
                     _num(1e3 * m["time_per_step_s"] if "time_per_step_s" in m else None, ".3f"),
                     "yes" if m.get("diverged") else "no"])
    return rows


def run_html(run: RunFiles, figures: list[Path], path: Path) -> Path:
    """Write the self-contained HTML report of ``run`` (a :class:`RunFiles`) to ``path``."""
    from uwcosim.report.reproduce import reproduce_command

    s, meta = run.summary, run.meta
    title = f"Run report: {s.get('scenario', meta.get('scenario_name', '?'))}"
    body = [f"<h1>{_esc(title)}</h1>",
            f"<p>Seed <b>{_esc(s.get('seed', meta.get('seed')))}</b>, {_esc(s.get('steps'))} "
            f"steps of {_esc(s.get('step_s'))} s, status <b>{_esc(s.get('status'))}</b>.</p>"]
    if s.get("error"):
        body.append(f"<p>Error: {_esc(s['error'])}</p>")
    for note in [*s.get("notes", []), *run.notes]:
        body.append(f"<p>Note: {_esc(note)}</p>")
    body += ["<h2>Reproduce</h2>",
             f"<pre>{_esc(reproduce_command(s, meta, run.run_dir))}</pre>", "<h2>Results</h2>",
             _table(["estimator", "pos. RMSE (m)", "x RMSE (m)", "y RMSE (m)",
                     "vel. RMSE (m/s)", "ANEES", "time/step (ms)", "diverged"],
                    _results_rows(s))]
    if run.has_estimates:
        body += ["<h2>Interactive plots</h2>", *_run_plots(run)]
    if figures:
        body += ["<h2>Figures</h2>", *(_png(p) for p in figures)]
    body += ["<h2>Provenance</h2>",
             _table(["package", "version"], sorted(meta.get("versions", {}).items())),
             _table(["FMU", "sha256"], sorted(meta.get("fmus", {}).items())),
             f"<p>Scenario sha256 (text and overrides): "
             f"<code>{_esc(meta.get('scenario_sha256', '?'))}</code></p>",
             "<p>Overrides: " + (", ".join(f"<code>{_esc(o)}</code>"
                                           for o in meta.get("overrides", [])) or "none")
             + "</p>",
             f"<details open><summary>Scenario {_esc(meta.get('scenario_path', ''))}</summary>"
             f"<pre>{_esc(meta.get('scenario_text', ''))}</pre></details>"]
    if meta.get("variable_maps"):
        body.append("<details><summary>Variable maps of third-party FMUs</summary><pre>"
                    f"{_esc(json.dumps(meta['variable_maps'], indent=2))}</pre></details>")
    path.write_text(_page(title, body), encoding="utf-8")
    return path


def _campaign_plots(rows: list[dict]) -> list[str]:
    import plotly.graph_objects as go

    ok = [r for r in rows if r["estimator"] and r["status"] == "ok" and not r["diverged"]]
    variants = sorted({r["variant"] for r in rows if r["estimator"]})
    out = []
    for i, variant in enumerate(variants):
        fig = go.Figure()
        for est in sorted({r["estimator"] for r in ok if r["variant"] == variant}):
            rs = sorted((r for r in ok if r["variant"] == variant and r["estimator"] == est),
                        key=lambda r: r["run"])
            fig.add_trace(go.Scatter(x=[r["run"] for r in rs],
                                     y=[r["rmse_position_m"] for r in rs],
                                     mode="lines+markers", name=est))
        fig.update_layout(title=f"Position RMSE of each run: {variant}", xaxis_title="run",
                          xaxis_tickformat="d",
                          yaxis_title="position RMSE (m)", yaxis_type="log")
        out.append(_plot(fig, f"plot-per-run-{i}", 420))
    fig = go.Figure()
    for label in sorted({(r["variant"], r["estimator"]) for r in ok}):
        fig.add_trace(go.Box(y=[r["rmse_position_m"] for r in ok
                                if (r["variant"], r["estimator"]) == label],
                             name=f"{label[1]} ({label[0]})", boxmean=True))
    fig.update_layout(title="Position RMSE over the runs (box: quartiles, dashed: mean)",
                      yaxis_title="position RMSE per run (m)", yaxis_type="log",
                      showlegend=False)
    out.append(_plot(fig, "plot-box", 480))
    return out


def campaign_html(campaign_dir: Path, summary: dict, path: Path) -> Path:
    """Write the self-contained HTML report of a campaign directory to ``path``."""
    from uwcosim.campaign.aggregate import read_records, run_rows

    rows = run_rows(read_records(Path(campaign_dir) / "results"))
    title = f"Campaign report: {Path(campaign_dir).resolve().name}"
    runs = len({(r["variant"], r["run"]) for r in rows})
    body = [f"<h1>{_esc(title)}</h1>",
            f"<p>{runs} runs; mean over finished, non-diverged runs of each run's RMSE "
            "(seed 000 eq. 56).</p>", "<h2>Table</h2>",
            _table(["variant", "estimator", "runs", "pos. RMSE (m)", "± std", "vel. RMSE (m/s)",
                    "ANEES", "filter time per run (s)", "diverged"],
                   [[r["variant"], r["estimator"], r["runs"], _num(r["rmse_position_m"], ".2f"),
                     _num(r["rmse_position_std_m"], ".2f"), _num(r["rmse_velocity_mps"], ".4f"),
                     _num(r["anees"], ".2f"), _num(r["total_time_s"], ".2f"), r["diverged"]]
                    for r in summary.get("table", [])])]
    if summary.get("failed"):
        body += ["<h2>Failed runs</h2>",
                 _table(["variant", "run", "error"],
                        [[f["variant"], f["run"], f["error"]] for f in summary["failed"]])]
    body += ["<h2>Interactive plots</h2>", *_campaign_plots(rows)]
    figs = sorted(path.parent.glob("rmse_*.png"))
    if figs:
        body += ["<h2>Figures</h2>", *(_png(p) for p in figs)]
    spec = Path(campaign_dir) / "campaign.toml"
    if spec.is_file():
        body.append("<details open><summary>Campaign spec</summary>"
                    f"<pre>{_esc(spec.read_text(encoding='utf-8'))}</pre></details>")
    path.write_text(_page(title, body), encoding="utf-8")
    return path
