"""The track of a run in the plane: an estimator's position over the run, and the window of
the map that the trajectory figures show (the PNG and the HTML report's, the same view).

No matplotlib here: the HTML report uses it without drawing a PNG.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from uwcosim.models.states import position_velocity_indices
from uwcosim.runlog import columns

if TYPE_CHECKING:
    from collections.abc import Sequence

    from uwcosim.models.terrain import Bathymetry

    #: log columns by name, and lists of names
    Columns = dict[str, np.ndarray]
    Names = Sequence[str]

#: margin of map around the track (m) when there is a map
MAP_PAD = 1500.0


def position(cols: Columns, estimator: str, states: Names) -> tuple[np.ndarray, np.ndarray]:
    """The position estimate ``(x, y)`` of ``estimator`` over the run."""
    ix, iy = position_velocity_indices(states)[0]
    return (cols[columns.estimate(estimator, states[ix])],
            cols[columns.estimate(estimator, states[iy])])


def _extent(cols: Columns, truth_xy, est_names: Names, states: Names):
    """``(xmin, xmax, ymin, ymax)`` of the truth, or of the estimates where it has no value."""
    tx, ty = truth_xy
    if not (np.isfinite(tx).any() and np.isfinite(ty).any()):
        pts = [position(cols, e, states) for e in est_names]
        tx = np.concatenate([p[0] for p in pts]) if pts else np.zeros(1)
        ty = np.concatenate([p[1] for p in pts]) if pts else np.zeros(1)
    if not (np.isfinite(tx).any() and np.isfinite(ty).any()):
        return 0.0, 1.0, 0.0, 1.0
    return (float(np.nanmin(tx)), float(np.nanmax(tx)), float(np.nanmin(ty)),
            float(np.nanmax(ty)))


def map_window(cols: Columns, truth_names: Names, est_names: Names, states: Names,
               bathy: Bathymetry | None) -> tuple[float, float, float, float]:
    """``(x0, x1, y0, y1)``: the truth's extent (the estimates' without a truth) with
    :data:`MAP_PAD` of map around it, kept on the map (the whole map when the track is off
    it); without a map, a tenth of the extent around it."""
    ix, iy = position_velocity_indices(states)[0]
    tx, ty = cols[truth_names[ix]], cols[truth_names[iy]]
    ex0, ex1, ey0, ey1 = _extent(cols, (tx, ty), est_names, states)
    pad = MAP_PAD if bathy is not None else 0.1 * max(ex1 - ex0, ey1 - ey0, 10.0)
    x0, x1 = ex0 - pad, ex1 + pad
    y0, y1 = ey0 - pad, ey1 + pad
    if bathy is not None:
        xmin, xmax, ymin, ymax = bathy.extent
        x0, x1, y0, y1 = max(xmin, x0), min(xmax, x1), max(ymin, y0), min(ymax, y1)
        if not (x0 < x1 and y0 < y1):  # the track is off the map: the map's extent
            x0, x1, y0, y1 = xmin, xmax, ymin, ymax
    return x0, x1, y0, y1
