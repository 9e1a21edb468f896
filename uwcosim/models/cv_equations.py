"""Constant-velocity (white-noise acceleration) vehicle in CasADi, for the lost-measurement
experiment.

State ``[px, vx, py, vy]`` (m, m/s), process-noise inputs ``[w_px, w_vx, w_py, w_vy]``
(held constant over a communication step)::

    px' = vx + w_px
    vx' = w_vx
    py' = vy + w_py
    vy' = w_vy

The ``ConstantVelocity`` FMU is generated from :func:`constant_velocity_ode`.
"""

from __future__ import annotations

import casadi as ca

STATE_NAMES = ("px", "vx", "py", "vy")
NOISE_NAMES = ("w_px", "w_vx", "w_py", "w_vy")


def constant_velocity_ode() -> ca.Function:
    """``xdot = f(x, w)`` of the constant-velocity model as a CasADi function."""
    x = ca.SX.sym("x", 4)
    w = ca.SX.sym("w", 4)
    xdot = ca.vertcat(x[1], 0, x[3], 0) + w
    return ca.Function("constant_velocity_ode", [x, w], [xdot], ["x", "w"], ["xdot"])
