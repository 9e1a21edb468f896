"""The figures a reviewer reads (issue 22): the properties that can be checked on the figure
objects themselves. Each test draws from synthetic data (no FMU, no run) and keeps the matplotlib
figure the function would close; the PNGs land in ``tmp_path`` to be looked at.

- display names (``Dead reckoning``, ``PFM-PSI``) instead of snake_case, one function for all;
- ``trajectory.png``: a zoom panel beside the map (not over the track), titled axes with units,
  ticks of at least 8 pt, equal aspect, the start marker in the legend;
- ``position_error.png``: "error (m)", the filter in the title, a scale per filter, one plain
  band (no hatch);
- ``position_error_norm.png``: log scale with plain tick labels, the legend outside the axes;
- ``density_t*.png``: a window that holds at least 99 % of every density and zooms on it;
- ``signals.png``: y labels, units (from the log) or a scale per panel, a title;
- regress diff plots: the tolerance tube visible in the difference panel;
- campaign figures: plain log ticks, markers (no line) at integer run numbers.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402
import pytest  # noqa: E402

from uwcosim.plots.labels import display_name  # noqa: E402
from uwcosim.runlog import columns  # noqa: E402

STATES = ["x", "y", "vx", "vy"]
TRUTH = ["vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy"]
NAMES = ["dead_reckoning", "ekf", "ukf", "pf", "pfm_psi", "point_mass"]


@pytest.fixture
def figures(monkeypatch):
    """The figures the functions under test close, kept open to be inspected."""
    kept = []
    real_close = plt.close

    def keep(fig=None):
        kept.append(fig)

    monkeypatch.setattr(plt, "close", keep)
    yield kept
    for f in kept:
        real_close(f)


class _Map:
    """A smooth bathymetry on [0, 20 km]^2 (what the figures use of a map: extent, depth)."""

    extent = (0.0, 20000.0, 0.0, 20000.0)

    def depth(self, x, y):
        return 1000.0 + 30.0 * np.sin(np.asarray(x) / 2000.0) * np.cos(np.asarray(y) / 3000.0)


def _run_columns(n: int = 2000) -> dict[str, np.ndarray]:
    """A track across the map, dead reckoning drifting to 100 m, the others within about 5 m."""
    rng = np.random.default_rng(0)
    t = np.arange(n, dtype=float)
    cols = {"time": t, TRUTH[0]: 2000.0 + 2.0 * t, TRUTH[1]: 9000.0 + 400.0 * np.sin(t / 400.0),
            TRUTH[2]: np.full(n, 2.0), TRUTH[3]: np.cos(t / 400.0)}
    for k, name in enumerate(NAMES):
        drift = 100.0 * t / t[-1] if name == "dead_reckoning" else 0.0
        for s, tr in zip(STATES, TRUTH):
            e = drift + rng.normal(0.0, 2.0 + 0.2 * k, n) if s in ("x", "y") \
                else rng.normal(0.0, 0.01, n)
            cols[columns.estimate(name, s)] = cols[tr] + e
            sd = (40.0 if name == "dead_reckoning" else 3.0) if s in ("x", "y") else 0.05
            cols[columns.variance(name, s)] = np.full(n, sd**2)
    return cols


def _overlap(a, b) -> bool:
    """Whether two display-space boxes overlap."""
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def _tick_texts(fig, axis) -> list[str]:
    fig.canvas.draw()
    return [t.get_text() for t in axis.get_ticklabels(which="both") if t.get_text()]


def test_display_names_one_function_for_all():
    assert display_name("dead_reckoning") == "Dead reckoning"
    assert display_name("pfm_psi") == "PFM-PSI"
    assert display_name("point_mass") == "Point mass"
    assert [display_name(n) for n in ("ekf", "ukf", "ckf", "cukf", "pf", "qivbf", "rbpf")] == \
        ["EKF", "UKF", "CKF", "CUKF", "PF", "QIVBF", "RBPF"]
    assert display_name("pf_1000") == "PF 1000"
    assert display_name("ekf_robust") == "EKF robust"
    assert display_name("pfm_psi_fast") == "PFM-PSI fast"
    assert display_name("MyFilter") == "MyFilter"


def test_trajectory_has_a_zoom_panel_beside_the_map(figures, tmp_path):
    from uwcosim.plots.run_figures import trajectory_figure

    cols = _run_columns()
    trajectory_figure(cols, TRUTH, NAMES, STATES, _Map(), tmp_path / "trajectory.png")
    fig = figures[-1]
    panels = [a for a in fig.axes if a.get_xlabel()]  # the colorbar has no x label
    assert len(panels) == 2
    ax, zoom = panels
    assert zoom.get_title().startswith("Zoom")
    fig.canvas.draw()
    # beside the map, not over it: the zoom does not cover the track
    assert not _overlap(ax.get_window_extent(), zoom.get_window_extent())
    for a in (ax, zoom):
        assert a.get_xlabel() == "x (m)" and a.get_ylabel() == "y (m)"
        assert a.get_aspect() == 1.0
        assert min(t.get_fontsize() for t in a.get_xticklabels() + a.get_yticklabels()) >= 8
    # the zoom is at the scale of the errors, the map at the scale of the track
    assert np.ptp(zoom.get_xlim()) < 0.02 * np.ptp(ax.get_xlim())
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "start" in labels and "truth" in labels
    assert {"Dead reckoning", "EKF", "PFM-PSI", "Point mass"} <= set(labels)
    assert not any("_" in label for label in labels)
    # dead reckoning (100 m off) ends outside the zoom: said in the panel
    assert any("Dead reckoning" in t.get_text() for t in zoom.texts)


def test_trajectory_without_a_map(figures, tmp_path):
    from uwcosim.plots.run_figures import trajectory_figure

    trajectory_figure(_run_columns(), TRUTH, NAMES[1:], STATES, None, tmp_path / "t.png")
    fig = figures[-1]
    ax, zoom = fig.axes
    fig.canvas.draw()
    assert ax.get_aspect() == 1.0 and zoom.get_aspect() == 1.0
    assert not _overlap(ax.get_window_extent(), zoom.get_window_extent())
    assert not zoom.texts  # every estimate ends inside the zoom


def test_position_error_scale_per_filter_and_plain_bands(figures, tmp_path):
    from uwcosim.plots.run_figures import error_figure

    error_figure(_run_columns(), TRUTH, NAMES, STATES, tmp_path / "position_error.png")
    fig = figures[-1]
    rows = np.array(fig.axes).reshape(len(NAMES), 2)
    for name, row in zip(NAMES, rows):
        assert row[0].get_ylabel() == "error (m)"
        assert all(a.get_title(loc="left").startswith(display_name(name) + ":")
                   for a in row)
        for a in row:  # one plain band, no hatch
            assert all(not c.get_hatch() for c in a.collections)
    lims = {name: row[0].get_ylim()[1] for name, row in zip(NAMES, rows)}
    assert lims["dead_reckoning"] > 5 * lims["ekf"]  # the drift does not flatten the rest
    assert lims["ekf"] < 20.0


def test_error_norm_log_scale_legend_outside(figures, tmp_path):
    from uwcosim.plots.run_figures import error_norm_figure

    error_norm_figure(_run_columns(), TRUTH, NAMES, STATES, tmp_path / "norm.png")
    fig = figures[-1]
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    texts = _tick_texts(fig, ax.yaxis)
    assert texts and not any("times" in s or "^" in s for s in texts)
    assert not ax.get_legend()
    leg = fig.legends[0]
    assert not _overlap(leg.get_window_extent(), ax.get_window_extent())
    assert [t.get_text() for t in leg.get_texts()] == [display_name(n) for n in NAMES]


def _densities_file(path: Path) -> Path:
    """Two snapshots on a 20 km grid of 50 m cells: a tight Gaussian and a banana-shaped one."""
    gx = np.arange(0.0, 20000.0, 50.0)
    gy = np.arange(0.0, 20000.0, 50.0)
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    tight = np.exp(-0.5 * (((X - 5000.0) / 15.0) ** 2 + ((Y - 12000.0) / 25.0) ** 2))
    bend = np.exp(-0.5 * (((X - 5100.0 - 2e-3 * (Y - 12000.0) ** 2) / 40.0) ** 2
                          + ((Y - 12000.0) / 150.0) ** 2))
    data = {"states": np.array(["x", "y"])}
    for i, (t, dens) in enumerate([(10.0, {"pfm_psi": bend, "point_mass": bend * 0.9}),
                                   (100.0, {"pfm_psi": tight, "point_mass": tight})]):
        data.update({f"{i}|t": np.array(t), f"{i}|truth": np.array([5000.0, 12000.0]),
                     f"{i}|x": gx, f"{i}|y": gy})
        for name, v in dens.items():
            v = v / (v.sum() * 50.0 * 50.0)
            data[f"{i}|{name}|values"] = v
            data[f"{i}|{name}|mean"] = np.array([(X * v).sum() / v.sum(),
                                                (Y * v).sum() / v.sum()])
    np.savez(path, **data)
    return path


def test_density_window_holds_the_mass_and_zooms(figures, tmp_path):
    from uwcosim.plots.density_figures import density_window, draw_densities, read_densities

    path = _densities_file(tmp_path / "densities.npz")
    _, snaps = read_densities(path)
    for snap in snaps:
        gx, gy = snap["axes"]
        vals = [v for v, _ in snap["densities"].values()]
        x0, x1, y0, y1 = density_window(gx, gy, vals, [snap["truth"]])
        inside = np.ix_((gx >= x0) & (gx <= x1), (gy >= y0) & (gy <= y1))
        for v in vals:
            assert v[inside].sum() >= 0.99 * v.sum()
        assert (x1 - x0) * (y1 - y0) < 0.01 * np.ptp(gx) * np.ptp(gy)  # not the whole grid
        assert x0 <= snap["truth"][0] <= x1 and y0 <= snap["truth"][1] <= y1
    pngs = draw_densities(path, tmp_path)
    assert [p.name for p in pngs] == ["density_t10.png", "density_t100.png"]
    fig = figures[-1]  # t = 100 s: the tight posterior fills a good part of the panel
    ax = fig.axes[0]
    assert ax.get_title() == "PFM-PSI" and ax.get_aspect() == 1.0
    assert np.ptp(ax.get_xlim()) < 500.0


def _log(path: Path, units: dict[str, str]) -> Path:
    t = np.arange(100, dtype=float)
    data = {"time": t, "vehicle.x": 2000.0 + 10 * t, "vehicle.y": 18000.0 + t,
            "vehicle.vx": np.full(100, 0.5), "vehicle.psi_out": np.full(100, 0.3),
            "controls.psi": np.full(100, 0.3)}
    fields = [pa.field(n, pa.float64(), metadata={"unit": units[n]} if n in units else None)
              for n in data]
    table = pa.Table.from_pydict(data, schema=pa.schema(fields))
    pq.write_table(table, path)
    return path


def test_signals_titled_labelled_positions_apart_from_velocities(figures, tmp_path):
    from uwcosim.plots.signals import signal_figures

    signal_figures(_log(tmp_path / "log.parquet", {}), tmp_path)
    fig = figures[-1]
    assert fig.get_suptitle().startswith("Logged signals of")
    lines = {ax.get_title(loc="left"): [ln.get_label() for ln in ax.get_lines()]
             for ax in fig.axes}
    pos = [k for k, v in lines.items() if "x" in v]
    assert len(pos) == 1 and "y" in lines[pos[0]] and "vx" not in lines[pos[0]]
    assert all(ax.get_ylabel() for ax in fig.axes)
    assert fig.axes[-1].get_xlabel() == "time (s)"
    # with units in the log (Parquet field metadata "unit"): a panel per unit, labelled with it
    figures.clear()
    signal_figures(_log(tmp_path / "log_u.parquet", {"vehicle.x": "m", "vehicle.y": "m",
                                                     "vehicle.vx": "m/s",
                                                     "vehicle.psi_out": "rad"}), tmp_path)
    labels = sorted(ax.get_ylabel() for ax in figures[-1].axes)
    assert "value (m)" in labels and "value (m/s)" in labels and "value (rad)" in labels


def test_regress_diff_plot_shows_the_tube(figures, tmp_path):
    from uwcosim.regress.compare import compare_signal
    from uwcosim.regress.plots import diff_plot

    t = np.linspace(0.0, 100.0, 1001)
    ref = 1e4 * (1.0 + t / 100.0)  # a position of 1e4 m: the tube is sub-millimetre
    run = ref + np.where(t > 60.0, 5e-2, 0.0)
    res, arrays = compare_signal("vehicle.x", t, ref, t, run, 1e-7, 1e-9, 0.0)
    assert not res.ok
    diff_plot(res, arrays, tmp_path)
    fig = figures[-1]
    axd = fig.axes[1]
    tube = [c for c in axd.collections if c.get_label() == "tolerance tube"]
    assert tube
    ext = tube[0].get_datalim(axd.transData)  # in data coordinates
    fig.canvas.draw()
    lo, hi = axd.transData.transform([[50.0, ext.y0], [50.0, ext.y1]])[:, 1]
    # visible: at least 5 % of the panel's height (the difference is 25 tolerances)
    assert (hi - lo) / axd.get_window_extent().height > 0.05


def _campaign_rows() -> list[dict]:
    rng = np.random.default_rng(1)
    return [{"variant": v, "estimator": e, "run": r, "status": "ok", "diverged": False,
             "rmse_position_m": float(rng.uniform(40.0, 90.0)),
             "rmse_velocity_mps": float(rng.uniform(0.01, 0.03))}
            for v in ("a",) for e in ("ekf", "dead_reckoning") for r in range(2)]


def test_campaign_figures_plain_ticks_and_markers(figures, tmp_path):
    from uwcosim.plots.campaign_figures import rmse_per_run, summary_chart

    rows = _campaign_rows()
    summary_chart(rows, tmp_path)
    fig = figures[-1]
    texts = _tick_texts(fig, fig.axes[0].yaxis)
    assert texts and not any("times" in s or "^" in s for s in texts)
    assert any(s in ("50", "60", "70", "80") for s in texts)
    rmse_per_run(rows, tmp_path)
    fig = figures[-1]
    for ax in fig.axes:
        assert all(ln.get_linestyle() == "None" and ln.get_marker() not in (None, "None")
                   for ln in ax.get_lines())
    ticks = fig.axes[1].get_xticks()
    shown = [v for v in ticks if fig.axes[1].get_xlim()[0] <= v <= fig.axes[1].get_xlim()[1]]
    assert shown and all(float(v).is_integer() for v in shown)
