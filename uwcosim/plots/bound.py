"""The posterior Cramér-Rao bound drawn under the position error curves of a figure.

:func:`bound_trace` adds, to an axes whose curves are position error norms against time, the
PCRB on the position error norm's RMSE (``sqrt`` of the sum of the log's squared
``bound.STATE`` columns of the position states, :mod:`uwcosim.evaluation.pcrb`), when the log
has them (a run with ``[evaluation] bound``); nothing otherwise. One run's error norm may fall
below it at some steps: the bound is on the RMSE over runs, not on one run's error.
"""

from __future__ import annotations

import numpy as np

from uwcosim.evaluation.pcrb import position_bound
from uwcosim.models.states import position_velocity_indices
from uwcosim.runlog import columns

__all__ = ["bound_trace"]


def bound_trace(ax, cols: dict[str, np.ndarray]) -> bool:
    """Draw the position bound of the log's ``bound.STATE`` columns on ``ax`` (black, dashed,
    under the other curves); True when there was one."""
    states = columns.bound_states_in(cols)
    pos = position_velocity_indices(states)[0] if states else []
    if not pos:
        return False
    std = np.stack([cols[columns.bound(s)] for s in states], axis=1)
    ax.plot(cols["time"], position_bound(std, pos), color="black", ls="--", lw=1.0,
            zorder=1, label="PCRB (RMSE bound)")
    return True
