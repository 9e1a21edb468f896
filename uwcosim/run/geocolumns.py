"""The latitude/longitude columns of a georeferenced run's log, computed from each row.

In a run with a geographic frame (:func:`uwcosim.scenario.geo.scenario_frame`) the log has,
beside ``x``/``y``, the latitude and longitude of the truth's position and of every
estimator's (:class:`~uwcosim.runlog.columns.LogLayout` ``geo``). :class:`GeoColumns` fills
them in a row from its ``x``/``y`` columns (the frame's inverse projection, one ``pyproj``
call per row for all the positions); the log recorder calls it before writing the row.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from uwcosim.models.geo import LocalFrame
from uwcosim.models.states import position_velocity_indices
from uwcosim.runlog.columns import LogLayout


class GeoColumns:
    """``derive(row)`` of :class:`~uwcosim.run.recorder.LogRecorder` for a georeferenced log:
    the truth's position columns are the ``truth`` signals of the position states."""

    def __init__(self, layout: LogLayout, frame: LocalFrame, truth: Sequence[str]) -> None:
        ix, iy = position_velocity_indices(layout.states)[0]
        sig = list(layout.signals)
        xs = [1 + sig.index(truth[ix])]
        ys = [1 + sig.index(truth[iy])]
        blk, start = layout.block, layout.estimates.start
        for e in range(len(layout.estimators)):
            xs.append(start + e * blk.width + blk.mean.start + ix)
            ys.append(start + e * blk.width + blk.mean.start + iy)
        self.xs, self.ys = np.array(xs, dtype=np.intp), np.array(ys, dtype=np.intp)
        g = layout.geo_part
        self.lat = np.arange(g.start, g.stop, 2, dtype=np.intp)
        self.lon = self.lat + 1
        self.frame = frame

    def __call__(self, row: np.ndarray) -> None:
        lat, lon = self.frame.to_latlon(row[self.xs], row[self.ys])
        row[self.lat] = lat
        row[self.lon] = lon
