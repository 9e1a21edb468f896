"""The vehicle with a water current and the beacon range, in CasADi: defined once, for the truth
FMUs (:mod:`current_nav.fmus`) and the filters' model (:mod:`current_nav.model`).

Vehicle, state ``[x, y, vx, vy, cx, cy]``: position (m, east/north), velocity through the water
in the body frame (m/s: surge ``vx``, sway ``vy`` to port) and the water current (m/s,
east/north); controls heading ``psi`` (rad, counter-clockwise from east) and surge acceleration
``a`` (m/s^2); process noise ``w`` on every rate (held over a step, as the master feeds it)::

    x'  = vx cos(psi) - vy sin(psi) + cx + w_x      vx' = a + w_vx      cx' = -cx / tau + w_cx
    y'  = vx sin(psi) + vy cos(psi) + cy + w_y      vy' = w_vy          cy' = -cy / tau + w_cy

The current is a first-order Gauss-Markov process of correlation time ``tau``: with the noise
PSD ``q_c`` its stationary standard deviation is ``sqrt(q_c tau / 2)``. A DVL in water-track
mode measures ``(vx, vy)``, not the current: dead reckoning drifts with it.

Beacon range (an acoustic transponder at ``(bx, by)``, ``dz`` below or above the vehicle's
depth): ``r = sqrt((x - bx)^2 + (y - by)^2 + dz^2)``.
"""

from __future__ import annotations

import casadi as ca

STATE_NAMES = ("x", "y", "vx", "vy", "cx", "cy")
CONTROL_NAMES = ("psi", "a")


def vehicle_rates(x, u, w, tau):
    """``dx/dt`` of the state ``x`` (6), controls ``u = [psi, a]`` and noise ``w`` (6)."""
    psi, a = u[0], u[1]
    c, s = ca.cos(psi), ca.sin(psi)
    return ca.vertcat(x[2] * c - x[3] * s + x[4], x[2] * s + x[3] * c + x[5], a, 0,
                      -x[4] / tau, -x[5] / tau) + w


def beacon_range(x, y, bx, by, dz):
    """Slant range from ``(x, y)`` to the beacon at ``(bx, by)``, ``dz`` apart in depth."""
    return ca.sqrt((x - bx) ** 2 + (y - by) ** 2 + dz ** 2)
