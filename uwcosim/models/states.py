"""State names: the one place that knows which states are the position and the velocity.

The built-in models name their states ``x, y, vx, vy`` (TAN, seed 000 eq. 54) and
``px, vx, py, vy`` (constant velocity, seed 001); :func:`position_velocity_indices` finds the
position and velocity states of any model by these names (the metrics, the divergence bound,
the figures and the density snapshots use it).
"""

from __future__ import annotations

from collections.abc import Sequence

#: the states of the built-in filter models (:mod:`uwcosim.models.tan`,
#: :mod:`uwcosim.models.linear`), by ``[model] kind``
MODEL_STATES = {"tan": ("x", "y", "vx", "vy"), "cv": ("px", "vx", "py", "vy")}

_POSITION = (("x", "y"), ("px", "py"))
_VELOCITY = (("vx", "vy"),)


def position_velocity_indices(state_names: Sequence[str]) -> tuple[list[int], list[int]]:
    """Indices of the position and velocity states from their names (TAN or CV order)."""
    names = list(state_names)
    pos = next(([names.index(a) for a in p] for p in _POSITION if set(p) <= set(names)), [])
    vel = next(([names.index(a) for a in v] for v in _VELOCITY if set(v) <= set(names)), [])
    return pos, vel
