"""Figures of one run and its ``report.md``.

- ``trajectory.png``: truth and estimates over the bathymetry map;
- ``position_error.png``: position error of each estimator against time with its 3-sigma bound;
- ``position_error_norm.png``: the error norm per step (seed 001 eq. 43, "RMSE(k)");
- ``report.md``: the result table and the figures, with the command that reproduces them.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from uwcosim.evaluation.metrics import position_velocity_indices  # noqa: E402
from uwcosim.runlog import read_log  # noqa: E402


def trajectory_figure(cols, truth_names, est_names, states, bathy, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(7, 6), dpi=110)
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    if bathy is not None:
        pad = 1500.0
        xmin, xmax, ymin, ymax = bathy.extent
        x0, x1 = max(xmin, np.nanmin(tx) - pad), min(xmax, np.nanmax(tx) + pad)
        y0, y1 = max(ymin, np.nanmin(ty) - pad), min(ymax, np.nanmax(ty) + pad)
        gx = np.linspace(x0, x1, 200)
        gy = np.linspace(y0, y1, 200)
        GX, GY = np.meshgrid(gx, gy)
        D = bathy.depth(GX.ravel(), GY.ravel()).reshape(GX.shape)
        im = ax.contourf(GX, GY, D, levels=30, cmap="viridis_r")
        fig.colorbar(im, ax=ax, label="depth (m)")
    ax.plot(tx, ty, "k-", lw=2, label="truth")
    for name in est_names:
        ax.plot(cols[f"est.{name}.{states[ix]}"], cols[f"est.{name}.{states[iy]}"], lw=1,
                label=name)
    ax.plot(tx[0], ty[0], "ko")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Trajectory and estimates")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def error_figure(cols, truth_names, est_names, states, path: Path) -> Path:
    t = cols["time"]
    fig, axes = plt.subplots(len(est_names), 1, figsize=(8, 2.2 * len(est_names) + 0.6),
                             dpi=110, sharex=True, squeeze=False)
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    for ax, name in zip(axes[:, 0], est_names):
        ex = cols[f"est.{name}.{states[ix]}"] - tx
        ey = cols[f"est.{name}.{states[iy]}"] - ty
        sx = 3 * np.sqrt(cols[f"est.{name}.var.{states[ix]}"])
        sy = 3 * np.sqrt(cols[f"est.{name}.var.{states[iy]}"])
        ax.plot(t, ex, lw=0.8, label="error x")
        ax.plot(t, ey, lw=0.8, label="error y")
        ax.fill_between(t, -sx, sx, color="C0", alpha=0.15, label="±3σ x")
        ax.fill_between(t, -sy, sy, color="C1", alpha=0.15, label="±3σ y")
        ax.set_ylabel(f"{name} (m)")
        lim = np.nanpercentile(np.abs(np.concatenate([ex, ey, sx, sy])), 99) * 1.2
        if np.isfinite(lim) and lim > 0:
            ax.set_ylim(-lim, lim)
        ax.legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Position error with 3-sigma bounds")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def error_norm_figure(cols, truth_names, est_names, states, path: Path) -> Path:
    """RMSE(k) of seed 001 eq. (43): the position error norm at each step, per estimator."""
    t = cols["time"]
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=110)
    for name in est_names:
        e = np.hypot(cols[f"est.{name}.{states[ix]}"] - tx, cols[f"est.{name}.{states[iy]}"] - ty)
        ax.plot(t, e, lw=0.8, label=name)
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position error (m)")
    ax.set_title("RMSE(k): position error norm per step")
    ax.legend(fontsize=8, ncol=min(4, len(est_names)))
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def results_table(summary: dict) -> str:
    head = ("| estimator | pos. RMSE (m) | x RMSE (m) | y RMSE (m) | vel. RMSE (m/s) | ANEES "
            "| time/step (ms) | diverged |\n|---|---|---|---|---|---|---|---|\n")
    rows = []
    for name, m in summary["estimators"].items():
        rows.append(
            f"| {name} | {m['rmse_position_m']:.2f} | {m['rmse_x_m']:.2f} | {m['rmse_y_m']:.2f} "
            f"| {m.get('rmse_velocity_mps', float('nan')):.4f} | {m['anees']:.2f} "
            f"| {1e3 * m['time_per_step_s']:.3f} | {'yes' if m['diverged'] else 'no'} |"
        )
    return head + "\n".join(rows) + "\n"


def write_report(result, bathy, model, truth: list[str], names: list[str],
                 extra_figures: list[Path] = ()) -> Path:
    out = Path(result.out_dir)
    cols, meta = read_log(result.log_path)
    states = list(model.state_names)
    trajectory_figure(cols, truth, names, states, bathy, out / "trajectory.png")
    error_figure(cols, truth, names, states, out / "position_error.png")
    error_norm_figure(cols, truth, names, states, out / "position_error_norm.png")
    s = result.summary
    text = (
        f"# Run report: {s['scenario']}\n\n"
        f"Seed {s['seed']}, {s['steps']} steps of {s['step_s']:g} s. Reproduce with "
        f"`uwcosim run {meta.get('scenario_path', 'SCENARIO')} --seed {s['seed']}`"
        f"{''.join(' --set ' + o for o in meta.get('overrides', []))}.\n\n"
        f"{results_table(s)}\n"
        f"Master overhead per step: {1e6 * s['timing']['master_overhead_per_step_s']:.1f} µs; "
        f"FMUs per step: {1e6 * s['timing']['fmus_per_step_s']:.1f} µs.\n\n"
        "![trajectory](trajectory.png)\n\n![position error](position_error.png)\n\n"
        "![position error norm](position_error_norm.png)\n"
        + "".join(f"\n![{p.stem}]({p.name})\n" for p in extra_figures)
    )
    path = out / "report.md"
    path.write_text(text)
    return path

