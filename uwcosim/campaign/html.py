"""The self-contained HTML report of a campaign (``report.html``), with Plotly.

Its table, the failed runs, the position RMSE of every run per variant (markers, no line
joining independent runs), box plots of the RMSE
over the runs and the PNG figures, from the campaign directory's files, with the blocks of
:mod:`uwcosim.plots.html`.
"""

from __future__ import annotations

from pathlib import Path

from uwcosim.campaign.aggregate import read_records, run_rows
from uwcosim.plots.html import esc, num, page, plot, png, table
from uwcosim.plots.labels import display_name


def _campaign_plots(rows: list[dict]) -> list[str]:
    import plotly.graph_objects as go

    ok = [r for r in rows if r["estimator"] and r["status"] == "ok" and not r["diverged"]]
    variants = sorted({r["variant"] for r in rows if r["estimator"]})
    out = []
    for i, variant in enumerate(variants):
        fig = go.Figure()
        for k, est in enumerate(sorted({r["estimator"] for r in ok
                                        if r["variant"] == variant})):
            rs = sorted((r for r in ok if r["variant"] == variant and r["estimator"] == est),
                        key=lambda r: r["run"])
            fig.add_trace(go.Scatter(x=[r["run"] for r in rs],
                                     y=[r["rmse_position_m"] for r in rs],
                                     mode="markers", name=display_name(est),
                                     marker={"size": 9, "symbol": k}))
        fig.update_layout(title=f"Position RMSE of each run (independent runs): {variant}",
                          xaxis_title="run", xaxis_tickformat="d", xaxis_dtick=1,
                          yaxis_title="position RMSE (m)", yaxis_type="log")
        out.append(plot(fig, f"plot-per-run-{i}", 420))
    fig = go.Figure()
    for label in sorted({(r["variant"], r["estimator"]) for r in ok}):
        fig.add_trace(go.Box(y=[r["rmse_position_m"] for r in ok
                                if (r["variant"], r["estimator"]) == label],
                             name=f"{display_name(label[1])} ({label[0]})", boxmean=True))
    fig.update_layout(title="Position RMSE over the runs (box: quartiles, dashed: mean)",
                      yaxis_title="position RMSE per run (m)", yaxis_type="log",
                      showlegend=False)
    out.append(plot(fig, "plot-box", 480))
    return out


def campaign_html(campaign_dir: Path, summary: dict, path: Path) -> Path:
    """Write the self-contained HTML report of a campaign directory to ``path``."""
    rows = run_rows(read_records(Path(campaign_dir) / "results"))
    title = f"Campaign report: {Path(campaign_dir).resolve().name}"
    runs = len({(r["variant"], r["run"]) for r in rows})
    body = [f"<h1>{esc(title)}</h1>",
            f"<p>{runs} runs; mean over finished, non-diverged runs of each run's RMSE "
            "(seed 000 eq. 56).</p>", "<h2>Table</h2>",
            table(["variant", "estimator", "runs", "pos. RMSE (m)", "± std", "vel. RMSE (m/s)",
                    "ANEES", "filter time per run (s)", "diverged"],
                   [[r["variant"], r["estimator"], r["runs"], num(r["rmse_position_m"], ".2f"),
                     num(r["rmse_position_std_m"], ".2f"), num(r["rmse_velocity_mps"], ".4f"),
                     num(r["anees"], ".2f"), num(r["total_time_s"], ".2f"), r["diverged"]]
                    for r in summary.get("table", [])])]
    if summary.get("failed"):
        body += ["<h2>Failed runs</h2>",
                 table(["variant", "run", "error"],
                        [[f["variant"], f["run"], f["error"]] for f in summary["failed"]])]
    body += ["<h2>Interactive plots</h2>", *_campaign_plots(rows)]
    figs = sorted(path.parent.glob("rmse_*.png"))
    if figs:
        body += ["<h2>Figures</h2>", *(png(p) for p in figs)]
    spec = Path(campaign_dir) / "campaign.toml"
    if spec.is_file():
        body.append("<details open><summary>Campaign spec</summary>"
                    f"<pre>{esc(spec.read_text(encoding='utf-8'))}</pre></details>")
    path.write_text(page(title, body), encoding="utf-8")
    return path
