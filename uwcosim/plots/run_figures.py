"""Figures of one run and its ``report.md``.

- ``trajectory.png``: truth and estimates over the bathymetry map, axes in metres or (a
  georeferenced run, ``[output] trajectory_axes = "latlon"``) in degrees of longitude and
  latitude;
- ``position_error.png``: position error of each estimator against time with its 3-sigma bound;
- ``position_error_norm.png``: the position error norm per step of the run (with the PCRB
  under it when the log has one, :mod:`uwcosim.plots.bound`);
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

from uwcosim.models.states import position_velocity_indices  # noqa: E402
from uwcosim.plots.bound import bound_trace  # noqa: E402
from uwcosim.runlog import columns  # noqa: E402


def _position(cols: Columns, estimator: str, states: Names) -> tuple[np.ndarray, np.ndarray]:
    """The position estimate ``(x, y)`` of ``estimator`` over the run."""
    ix, iy = position_velocity_indices(states)[0]
    return (cols[columns.estimate(estimator, states[ix])],
            cols[columns.estimate(estimator, states[iy])])


def _end_window(cols, truth_names, est_names, states):
    """The inset's square window: centred on the truth at the last step, half-width 3 times
    the median over the estimators of their largest position error over the last 5% of the
    run (at least 10 m): the estimates separate from the truth, an outlier (dead reckoning)
    may leave the window."""
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    n = tx.size
    k0 = max(0, n - max(5, n // 20))
    with warnings.catch_warnings():  # a replay's sparse reference: no value at the end
        warnings.simplefilter("ignore", RuntimeWarning)
        worst = [np.nanmax(np.hypot(ex[k0:] - tx[k0:], ey[k0:] - ty[k0:]), initial=np.nan)
                 for ex, ey in (_position(cols, e, states) for e in est_names)]
    worst = np.array([w for w in worst if np.isfinite(w)])
    if not np.isfinite(tx[-1]) or not np.isfinite(ty[-1]):
        return None
    half = max(3.0 * float(np.median(worst)) if worst.size else 0.0, 10.0)
    return tx[-1] - half, tx[-1] + half, ty[-1] - half, ty[-1] + half


INSET = 0.37  # size of the zoomed inset (axes fraction)


def _inset_corner(tx, ty, lims) -> tuple[float, float]:
    """Lower-left corner (axes fraction) of the inset: the corner that hides the fewest points
    of the track, its tick labels included (kept inside the main axes)."""
    x0, x1, y0, y1 = lims
    fx = (np.asarray(tx) - x0) / (x1 - x0 or 1.0)
    fy = (np.asarray(ty) - y0) / (y1 - y0 or 1.0)
    corners = [(0.1, 0.6), (0.6, 0.6), (0.1, 0.07), (0.6, 0.07)]
    hidden = [np.count_nonzero((fx > cx - 0.1) & (fx < cx + INSET + 0.01) & (fy > cy - 0.08)
                               & (fy < cy + INSET + 0.01)) for cx, cy in corners]
    return corners[int(np.argmin(hidden))]


def _sparse(v: np.ndarray) -> dict:
    """Line style of a series: markers when most of its steps have no value (a replay's
    sparse fixes: a line would not show them)."""
    fin = np.isfinite(v)
    return {"marker": ".", "ms": 4} if fin.any() and fin.mean() < 0.5 else {}


def _extent(cols: Columns, truth_xy, est_names: Names, states: Names):
    """``(xmin, xmax, ymin, ymax)`` of the truth, or of the estimates where it has no value."""
    tx, ty = truth_xy
    if not (np.isfinite(tx).any() and np.isfinite(ty).any()):
        pts = [_position(cols, e, states) for e in est_names]
        tx = np.concatenate([p[0] for p in pts]) if pts else np.zeros(1)
        ty = np.concatenate([p[1] for p in pts]) if pts else np.zeros(1)
    if not (np.isfinite(tx).any() and np.isfinite(ty).any()):
        return 0.0, 1.0, 0.0, 1.0
    return (float(np.nanmin(tx)), float(np.nanmax(tx)), float(np.nanmin(ty)),
            float(np.nanmax(ty)))


def trajectory_figure(cols: Columns, truth_names: Names, est_names: Names, states: Names,
                      bathy: Bathymetry | None, path: Path,
                      frame: LocalFrame | None = None) -> Path:
    """Track and estimates over the map, a colorbar the height of the axes and an inset that
    zooms on the end of the run (at map scale the estimates hide under the truth). With
    ``frame``, the axes are longitude and latitude (degrees; the frame's inverse projection of
    everything drawn, the map's contours included). A truth with values at few steps (a
    replay's fixes) is drawn as points."""
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    ex0, ex1, ey0, ey1 = _extent(cols, (tx, ty), est_names, states)
    pad = 1500.0 if bathy is not None else 0.1 * max(ex1 - ex0, ey1 - ey0, 10.0)
    x0, x1 = ex0 - pad, ex1 + pad
    y0, y1 = ey0 - pad, ey1 + pad
    if bathy is not None:
        xmin, xmax, ymin, ymax = bathy.extent
        x0, x1, y0, y1 = max(xmin, x0), min(xmax, x1), max(ymin, y0), min(ymax, y1)
        if not (x0 < x1 and y0 < y1):  # the track is off the map: the map's extent
            x0, x1, y0, y1 = xmin, xmax, ymin, ymax
    if frame is not None:
        return _trajectory_latlon(cols, (tx, ty), est_names, states, bathy,
                                  (x0, x1, y0, y1), path, frame)
    # the figure takes the shape of the view (equal axes): no empty bands around it
    ratio = float(np.clip((y1 - y0) / (x1 - x0), 0.45, 1.3)) if x1 > x0 else 1.0
    fig, ax = plt.subplots(figsize=(7.5, 5.9 * ratio + 1.5), dpi=110)
    ax.set_aspect("equal", adjustable="box" if bathy is not None else "datalim")
    if bathy is not None:
        GX, GY = np.meshgrid(np.linspace(x0, x1, 200), np.linspace(y0, y1, 200))
        D = bathy.depth(GX.ravel(), GY.ravel()).reshape(GX.shape)
        im = ax.contourf(GX, GY, D, levels=30, cmap="viridis_r")
        cax = make_axes_locatable(ax).append_axes("right", size="4%", pad=0.1)
        fig.colorbar(im, cax=cax, label="depth (m)")
    style = _sparse(tx)
    lines = [ax.plot(tx, ty, "k-", lw=2, label="reference" if style else "truth", **style)[0]]
    for name in est_names:
        lines += ax.plot(*_position(cols, name, states), lw=1, label=name)
    ax.plot(tx[0], ty[0], "ko")
    if bathy is not None:
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    else:  # no map: the data limits grow to fill the axes
        ax.apply_aspect()
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    box = _end_window(cols, truth_names, est_names, states)
    if box is not None:
        ins = ax.inset_axes([*_inset_corner(tx, ty, (x0, x1, y0, y1)), INSET, INSET])
        ins.set_facecolor("white")
        ins.plot(tx, ty, "k-", lw=2)
        ins.plot(tx[-1], ty[-1], "ko", ms=4)
        for line, name in zip(lines[1:], est_names):
            ins.plot(*_position(cols, name, states), lw=1, color=line.get_color())
        ins.set_xlim(box[0], box[1])
        ins.set_ylim(box[2], box[3])
        ins.set_aspect("equal")
        ins.tick_params(labelsize=6)
        ins.text(0.03, 0.97, f"zoom: t = {cols['time'][-1]:g} s",
                 transform=ins.transAxes, va="top", fontsize=7,
                 bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8})
        ax.indicate_inset_zoom(ins, edgecolor="0.2")
    ax.set_title("Trajectory and estimates")
    fig.tight_layout(rect=(0, 0.4 / fig.get_figheight(), 1, 1))
    fig.legend(handles=lines, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.savefig(path)
    plt.close(fig)
    return path


def _trajectory_latlon(cols, truth_xy, est_names, states, bathy, lims, path, frame) -> Path:
    """:func:`trajectory_figure` with longitude/latitude axes (no inset)."""
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    x0, x1, y0, y1 = lims
    tx, ty = truth_xy
    ratio = float(np.clip((y1 - y0) / (x1 - x0), 0.45, 1.3)) if x1 > x0 else 1.0
    fig, ax = plt.subplots(figsize=(7.5, 5.9 * ratio + 1.5), dpi=110)
    if bathy is not None:
        GX, GY = np.meshgrid(np.linspace(x0, x1, 200), np.linspace(y0, y1, 200))
        D = bathy.depth(GX.ravel(), GY.ravel()).reshape(GX.shape)
        la, lo = frame.to_latlon(GX, GY)
        im = ax.contourf(lo, la, D, levels=30, cmap="viridis_r")
        cax = make_axes_locatable(ax).append_axes("right", size="4%", pad=0.1)
        fig.colorbar(im, cax=cax, label="depth (m)")
    lat, lon = frame.to_latlon(tx, ty)
    style = _sparse(lon)
    lines = [ax.plot(lon, lat, "k-", lw=2, label="reference" if style else "truth",
                     **style)[0]]
    for name in est_names:
        elat, elon = frame.to_latlon(*_position(cols, name, states))
        lines += ax.plot(elon, elat, lw=1, label=name)
    ax.plot(lon[0], lat[0], "ko")
    # the view: the metric window's corners in degrees; equal ground scales on both axes
    cla, clo = frame.to_latlon(np.array([x0, x1, x0, x1]), np.array([y0, y0, y1, y1]))
    ax.set_xlim(float(clo.min()), float(clo.max()))
    ax.set_ylim(float(cla.min()), float(cla.max()))
    ax.set_aspect(1.0 / np.cos(np.deg2rad(frame.lat0)), adjustable="box")
    ax.set_xlabel("longitude (°)")
    ax.set_ylabel("latitude (°)")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_title("Trajectory and estimates")
    fig.tight_layout(rect=(0, 0.4 / fig.get_figheight(), 1, 1))
    fig.legend(handles=lines, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.savefig(path)
    plt.close(fig)
    return path


def error_figure(cols: Columns, truth_names: Names, est_names: Names, states: Names,
                 path: Path) -> Path:
    """Position error (x solid, y dashed) and their 3-sigma bounds (x: hatched band, y: plain
    band with dotted edges), one legend, the same y-scale in every panel."""
    t = cols["time"]
    fig, axes = plt.subplots(len(est_names), 1, figsize=(8, 2.0 * len(est_names) + 1.0),
                             dpi=110, sharex=True, sharey=True, squeeze=False,
                             layout="constrained")
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    mags = []
    handles = None
    for ax, name in zip(axes[:, 0], est_names):
        ex = cols[columns.estimate(name, states[ix])] - tx
        ey = cols[columns.estimate(name, states[iy])] - ty
        sx = 3 * np.sqrt(cols[columns.variance(name, states[ix])])
        sy = 3 * np.sqrt(cols[columns.variance(name, states[iy])])
        bx = ax.fill_between(t, -sx, sx, facecolor="none", edgecolor="C0", hatch="////",
                             lw=0.0, alpha=0.5, label="±3σ x")
        by = ax.fill_between(t, -sy, sy, color="C1", alpha=0.18, lw=0, label="±3σ y")
        ax.plot(t, sy, "C1:", lw=0.8)
        ax.plot(t, -sy, "C1:", lw=0.8)
        lx, = ax.plot(t, ex, "C0-", lw=0.9, label="error x", **_sparse(ex))
        ly, = ax.plot(t, ey, "C1--", lw=0.9, label="error y", **_sparse(ey))
        handles = [lx, bx, ly, by]
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.set_ylabel(f"{name} (m)")
        mags.append(np.abs(np.concatenate([ex, ey, sx, sy])))
    lim = np.nanpercentile(np.concatenate(mags), 99) * 1.15 if mags else np.nan
    if np.isfinite(lim) and lim > 0:
        axes[0, 0].set_ylim(-lim, lim)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Position error with 3-sigma bounds (same scale in every panel)")
    fig.legend(handles=handles, loc="outside lower center", ncol=4, fontsize=8)
    fig.savefig(path)
    plt.close(fig)
    return path


def error_norm_figure(cols: Columns, truth_names: Names, est_names: Names, states: Names,
                      path: Path) -> Path:
    """The position error norm ``|p_est(t_k) - p(t_k)|`` of this one run, per estimator.

    For one run this is what seed 001 eq. (43) calls RMSE(k) (an RMSE over runs); the figure
    is titled for what it shows.
    """
    t = cols["time"]
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=110)
    for name in est_names:
        ex, ey = _position(cols, name, states)
        e = np.hypot(ex - tx, ey - ty)
        ax.plot(t, e, lw=0.8, label=name, **_sparse(e))
    bound_trace(ax, cols)
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position error norm (m)")
    ax.set_title("Position error norm per step (this run)")
    ax.legend(fontsize=8, ncol=min(4, len(est_names)))
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
