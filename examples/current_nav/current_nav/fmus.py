"""The truth FMUs of current_nav, built from the CasADi equations by uwcosim's FMU tooling::

    cd examples/current_nav && uwcosim fmu build --spec current_nav.fmus:specs --out fmus

(``fmus/CurrentVehicle.fmu`` and ``fmus/BeaconRanger.fmu``, FMI 3.0, and their ``_fmi2``
twins: the same generated C code and templates as the project's FMUs; the DVL is the
project's ``fmus/DVL.fmu``.)
"""

from __future__ import annotations

import casadi as ca

from current_nav.equations import beacon_range, vehicle_rates
from uwcosim.fmu.specs import ModelSpec, Var


def _vehicle(x, u, p, z):
    return vehicle_rates(x, u[0:2], u[2:8], p[0]), ca.SX(0, 1)


def _ranger(x, u, p, z):
    bx, by, dz, multipath, threshold = (p[i] for i in range(5))
    outlier = ca.if_else(u[3] > threshold, multipath, 0.0)  # a longer, reflected path
    return ca.SX(0, 1), beacon_range(u[0], u[1], bx, by, dz) + u[2] + outlier


def vehicle_spec() -> ModelSpec:
    return ModelSpec(
        name="CurrentVehicle",
        description="AUV in a water current: position, body-frame velocity through the "
                    "water, Gauss-Markov current; heading and surge acceleration inputs, "
                    "process noise",
        equations=_vehicle,
        states=(
            Var("x", "m", 0.0, "East position", der_unit="m/s"),
            Var("y", "m", 0.0, "North position", der_unit="m/s"),
            Var("vx", "m/s", 0.0, "Surge: body-frame velocity through the water",
                der_unit="m/s2"),
            Var("vy", "m/s", 0.0, "Sway (to port): body-frame velocity through the water",
                der_unit="m/s2"),
            Var("cx", "m/s", 0.0, "East water current", der_unit="m/s2"),
            Var("cy", "m/s", 0.0, "North water current", der_unit="m/s2"),
        ),
        inputs=(
            Var("psi", "rad", 0.0, "Heading (counter-clockwise from east)"),
            Var("a", "m/s2", 0.0, "Surge acceleration"),
            Var("w_x", "m/s", 0.0, "Process noise on x'"),
            Var("w_y", "m/s", 0.0, "Process noise on y'"),
            Var("w_vx", "m/s2", 0.0, "Process noise on vx'"),
            Var("w_vy", "m/s2", 0.0, "Process noise on vy'"),
            Var("w_cx", "m/s2", 0.0, "Process noise on cx'"),
            Var("w_cy", "m/s2", 0.0, "Process noise on cy'"),
        ),
        params=(Var("tau", "s", 600.0, "Correlation time of the current"),),
    )


def ranger_spec() -> ModelSpec:
    return ModelSpec(
        name="BeaconRanger",
        description="Acoustic range to a beacon, with multipath outliers: slant range + e_r, "
                    "plus multipath_m when the input mp exceeds threshold",
        equations=_ranger,
        inputs=(
            Var("x", "m", 0.0, "East position"),
            Var("y", "m", 0.0, "North position"),
            Var("e_r", "m", 0.0, "Measurement noise on the range"),
            Var("mp", None, 0.0, "Multipath indicator (an outlier when > threshold)"),
        ),
        params=(
            Var("bx", "m", 0.0, "Beacon east position"),
            Var("by", "m", 0.0, "Beacon north position"),
            Var("dz", "m", 0.0, "Depth difference between beacon and vehicle"),
            Var("multipath_m", "m", 25.0, "Extra length of a multipath range"),
            Var("threshold", None, 1e300, "mp above which a range is a multipath one"),
        ),
        outputs=(Var("range_m", "m", 0.0, "Measured slant range"),),
    )


def specs() -> list[ModelSpec]:
    """The two truth FMUs of the example."""
    return [vehicle_spec(), ranger_spec()]
