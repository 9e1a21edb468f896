"""Figures of one run and its ``report.md``.

- ``trajectory.png``: truth and estimates over the bathymetry map and a panel zoomed on the end
  of the run, axes in metres or (a georeferenced run, ``[output] trajectory_axes = "latlon"``)
  in degrees of longitude and latitude;
- ``position_error.png``: position error of each estimator against time with its 3-sigma
  bound, each estimator on its own scale;
- ``position_error_norm.png``: the position error norm per step of the run and its moving RMS
  (with the PCRB under it when the log has one, :mod:`uwcosim.plots.bound`).

Estimators are labelled by :func:`~uwcosim.plots.labels.display_name`.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence

    import numpy as np

    from uwcosim.models.geo import LocalFrame
    from uwcosim.models.terrain import Bathymetry

    #: log columns by name, and lists of names
    Columns = dict[str, np.ndarray]
    Names = Sequence[str]

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from uwcosim.models.states import position_velocity_indices  # noqa: E402
from uwcosim.plots.bound import bound_trace  # noqa: E402
from uwcosim.plots.labels import display_name, plain_log_ticks  # noqa: E402
from uwcosim.plots.track import map_window, position  # noqa: E402
from uwcosim.runlog import columns  # noqa: E402


def _end_window(cols, truth_names, est_names, states):
    """The zoom panel's square window: half-width 3 times the median over the estimators of
    their largest position error over the last 5% of the run (at least 10 m), so that the
    estimates separate from the truth (an outlier, dead reckoning, may leave the window);
    the truth's last point half a half-width ahead of the centre along its last heading, so
    that the window shows the track coming in rather than the empty space past its end."""
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    n = tx.size
    k0 = max(0, n - max(5, n // 20))
    with warnings.catch_warnings():  # a replay's sparse reference: no value at the end
        warnings.simplefilter("ignore", RuntimeWarning)
        worst = [np.nanmax(np.hypot(ex[k0:] - tx[k0:], ey[k0:] - ty[k0:]), initial=np.nan)
                 for ex, ey in (position(cols, e, states) for e in est_names)]
    worst = np.array([w for w in worst if np.isfinite(w)])
    if not np.isfinite(tx[-1]) or not np.isfinite(ty[-1]):
        return None
    half = max(3.0 * float(np.median(worst)) if worst.size else 0.0, 10.0)
    dist = np.hypot(tx - tx[-1], ty - ty[-1])
    back = np.flatnonzero(np.isfinite(dist) & (dist >= half))
    cx, cy = tx[-1], ty[-1]
    if back.size:  # the last point at least a half-width before the end
        k = back[-1]
        cx -= 0.5 * half * (tx[-1] - tx[k]) / dist[k]
        cy -= 0.5 * half * (ty[-1] - ty[k]) / dist[k]
    return cx - half, cx + half, cy - half, cy + half


def _sparse(v: np.ndarray) -> dict:
    """Line style of a series: markers when most of its steps have no value (a replay's
    sparse fixes: a line would not show them)."""
    fin = np.isfinite(v)
    return {"marker": ".", "ms": 4} if fin.any() and fin.mean() < 0.5 else {}


def trajectory_figure(cols: Columns, truth_names: Names, est_names: Names, states: Names,
                      bathy: Bathymetry | None, path: Path,
                      frame: LocalFrame | None = None) -> Path:
    """Track and estimates over the map (left, with the depth colorbar) and a second panel
    that zooms on the end of the run (right; at map scale the estimates hide under the
    truth), its window boxed on the map. The start and end markers are in the legend, below
    the panels. With ``frame``, the axes are longitude and latitude (degrees; the frame's
    inverse projection of everything drawn, the map's contours included; equal ground scales).
    A truth with values at few steps (a replay's fixes) is drawn as points."""
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    x0, x1, y0, y1 = map_window(cols, truth_names, est_names, states, bathy)
    proj = _projection(frame)
    box = _end_window(cols, truth_names, est_names, states)
    # the map panel takes the shape of the view (equal axes): no empty bands around it
    ratio = float(np.clip((y1 - y0) / (x1 - x0), 0.45, 1.3)) if x1 > x0 else 1.0
    fig = plt.figure(figsize=(12.5, 5.6 * ratio + 1.6), dpi=110, layout="constrained")
    ax, zoom = fig.subplots(1, 2, width_ratios=[1.5, 1.0]) if box is not None \
        else (fig.subplots(), None)
    if bathy is not None:
        GX, GY = np.meshgrid(np.linspace(x0, x1, 200), np.linspace(y0, y1, 200))
        D = bathy.depth(GX.ravel(), GY.ravel()).reshape(GX.shape)
        im = ax.contourf(*proj(GX, GY), D, levels=30, cmap="viridis_r")
        fig.colorbar(im, ax=ax, label="depth (m)", shrink=0.9, pad=0.01)
    style = _sparse(tx)
    lines = [ax.plot(*proj(tx, ty), "k-", lw=2, label="reference" if style else "truth",
                     **style)[0]]
    for name in est_names:
        lines += ax.plot(*proj(*position(cols, name, states)), lw=1, label=display_name(name))
    lines += ax.plot(*proj(tx[:1], ty[:1]), "ko", ms=7, mfc="white", mew=2, ls="none",
                     label="start")
    if bathy is not None or frame is not None:
        _view(ax, proj, (x0, x1, y0, y1))
    _axes_style(ax, frame, datalim=bathy is None and frame is None)
    ax.set_title("Trajectory and estimates over the map" if bathy is not None
                 else "Trajectory and estimates")
    if zoom is not None:
        lines += _zoom_panel(zoom, ax, cols, (tx, ty), est_names, states, lines, box, frame)
    fig.legend(handles=lines, loc="outside lower center", ncol=min(len(lines), 5), fontsize=9,
               frameon=False)
    fig.savefig(path)
    plt.close(fig)
    return path


def _projection(frame: LocalFrame | None):
    """``(x, y) -> what the axes show``: metres as they are, or ``(longitude, latitude)``."""
    if frame is None:
        return lambda x, y: (x, y)
    return lambda x, y: frame.to_latlon(x, y)[::-1]


def _view(ax, proj, box) -> None:
    """The axes' limits: the metric window ``box`` ``(x0, x1, y0, y1)`` through ``proj`` (in
    degrees, the bounds of its projected corners)."""
    x0, x1, y0, y1 = box
    u, v = proj(np.array([x0, x1, x0, x1]), np.array([y0, y0, y1, y1]))
    ax.set_xlim(float(np.min(u)), float(np.max(u)))
    ax.set_ylim(float(np.min(v)), float(np.max(v)))


def _axes_style(ax, frame: LocalFrame | None, datalim: bool = False) -> None:
    """Axis titles with units, equal ground scales, ticks of 9 pt, plain degrees."""
    if frame is None:
        ax.set_aspect("equal", adjustable="datalim" if datalim else "box")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    else:
        ax.set_aspect(1.0 / np.cos(np.deg2rad(frame.lat0)), adjustable="box")
        ax.set_xlabel("longitude (°)")
        ax.set_ylabel("latitude (°)")
        ax.ticklabel_format(useOffset=False, style="plain")
        ax.xaxis.set_major_locator(MaxNLocator(5))  # long labels: fewer of them
    ax.tick_params(labelsize=9)


def _inside(xy, box) -> bool:
    """Whether the last finite point of the track ``xy`` is in ``box``."""
    x, y = xy
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    if not ok.size:
        return True
    k = ok[-1]
    return bool(box[0] <= x[k] <= box[1] and box[2] <= y[k] <= box[3])


def _zoom_panel(zoom, ax, cols, truth_xy, est_names, states, lines, box, frame) -> list:
    """The end of the run at the scale of the errors, in its own panel; its window boxed on
    the map ``ax``. Returns the end marker (a legend entry)."""
    proj = _projection(frame)
    tx, ty = truth_xy
    zoom.plot(*proj(tx, ty), "k-", lw=2, **_sparse(tx))
    for line, name in zip(lines[1:], est_names):
        zoom.plot(*proj(*position(cols, name, states)), lw=1.2, color=line.get_color())
    end = zoom.plot(*proj(tx[-1:], ty[-1:]), "ks", ms=7, mfc="white", mew=2, ls="none",
                    label="truth at the end")
    _view(zoom, proj, box)
    off = [display_name(name) for name in est_names  # estimates that end outside the window
           if not _inside(position(cols, name, states), box)]
    if off:
        zoom.text(0.02, 0.02, "ends outside this window: " + ", ".join(off), fontsize=8,
                  transform=zoom.transAxes, va="bottom",
                  bbox={"facecolor": "white", "edgecolor": "0.7", "alpha": 0.9})
    _axes_style(zoom, frame)
    zoom.set_title(f"Zoom on the end of the run (t = {cols['time'][-1]:g} s)")
    zoom.grid(alpha=0.3)
    u0, u1 = zoom.get_xlim()
    v0, v1 = zoom.get_ylim()
    ax.indicate_inset((u0, v0, u1 - u0, v1 - v0), edgecolor="red", lw=1.5, alpha=1.0)
    ax.plot(*proj(tx[-1:], ty[-1:]), "ks", ms=5, mfc="white", mew=1.5)
    return end


def error_figure(cols: Columns, truth_names: Names, est_names: Names, states: Names,
                 path: Path) -> Path:
    """Position error of each estimator (a row, titled with its name) in x (left) and y
    (right), each with its 3-sigma bound as one shaded band; every row on its own scale (the
    99th percentile of its errors and bounds), so that dead reckoning's drift does not flatten
    the others; the two panels of a row share it."""
    t = cols["time"]
    n = len(est_names)
    fig, axes = plt.subplots(n, 2, figsize=(10, 1.9 * n + 1.1), dpi=110, sharex=True,
                             squeeze=False, layout="constrained")
    ix, iy = position_velocity_indices(states)[0]
    handles = []
    for row, name in zip(axes, est_names):
        mags = []
        for ax, i in zip(row, (ix, iy)):
            e = cols[columns.estimate(name, states[i])] - cols[truth_names[i]]
            s3 = 3 * np.sqrt(cols[columns.variance(name, states[i])])
            band = ax.fill_between(t, -s3, s3, color="C0", alpha=0.2, lw=0, label="±3σ bound")
            line, = ax.plot(t, e, "C3-", lw=0.9, label="error", **_sparse(e))
            handles = [line, band]
            ax.axhline(0.0, color="0.5", lw=0.5)
            ax.set_title(f"{display_name(name)}: {states[i]}", fontsize=10, loc="left")
            ax.grid(alpha=0.3)
            mags.append(np.abs(np.concatenate([e, s3])))
        with warnings.catch_warnings():  # a filter with no value at all (all NaN)
            warnings.simplefilter("ignore", RuntimeWarning)
            lim = np.nanpercentile(np.concatenate(mags), 99) * 1.15
        if np.isfinite(lim) and lim > 0:
            for ax in row:
                ax.set_ylim(-lim, lim)
        row[0].set_ylabel("error (m)")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle("Position error with its 3-sigma bound (each filter on its own scale)")
    fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize=9, frameon=False)
    fig.savefig(path)
    plt.close(fig)
    return path


def _moving_rms(e: np.ndarray, w: int) -> np.ndarray:
    """The RMS of ``e`` over a centred window of ``w`` steps (NaN steps left out; NaN where
    the window has no value)."""
    ok = np.isfinite(e)
    k = np.ones(w)
    s2 = np.convolve(np.where(ok, e, 0.0) ** 2, k, mode="same")
    n = np.convolve(ok.astype(float), k, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(s2 / np.maximum(n, 1.0)), np.nan)


#: line styles of the error norms after the ten colours
_DASHES = ("-", "--", ":", "-.")


def error_norm_figure(cols: Columns, truth_names: Names, est_names: Names, states: Names,
                      path: Path) -> Path:
    """The position error norm ``|p_est(t_k) - p(t_k)|`` of this one run, per estimator: per
    step (thin, faint) and its moving RMS over a hundredth of the run (thick: six filters
    stay apart), log scale, the legend outside the axes.

    For one run this is what seed 001 eq. (43) calls RMSE(k) (an RMSE over runs); the figure
    is titled for what it shows.
    """
    t = cols["time"]
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    fig, ax = plt.subplots(figsize=(9.5, 4.4), dpi=110, layout="constrained")
    w = max(1, t.size // 100)  # steps of the moving RMS
    for k, name in enumerate(est_names):
        ex, ey = position(cols, name, states)
        e = np.hypot(ex - tx, ey - ty)
        color = f"C{k % 10}"
        ax.plot(t, e, lw=0.5, alpha=0.3, color=color, **_sparse(e))
        ax.plot(t, _moving_rms(e, w), lw=1.8, color=color, ls=_DASHES[k // 10 % len(_DASHES)],
                label=display_name(name))
    bound_trace(ax, cols)
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position error norm (m)")
    span = f"{w * float(np.nanmedian(np.diff(t))):g} s" if t.size > 1 else "1 step"
    ax.set_title(f"Position error norm (this run, log scale): per step (thin) and its moving "
                 f"RMS over {span} (thick)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    plain_log_ticks(ax.yaxis)
    fig.legend(loc="outside right upper", fontsize=9, frameon=False)
    fig.savefig(path)
    plt.close(fig)
    return path
