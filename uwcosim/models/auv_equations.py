"""AUV kinematics of seed 000, eq. (54), and the sensors' output equations, in CasADi.

These expressions are the single definition of the truth models: ``uwcosim fmu build`` generates
the FMUs' C code from them and the estimators take their exact Jacobians from them.

Vehicle (eq. 54)::

    x'  = vx cos(psi) - vy sin(psi) + w_x
    y'  = vy cos(psi) + vx sin(psi) + w_y
    vx' = a cos(psi) + w_vx
    vy' = a sin(psi) + w_vy

with state ``[x, y, vx, vy]`` (m, m/s), inputs heading ``psi`` (rad) and acceleration ``a``
(m/s^2), and four process-noise inputs ``w`` (held constant over a communication step).
The vehicle FMU adds two control-noise inputs ``w_psi``, ``w_a`` (default 0) to ``psi`` and
``a`` before these equations (:func:`noisy_controls`): the truth then follows noisy controls
while the filters know the commanded ones (seed 000, Fig. 6, "control vector with noise").
The paper's model is reproduced as printed: the velocity state is rotated by psi for the
position rate while the acceleration is applied along psi.

DVL (eq. 55, first two rows): ``[vx_m, vy_m] = [vx, vy] + e_v``.
Depth sounder (eq. 55, third row): ``h_m = h_d(x, y) + e_h`` with ``h_d`` the bathymetry
spline of :mod:`uwcosim.models.terrain`.
"""

from __future__ import annotations

import casadi as ca

from uwcosim.core.integrators import rk4

STATE_NAMES = ("x", "y", "vx", "vy")
CONTROL_NAMES = ("psi", "a")
NOISE_NAMES = ("w_x", "w_y", "w_vx", "w_vy")
CONTROL_NOISE_NAMES = ("w_psi", "w_a")


def noisy_controls(u, w_u):
    """The controls the vehicle follows: the commanded ``[psi, a]`` plus the control noise."""
    return u + w_u


def vehicle_ode() -> ca.Function:
    """``xdot = f(x, u, w)`` of eq. (54) as a CasADi function."""
    x = ca.SX.sym("x", 4)
    u = ca.SX.sym("u", 2)
    w = ca.SX.sym("w", 4)
    vx, vy = x[2], x[3]
    psi, a = u[0], u[1]
    c, s = ca.cos(psi), ca.sin(psi)
    xdot = ca.vertcat(vx * c - vy * s, vy * c + vx * s, a * c, a * s) + w
    return ca.Function("vehicle_ode", [x, u, w], [xdot], ["x", "u", "w"], ["xdot"])


def dvl_output() -> ca.Function:
    """DVL: measured body velocities ``[vx, vy] + e``."""
    v = ca.SX.sym("v", 2)
    e = ca.SX.sym("e", 2)
    return ca.Function("dvl_output", [v, e], [v + e], ["v", "e"], ["v_m"])


def rk4_step(ode: ca.Function, substeps: int = 1) -> ca.Function:
    """One RK4 step of length ``dt`` (inputs held) for ``ode(x, u, w)``: ``F(x, u, w, dt)``.

    For eq. (54) with held inputs the position is a quadratic polynomial in time, so a single
    RK4 step is exact; ``substeps`` is there for other models.
    """
    x = ca.SX.sym("x", ode.size1_in(0))
    u = ca.SX.sym("u", ode.size1_in(1))
    w = ca.SX.sym("w", ode.size1_in(2))
    dt = ca.SX.sym("dt")
    xk = rk4(lambda _t, xx: ode(xx, u, w), x, 0.0, dt, substeps)
    return ca.Function("rk4_step", [x, u, w, dt], [xk], ["x", "u", "w", "dt"], ["xf"])
