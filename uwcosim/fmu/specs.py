"""Specifications of the project's FMUs: variables, units, start values and CasADi equations.

Each model is described once by a :class:`ModelSpec`. :mod:`uwcosim.fmu.codegen` turns it
into CasADi generated C code and the configuration header of the C template,
:mod:`uwcosim.fmu.model_description` into ``modelDescription.xml`` (FMI 2.0 and 3.0).

The equations have a fixed interface (see ``templates/uwc_model.h``)::

    ode(x[NX], u[NU], p[NP])        -> xdot[NX]
    out(x[NX], u[NU], p[NP], z[NZ]) -> y[NY]

``z`` are values computed by C kernels (the terrain depth ``h_d(x, y)`` of the DepthSounder).
Value references are the positions in the Float64 layout
``[time | states | derivatives | inputs | parameters | calculated parameters | outputs]``
followed by the String parameters (see :func:`layout`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from uwcosim.core.errors import FMUError
from uwcosim.models.auv_equations import dvl_output, noisy_controls, vehicle_ode
from uwcosim.models.cv_equations import constant_velocity_ode

#: base-unit exponents of every unit the FMUs use (FMI UnitDefinitions)
UNITS: dict[str, dict[str, int]] = {
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "rad": {"rad": 1},
    "1/s": {"s": -1},
}

#: file name of the default map inside the DepthSounder's resources/ folder
DEFAULT_MAP_FILE = "default_map.uwcbath"
#: seed of :func:`uwcosim.models.terrain.synthetic_bathymetry` for the default map
DEFAULT_MAP_SEED = 7


@dataclass(frozen=True)
class Var:
    """One model variable as declared in a :class:`ModelSpec`."""

    name: str
    unit: str | None = None
    start: float | str = 0.0
    description: str = ""
    der_unit: str | None = None  # states: unit of the derivative
    tunable: bool = False  # parameters: may change during the simulation


Equations = Callable[[ca.SX, ca.SX, ca.SX, ca.SX], tuple[ca.SX, ca.SX]]


@dataclass(frozen=True)
class ModelSpec:
    """Everything needed to generate one FMU (both FMI versions)."""

    name: str
    description: str
    equations: Equations  # (x, u, p, z) -> (xdot, y)
    states: tuple[Var, ...] = ()  # continuous states, also outputs (initial="exact")
    inputs: tuple[Var, ...] = ()
    params: tuple[Var, ...] = ()
    calc_params: tuple[Var, ...] = ()  # computed by C code (map extent)
    outputs: tuple[Var, ...] = ()  # algebraic outputs y of `out`
    strings: tuple[Var, ...] = ()  # String parameters
    externals: tuple[str, ...] = ()  # names of the z values
    external_deps: tuple[tuple[str, ...], ...] = ()  # inputs/strings each z depends on
    kind: str = "generic"  # "generic" | "bathymetry"
    stop_time: float = 10.0
    step_size: float = 0.1
    resources: tuple[str, ...] = field(default=())  # files generated into resources/
    #: C source of ``uwc_hook_eval/outputs/step`` (see templates/uwc_model.h) compiled with
    #: the model: test models only (tests/fault_injector.py); no shipped FMU has hooks
    hooks: Path | None = None

    def functions(self) -> tuple[ca.Function, ca.Function]:
        """The CasADi functions ``ode(x, u, p)`` and ``out(x, u, p, z)``."""
        x = ca.SX.sym("x", len(self.states))
        u = ca.SX.sym("u", len(self.inputs))
        p = ca.SX.sym("p", len(self.params))
        z = ca.SX.sym("z", len(self.externals))
        xdot, y = self.equations(x, u, p, z)
        xdot = ca.densify(ca.SX(xdot)).reshape((-1, 1))
        y = ca.densify(ca.SX(y)).reshape((-1, 1))
        if xdot.numel() != len(self.states) or y.numel() != len(self.outputs):
            raise FMUError(f"{self.name}: equations return {xdot.numel()} derivatives and "
                           f"{y.numel()} outputs, expected {len(self.states)} and "
                           f"{len(self.outputs)}")
        ode = ca.Function("ode", [x, u, p], [xdot], ["x", "u", "p"], ["xdot"])
        out = ca.Function("out", [x, u, p, z], [y], ["x", "u", "p", "z"], ["y"])
        return ode, out


@dataclass(frozen=True)
class Variable:
    """A variable with its value reference and role, as it appears in the FMU."""

    vr: int
    name: str
    kind: str  # time | state | der | input | param | tunable | calc | output | string
    unit: str | None
    start: float | str | None
    description: str
    state_vr: int | None = None  # derivatives: value reference of their state


KIND_CODES = {"time": 0, "state": 1, "der": 2, "input": 3, "param": 4, "tunable": 5,
              "calc": 6, "output": 7}


def layout(spec: ModelSpec) -> list[Variable]:
    """All variables of ``spec`` in value-reference order (the C template's ``r[]`` layout)."""
    out = [Variable(0, "time", "time", "s", None, "Simulation time")]
    nx = len(spec.states)
    for i, v in enumerate(spec.states):
        out.append(Variable(1 + i, v.name, "state", v.unit, float(v.start), v.description))
    for i, v in enumerate(spec.states):
        out.append(Variable(1 + nx + i, f"der({v.name})", "der", v.der_unit, None,
                            f"Time derivative of {v.name}", state_vr=1 + i))
    groups = [(spec.inputs, "input"), (spec.params, None), (spec.calc_params, "calc"),
              (spec.outputs, "output")]
    for group, kind in groups:
        for v in group:
            k = kind or ("tunable" if v.tunable else "param")
            start = None if k in ("calc", "output") else float(v.start)
            out.append(Variable(len(out), v.name, k, v.unit, start, v.description))
    nr = len(out)
    for i, v in enumerate(spec.strings):
        out.append(Variable(nr + i, v.name, "string", None, str(v.start), v.description))
    return out


def dependencies(spec: ModelSpec) -> dict[str, tuple[list[str], list[str]]]:
    """Structural dependencies from the CasADi Jacobian sparsity.

    Returns ``{unknown: (run_time_deps, initial_deps)}`` for every derivative ``der(s)`` and
    algebraic output: run-time dependencies on states and inputs (ModelStructure Outputs /
    Derivatives) and initialization dependencies that add parameters and String parameters
    (InitialUnknowns). Calculated parameters depend on the String parameters.
    """
    ode, out = spec.functions()
    names = {
        0: [v.name for v in spec.states],
        1: [v.name for v in spec.inputs],
        2: [v.name for v in spec.params],
    }

    def deps_of(fun: ca.Function, unknowns: list[str]) -> dict[str, tuple[list[str], list[str]]]:
        result: dict[str, tuple[set[str], set[str]]] = {u: (set(), set()) for u in unknowns}
        for i in range(fun.n_in()):
            if fun.numel_in(i) == 0 or fun.numel_out(0) == 0:
                continue
            rows, cols = fun.jac_sparsity(0, i).get_triplet()
            for r, c in zip(rows, cols, strict=True):
                run, init = result[unknowns[r]]
                if i == 3:  # external z: its declared dependencies
                    extra = spec.external_deps[c]
                    run.update(n for n in extra if n not in {s.name for s in spec.strings})
                    init.update(extra)
                else:
                    if i < 2:
                        run.add(names[i][c])
                    init.add(names[i][c])
        return {u: (sorted(run), sorted(init)) for u, (run, init) in result.items()}

    deps = deps_of(ode, [f"der({v.name})" for v in spec.states])
    deps.update(deps_of(out, [v.name for v in spec.outputs]))
    for v in spec.calc_params:
        deps[v.name] = ([], [s.name for s in spec.strings])
    return deps


# ---- the models -------------------------------------------------------------------------

_MAX_STEP = Var("max_internal_step", "s", 0.1,
                "Largest internal RK4 step in co-simulation (<= 0: one step per doStep)")


def _auv(x, u, p, z):
    xdot = vehicle_ode()(x, noisy_controls(u[0:2], u[6:8]), u[2:6])
    return xdot, u[0]  # psi_out: the commanded heading


def _constant_velocity(x, u, p, z):
    return constant_velocity_ode()(x, u), ca.SX(0, 1)


def _dvl(x, u, p, z):
    """DVL errors (all zero by default: then ``v_m = v + e`` exactly as eq. 55): bias ``b`` and
    scale factor ``s`` are random walks (states, ``b' = w_b``, ``s' = w_s``, white noise held
    over a step as the process noise), ``v_m = (1 + s) v + b + e``; ``bottom_lock`` is 0 when
    ``maxAltitude > 0`` and the altitude is above it (a sensor's ``valid`` output)."""
    v, e, altitude = u[0:2], u[2:4], u[7]
    b, sf = x[0:2], x[2]
    xdot = ca.vertcat(u[4], u[5], u[6])  # b' = w_b, s' = w_s
    v_m = dvl_output()((1 + sf) * v + b, e)  # (1 + s) v + b + e
    lock = ca.if_else(ca.logic_and(p[0] > 0, altitude > p[0]), 0.0, 1.0)
    return xdot, ca.vertcat(v_m, lock)


def _std_normal_cdf(u):
    return 0.5 * (1.0 + ca.erf(u / np.sqrt(2.0)))


def _depth_sounder(x, u, p, z):
    """``depth_m = h + e_h`` (eq. 55) plus the truth's offset and the sounder's faults, all zero
    by default: with ``Phi(u_o)`` (``u_o`` standard normal, the sensor's noise) below
    ``outlierProb`` the return is an outlier ``+ outlierStd * e_o`` (a Gaussian mixture);
    in the next ``multipathProb`` of probability a multipath return ``multipathFactor * h``
    (2: the seafloor-surface-seafloor echo)."""
    h, e_h, offset, u_o, e_o = z[0], u[2], u[3], u[4], u[5]
    p_out, std_out, p_mp, k_mp = p[0], p[1], p[2], p[3]
    c = _std_normal_cdf(u_o)
    outlier = c < p_out
    multipath = ca.logic_and(c >= p_out, c < p_out + p_mp)
    hm = ca.if_else(multipath, k_mp * h, h)
    depth = hm + e_h + offset + ca.if_else(outlier, std_out * e_o, 0.0)
    return ca.SX(0, 1), ca.vertcat(depth, h - p[4])


def _auv_spec() -> ModelSpec:
    return ModelSpec(
        name="AUVKinematics",
        description="AUV planar kinematics, eq. (54): states x, y, vx, vy; heading and "
                    "acceleration inputs; additive process noise and control noise",
        equations=_auv,
        states=(
            Var("x", "m", 0.0, "East position", der_unit="m/s"),
            Var("y", "m", 0.0, "North position", der_unit="m/s"),
            Var("vx", "m/s", 0.0, "Velocity state vx", der_unit="m/s2"),
            Var("vy", "m/s", 0.0, "Velocity state vy", der_unit="m/s2"),
        ),
        inputs=(
            Var("psi", "rad", 0.0, "Heading"),
            Var("a", "m/s2", 0.0, "Acceleration along the heading"),
            Var("w_x", "m/s", 0.0, "Process noise on x'"),
            Var("w_y", "m/s", 0.0, "Process noise on y'"),
            Var("w_vx", "m/s2", 0.0, "Process noise on vx'"),
            Var("w_vy", "m/s2", 0.0, "Process noise on vy'"),
            Var("w_psi", "rad", 0.0, "Control noise added to the heading psi"),
            Var("w_a", "m/s2", 0.0, "Control noise added to the acceleration a"),
        ),
        params=(_MAX_STEP,),
        outputs=(Var("psi_out", "rad", 0.0, "Heading (passthrough of the commanded psi)"),),
    )


def _cv_spec() -> ModelSpec:
    return ModelSpec(
        name="ConstantVelocity",
        description="Constant-velocity vehicle [px, vx, py, vy] with process-noise inputs",
        equations=_constant_velocity,
        states=(
            Var("px", "m", 0.0, "East position", der_unit="m/s"),
            Var("vx", "m/s", 0.0, "East velocity", der_unit="m/s2"),
            Var("py", "m", 0.0, "North position", der_unit="m/s"),
            Var("vy", "m/s", 0.0, "North velocity", der_unit="m/s2"),
        ),
        inputs=(
            Var("w_px", "m/s", 0.0, "Process noise on px'"),
            Var("w_vx", "m/s2", 0.0, "Process noise on vx' (acceleration)"),
            Var("w_py", "m/s", 0.0, "Process noise on py'"),
            Var("w_vy", "m/s2", 0.0, "Process noise on vy' (acceleration)"),
        ),
        params=(_MAX_STEP,),
    )


def _dvl_spec() -> ModelSpec:
    return ModelSpec(
        name="DVL",
        description="Doppler velocity log, eq. (55): measured velocities v + e_v",
        equations=_dvl,
        states=(
            Var("b_vx", "m/s", 0.0, "Bias random walk on vx", der_unit="m/s2"),
            Var("b_vy", "m/s", 0.0, "Bias random walk on vy", der_unit="m/s2"),
            Var("scale", None, 0.0, "Scale-factor error random walk (1)", der_unit="1/s"),
        ),
        inputs=(
            Var("vx", "m/s", 0.0, "True velocity vx"),
            Var("vy", "m/s", 0.0, "True velocity vy"),
            Var("e_vx", "m/s", 0.0, "Measurement noise on vx"),
            Var("e_vy", "m/s", 0.0, "Measurement noise on vy"),
            Var("w_bvx", "m/s2", 0.0, "White noise driving the vx bias (b_vx' = w_bvx)"),
            Var("w_bvy", "m/s2", 0.0, "White noise driving the vy bias (b_vy' = w_bvy)"),
            Var("w_scale", "1/s", 0.0, "White noise driving the scale factor"),
            Var("altitude", "m", 0.0, "Altitude above the seafloor (bottom lock)"),
        ),
        params=(
            Var("maxAltitude", "m", 0.0, "Largest altitude with bottom lock (<= 0: always)"),
        ),
        outputs=(
            Var("vx_m", "m/s", 0.0, "Measured vx"),
            Var("vy_m", "m/s", 0.0, "Measured vy"),
            Var("bottom_lock", None, 1.0, "1 with bottom lock, 0 above maxAltitude"),
        ),
    )


def _depth_sounder_spec() -> ModelSpec:
    return ModelSpec(
        name="DepthSounder",
        description="Depth sounder, eq. (55): h_d(x, y) + e_h with h_d the bicubic B-spline "
                    "terrain of a UWCBATH1 map (default map in resources/)",
        equations=_depth_sounder,
        inputs=(
            Var("x", "m", 0.0, "East position"),
            Var("y", "m", 0.0, "North position"),
            Var("e_h", "m", 0.0, "Measurement noise on the depth"),
            Var("offset_h", "m", 0.0, "Tide or depth-bias offset added to the depth"),
            Var("u_o", None, 0.0, "Standard normal selecting outliers and multipath returns"),
            Var("e_o", None, 0.0, "Standard normal scaling an outlier"),
        ),
        params=(
            Var("outlierProb", None, 0.0, "Probability of an outlier return"),
            Var("outlierStd", "m", 0.0, "Standard deviation of an outlier's extra error"),
            Var("multipathProb", None, 0.0, "Probability of a multipath return"),
            Var("multipathFactor", None, 2.0, "Depth of a multipath return / true depth"),
            Var("vehicleDepth", "m", 0.0, "Vehicle depth (altitude = depth - vehicleDepth)"),
        ),
        calc_params=(
            Var("map_xmin", "m", description="Map extent: smallest x"),
            Var("map_xmax", "m", description="Map extent: largest x"),
            Var("map_ymin", "m", description="Map extent: smallest y"),
            Var("map_ymax", "m", description="Map extent: largest y"),
        ),
        outputs=(Var("depth_m", "m", 0.0, "Measured depth (positive down)"),
                 Var("altitude", "m", 0.0, "True altitude above the seafloor (no noise)")),
        strings=(
            Var("mapFile", None, "", "Path of a UWCBATH1 coefficient file (empty: the "
                "default map in the FMU's resources)"),
        ),
        externals=("terrain_depth",),
        external_deps=(("x", "y", "mapFile"),),
        kind="bathymetry",
        resources=(DEFAULT_MAP_FILE,),
    )


MODELS: dict[str, Callable[[], ModelSpec]] = {
    "AUVKinematics": _auv_spec,
    "DVL": _dvl_spec,
    "DepthSounder": _depth_sounder_spec,
    "ConstantVelocity": _cv_spec,
}


def get_spec(name: str) -> ModelSpec:
    """The specification of model ``name`` (FMUError listing the valid names otherwise)."""
    try:
        return MODELS[name]()
    except KeyError:
        raise FMUError(f"unknown FMU model {name!r} (valid: {', '.join(MODELS)})") from None
