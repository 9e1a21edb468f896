"""The self-contained HTML report of one run (``report.html``), with Plotly.

The scenario text, seed, package versions and FMU hashes from the log metadata, the reproduce
command, the result table, interactive plots (the trajectory over the bathymetry with equal
scales, each state against time, the position errors with their 3-sigma bands; every axis
titled with its unit, the filters by their display names), and the PNG figures; built from
the run directory's files (:class:`~uwcosim.reports.runfiles.RunFiles`) with the blocks of
:mod:`uwcosim.plots.html`.
The table and the PNG figures use every step; the interactive plots are thinned.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from uwcosim.models.states import position_velocity_indices
from uwcosim.plots.html import band, esc, num, page, plot, png, table, thin
from uwcosim.plots.labels import display_name, state_unit, with_unit
from uwcosim.plots.track import map_window, position
from uwcosim.reports.reproduce import reproduce_command, user_code_lines
from uwcosim.reports.runfiles import RunFiles
from uwcosim.runlog import columns


def _run_plots(run) -> list[str]:
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    cols, states, truth, names = run.cols, run.states, run.truth, run.estimators
    idx = thin(cols["time"].size)
    t = cols["time"][idx]
    pos = position_velocity_indices(states)[0]
    out = []
    colors = [f"hsl({(40 + 360 * i / max(len(names), 1)) % 360:.0f},65%,45%)"
              for i in range(len(names))]
    if pos:
        out.append(plot(_trajectory(go, run, idx, colors), "plot-trajectory", 650))
    fig = make_subplots(rows=len(states), cols=1, shared_xaxes=True, vertical_spacing=0.04,
                        subplot_titles=[f"{s}: truth and estimates" for s in states])
    for r, s in enumerate(states, start=1):
        fig.update_yaxes(title_text=with_unit(s, state_unit(s, states)), row=r, col=1)
    for r, (s, tr) in enumerate(zip(states, truth), start=1):
        fig.add_trace(go.Scatter(x=t, y=cols[tr][idx], name="truth", legendgroup="truth",
                                 showlegend=r == 1, line={"color": "black", "width": 2.5}),
                      row=r, col=1)
        for n, c in zip(names, colors):
            fig.add_trace(go.Scatter(x=t, y=cols[columns.estimate(n, s)][idx],
                                     name=display_name(n),
                                     legendgroup=n, showlegend=r == 1,
                                     line={"color": c, "width": 1.2}),
                          row=r, col=1)
    fig.update_xaxes(title_text="time (s)", row=len(states), col=1)
    out.append(plot(fig, "plot-states", 260 * len(states) + 80))
    if pos:
        ix, iy = pos
        fig = make_subplots(rows=len(names), cols=1, shared_xaxes=True, shared_yaxes=False,
                            vertical_spacing=min(0.08, 0.3 / len(names)),
                            subplot_titles=[f"{display_name(n)}: position error with ±3σ"
                                            for n in names])
        styles = (("x", ix, "rgba(31,119,180,0.18)", "#1f77b4", "solid"),
                  ("y", iy, "rgba(255,127,14,0.18)", "#ff7f0e", "dash"))
        for r, n in enumerate(names, start=1):
            mags = []
            for axis, i, fill, color, dash in styles:
                sig = 3 * np.sqrt(cols[columns.variance(n, states[i])][idx])
                fig.add_trace(band(go, t, sig, f"±3σ {axis}", fill, f"band-{axis}", r == 1),
                              row=r, col=1)
                err = cols[columns.estimate(n, states[i])][idx] - cols[truth[i]][idx]
                fig.add_trace(go.Scatter(x=t, y=err, name=f"error {axis}",
                                         legendgroup=f"err-{axis}", showlegend=r == 1,
                                         line={"color": color, "width": 1.2, "dash": dash}),
                              row=r, col=1)
                mags.append(np.abs(np.concatenate([err, sig])))
            # each filter on its own scale (the 99th percentile: the start's wide bound and
            # dead reckoning's drift do not flatten the rest; the mouse zooms out)
            m = np.concatenate(mags)
            m = m[np.isfinite(m)]
            lim = 1.15 * float(np.percentile(m, 99)) if m.size else 0.0
            fig.update_yaxes(title_text="error (m)", row=r, col=1,
                             **({"range": [-lim, lim]} if lim > 0 else {}))
        fig.update_xaxes(title_text="time (s)", row=len(names), col=1)
        out.append(plot(fig, "plot-errors", 230 * len(names) + 100))
    return out


#: cells per side of the bathymetry drawn behind the interactive trajectory
MAP_CELLS = 150


def _trajectory(go, run, idx, colors):
    """The interactive trajectory: the bathymetry as a heatmap behind truth and estimates (the
    window of ``trajectory.png``), equal scales on x and y, titled axes."""
    cols, states, truth, names = run.cols, run.states, run.truth, run.estimators
    ix, iy = position_velocity_indices(states)[0]
    x0, x1, y0, y1 = map_window(cols, truth, names, states, run.bathymetry)
    fig = go.Figure()
    if run.bathymetry is not None:
        gx, gy = np.linspace(x0, x1, MAP_CELLS), np.linspace(y0, y1, MAP_CELLS)
        GX, GY = np.meshgrid(gx, gy)
        D = run.bathymetry.depth(GX.ravel(), GY.ravel()).reshape(GX.shape)
        fig.add_trace(go.Heatmap(x=np.round(gx, 1), y=np.round(gy, 1), z=np.round(D, 2),
                                 name="bathymetry", colorscale="Viridis", reversescale=True,
                                 colorbar={"title": {"text": "depth (m)"}, "x": 1.02},
                                 hovertemplate="x %{x} m<br>y %{y} m<br>depth %{z} m"
                                 "<extra></extra>"))
    fig.add_trace(go.Scatter(x=cols[truth[ix]][idx], y=cols[truth[iy]][idx], name="truth",
                             line={"color": "black", "width": 3}))
    for n, c in zip(names, colors):
        ex, ey = position(cols, n, states)
        fig.add_trace(go.Scatter(x=ex[idx], y=ey[idx], name=display_name(n),
                                 line={"color": c, "width": 1.5}))
    fig.add_trace(go.Scatter(x=cols[truth[ix]][:1], y=cols[truth[iy]][:1], name="start",
                             mode="markers", marker={"color": "white", "size": 11,
                                                     "line": {"color": "black", "width": 2}}))
    fig.update_layout(title="Trajectory over the bathymetry: truth and estimates "
                            "(zoom with the mouse)",
                      legend={"orientation": "h", "y": -0.12},
                      xaxis={"title": {"text": "x (m)"}, "range": [x0, x1],
                             "constrain": "domain"},
                      yaxis={"title": {"text": "y (m)"}, "range": [y0, y1],
                             "scaleanchor": "x", "scaleratio": 1, "constrain": "domain"})
    return fig


def _results_rows(summary: dict) -> list[list]:
    rows = []
    for name, m in summary.get("estimators", {}).items():
        rows.append([name, num(m.get("rmse_position_m"), ".2f"), num(m.get("rmse_x_m"), ".2f"),
                     num(m.get("rmse_y_m"), ".2f"), num(m.get("rmse_velocity_mps"), ".4f"),
                     num(m.get("anees"), ".2f"),
                     num(1e3 * m["time_per_step_s"] if "time_per_step_s" in m else None, ".3f"),
                     "yes" if m.get("diverged") else "no"])
    return rows


def run_html(run: RunFiles, figures: list[Path], path: Path) -> Path:
    """Write the self-contained HTML report of ``run`` (a :class:`RunFiles`) to ``path``."""
    s, meta = run.summary, run.meta
    title = f"Run report: {s.get('scenario', meta.get('scenario_name', '?'))}"
    body = [f"<h1>{esc(title)}</h1>",
            f"<p>Seed <b>{esc(s.get('seed', meta.get('seed')))}</b>, {esc(s.get('steps'))} "
            f"steps of {esc(s.get('step_s'))} s, status <b>{esc(s.get('status'))}</b>.</p>"]
    if s.get("error"):
        body.append(f"<p>Error: {esc(s['error'])}</p>")
    for note in [*s.get("notes", []), *run.notes]:
        body.append(f"<p>Note: {esc(note)}</p>")
    body += ["<h2>Reproduce</h2>",
             f"<pre>{esc(reproduce_command(s, meta, run.run_dir))}</pre>", "<h2>Results</h2>",
             table(["estimator", "pos. RMSE (m)", "x RMSE (m)", "y RMSE (m)",
                     "vel. RMSE (m/s)", "ANEES", "time/step (ms)", "diverged"],
                    _results_rows(s))]
    if run.has_estimates:
        body += ["<h2>Interactive plots</h2>", *_run_plots(run)]
    if figures:
        body += ["<h2>Figures</h2>", *(png(p) for p in figures)]
    body += ["<h2>Provenance</h2>",
             table(["package", "version"], sorted(meta.get("versions", {}).items())),
             table(["FMU", "sha256"], sorted(meta.get("fmus", {}).items())),
             *([f"<p>User code: {'; '.join(esc(c) for c in user_code_lines(meta))}</p>"]
               if meta.get("user_code") else []),
             f"<p>Scenario sha256 (text and overrides): "
             f"<code>{esc(meta.get('scenario_sha256', '?'))}</code></p>",
             "<p>Overrides: " + (", ".join(f"<code>{esc(o)}</code>"
                                           for o in meta.get("overrides", [])) or "none")
             + "</p>",
             f"<details open><summary>Scenario {esc(meta.get('scenario_path', ''))}</summary>"
             f"<pre>{esc(meta.get('scenario_text', ''))}</pre></details>"]
    if meta.get("variable_maps"):
        body.append("<details><summary>Variable maps of third-party FMUs</summary><pre>"
                    f"{esc(json.dumps(meta['variable_maps'], indent=2))}</pre></details>")
    path.write_text(page(title, body), encoding="utf-8")
    return path
