"""A plain description of a co-simulation system, the master's only input.

:class:`System` lists the FMUs (:class:`FMU`: archive, interface, solver, period, parameters,
start values, variable map), the connections between their variables, the sources the master
drives inputs with (:class:`Control`: table or waypoint controls; :class:`Noise`: white noise),
the sensors (:class:`Sensor`, with a :class:`BernoulliLoss` or :class:`GilbertElliottLoss`
model) and the time grid. The scenario layer converts a scenario into one
(:func:`uwcosim.scenario.system.to_system`) and its schema reuses these types; a Python user
builds one in code::

    from uwcosim.master import FMU, Control, Master, System

    system = System(
        fmus={"src": FMU("Feedthrough.fmu"), "ball": FMU("BouncingBall.fmu", interface="me")},
        connections=[("src.y", "ball.u")],
        controls={"u": Control(target="src.u", table=[[0, 0.0], [1, 1.0]])},
        step=0.01, duration=3.0,
    )
    m = Master(system, seed=1)
    m.initialize()
    m.run_until(3.0)
    m.close()

The master algorithm (``algorithm``), what an algebraic loop means (``algebraic_loops``) and its
solver's ``loop_tolerance`` and ``loop_max_iterations`` are fields of the system too.

The FMU, source and sensor types are validated dataclasses (pydantic): types are strict (a
string is never taken for a number), unknown keywords, NaN and infinity are refused, and the
checks that need no FMU (one kind of control, one PSD per target, one sigma per noise input)
run when one is built. Nothing here touches an FMU: names are checked against the FMUs' model
descriptions when the :class:`~uwcosim.master.master.Master` is built, with one-line errors
that name ``where`` (the scenario file, or ``"system"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal

from pydantic import (
    ConfigDict,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    StrictStr,
    model_validator,
)
from pydantic.dataclasses import dataclass as record

__all__ = ["FMU", "BernoulliLoss", "Connection", "ConnectionTransform", "Control",
           "GilbertElliottLoss", "Loss", "Noise", "Sensor", "System", "Termination",
           "table_problem"]

#: the validation of every record: unknown keywords, NaN and infinity refused
RECORD_CONFIG = ConfigDict(extra="forbid", allow_inf_nan=False)

# Strict types: a string is never taken for a number, a float never for an integer; an
# integer is a valid float.
Float, Int, Bool, Str = StrictFloat, StrictInt, StrictBool, StrictStr
Scalar = StrictFloat | StrictInt | StrictBool | StrictStr
#: a start value or parameter: any FMI scalar, or an array (FMI 3 arrays)
Value = Scalar | list[StrictFloat | StrictInt | StrictBool]
PositiveFloat = Annotated[StrictFloat, Field(gt=0)]
NonNegativeFloat = Annotated[StrictFloat, Field(ge=0)]
PositiveInt = Annotated[StrictInt, Field(ge=1)]
Probability = Annotated[StrictFloat, Field(ge=0.0, le=1.0)]


@record(config=RECORD_CONFIG)
class FMU:
    """One FMU of a system (the keys of a scenario's ``[fmus.NAME]``)."""

    path: Str | Path
    interface: Literal["cs", "me"] = "cs"
    #: ME only: ``rk4`` (fixed step, ``substeps`` per communication step), ``adaptive``
    #: (DOP853) or ``cvode`` (CVode even without events); an FMU with events uses CVode
    solver: Literal["rk4", "adaptive", "cvode"] = "rk4"
    substeps: PositiveInt = 1
    #: communication period as an integer multiple of the system's step
    period: PositiveInt = 1
    rtol: PositiveFloat = 1e-8
    #: values of any FMI type by variable name (TOML-like: float, int, bool, str, list)
    parameters: dict[Str, Value] = field(default_factory=dict)
    start: dict[Str, Value] = field(default_factory=dict)
    #: roles -> FMU variables with unit conversion (a TOML file name or an inline table;
    #: see :mod:`uwcosim.fmi.varmap`); start values may then use the role names
    map: Str | dict[Str, Str | dict[Str, Scalar]] | None = None
    #: role table the map is checked against (default: the FMU's name if it is a role)
    role: Literal["vehicle"] | None = None
    #: per-call time limit (s): the FMU then runs in a worker process, killed on timeout
    timeout_s: PositiveFloat | None = None


@record(config=RECORD_CONFIG, frozen=True)
class ConnectionTransform:
    """A linear transformation on a connection: ``input = factor * output + offset``."""

    factor: Float = 1.0
    offset: Float = 0.0


#: ``(output, input)`` or ``(output, input, ConnectionTransform)``
Connection = tuple[Str, Str] | tuple[Str, Str, ConnectionTransform]


def table_problem(table: list) -> str:
    """Why ``[[t, value], ...]`` is not a control table (empty string if it is one): at least
    one row, times never decreasing, a time at most twice. A time given twice is a step
    discontinuity (the value jumps there), as fmpy's ``simulate_fmu(input=...)`` and
    OMSimulator read input tables."""
    times = [t for t, _ in table]
    if not times:
        return "'table' needs at least one [time, value] row"
    for i, (a, b) in enumerate(zip(times, times[1:]), start=1):
        if b < a:
            return (f"'table': times must not decrease (row {i + 1} has t={b!r} after t={a!r}; "
                    f"a time given twice is a step)")
        if b == a and i + 1 < len(times) and times[i + 1] == b:
            return (f"'table': time {b!r} is given more than twice (twice is a step: the "
                    f"values before and after it)")
    return ""


@record(config=RECORD_CONFIG)
class Control:
    """A control input driven by the master: a time table, or the heading to waypoints.

    ``table`` rows ``[t, value]`` with times never decreasing; a time given twice is a step
    (the value before, then after it: the control takes the second from that time on), as
    fmpy and OMSimulator read time-stamped inputs."""

    target: Str
    table: list[tuple[Float, Float]] | None = None
    waypoints: list[tuple[Float, Float]] | None = None
    interpolation: Literal["linear", "hold"] = "linear"
    position: tuple[Str, Str] = ("vehicle.x", "vehicle.y")
    acceptance_radius: PositiveFloat = 50.0

    @model_validator(mode="after")
    def _one_kind(self) -> Control:
        if (self.table is None) == (self.waypoints is None):
            raise ValueError("give exactly one of 'table' or 'waypoints'")
        if self.table is not None:
            problem = table_problem(self.table)
            if problem:
                raise ValueError(problem)
        if self.waypoints is not None and len(self.waypoints) < 1:
            raise ValueError("'waypoints' needs at least one [x, y] point")
        return self


@record(config=RECORD_CONFIG, frozen=True)
class BernoulliLoss:
    """Each sample is lost independently with probability ``p``."""

    model: Literal["bernoulli"]
    p: Probability = 0.0


@record(config=RECORD_CONFIG, frozen=True)
class GilbertElliottLoss:
    """Bursty losses: a two-state Markov chain (good, bad) with a loss probability in each."""

    model: Literal["gilbert_elliott"]
    p_good_to_bad: Probability
    p_bad_to_good: Probability
    loss_good: Probability = 0.0
    loss_bad: Probability = 1.0


#: a sensor's loss model, chosen by ``model``
Loss = Annotated[BernoulliLoss | GilbertElliottLoss, Field(discriminator="model")]


@record(config=RECORD_CONFIG)
class Noise:
    """White noise of power spectral densities ``psd`` on the inputs ``targets``, held over a
    step (a sample of PSD ``q`` has variance ``q / step``)."""

    targets: list[Str]
    psd: list[NonNegativeFloat]

    @model_validator(mode="after")
    def _same_length(self) -> Noise:
        if len(self.targets) != len(self.psd):
            raise ValueError(f"'psd' has {len(self.psd)} values for {len(self.targets)} targets")
        return self


@record(config=RECORD_CONFIG)
class Sensor:
    """Outputs of FMUs sampled every ``period`` steps, with noise (on the FMU's noise inputs, or
    added to the outputs) and an optional loss model."""

    outputs: list[Str]
    noise_inputs: list[Str] = field(default_factory=list)
    sigma: list[NonNegativeFloat] = field(default_factory=list)
    period: PositiveInt = 1
    loss: Loss | None = None
    #: an FMU output (FMU.variable): a sample is received only when it is nonzero (a DVL's
    #: ``bottom_lock``)
    valid: Str | None = None

    @model_validator(mode="after")
    def _same_length(self) -> Sensor:
        if self.noise_inputs and len(self.noise_inputs) != len(self.sigma):
            raise ValueError(
                f"'sigma' has {len(self.sigma)} values for {len(self.noise_inputs)} noise_inputs"
            )
        if not self.noise_inputs and self.sigma and len(self.sigma) != len(self.outputs):
            raise ValueError(
                f"'sigma' without noise_inputs is additive noise on the outputs: it needs "
                f"{len(self.outputs)} values, got {len(self.sigma)}"
            )
        return self


@dataclass
class System:
    """FMUs, connections, sources, sensors and the time grid ``t = start_time + k*step``."""

    fmus: dict[str, FMU]
    step: float
    duration: float
    start_time: float = 0.0
    seed: int = 0
    #: ``[("fmu.output", "fmu.input"), ...]``
    connections: list[Connection] = field(default_factory=list)
    controls: dict[str, Control] = field(default_factory=dict)
    noise: dict[str, Noise] = field(default_factory=dict)
    sensors: dict[str, Sensor] = field(default_factory=dict)
    #: the sensors whose outputs form the measurement vector ``z``, in order (None: all;
    #: :mod:`uwcosim.master.measurement`)
    measured: list[str] | None = None
    #: variables that are not outputs to read after every step as signals (``fmu.var``:
    #: locals, states, parameters; FMI 3 array elements ``fmu.var[i]`` read the whole array);
    #: names that are outputs already, sources or unknown are left out
    observe: list[str] = field(default_factory=list)
    #: what an FMU's request to stop means: ``"stop"`` (status terminated) or ``"error"``
    stop_on_terminate: Literal["stop", "error"] = "stop"
    #: the master algorithm (:mod:`uwcosim.master.algorithms`): ``"gauss-seidel"`` (units in
    #: dependency order, each from the bus as it is when its turn comes) or ``"jacobi"``
    #: (every unit from the values of the previous communication point)
    algorithm: Literal["gauss-seidel", "jacobi"] = "gauss-seidel"
    #: an algebraic loop between FMUs is solved (``"solve"``: Newton, :mod:`uwcosim.master.loops`)
    #: or an ``"error"`` when the system is built
    algebraic_loops: Literal["solve", "error"] = "solve"
    #: convergence of a loop: every residual ``|r_i| <= loop_tolerance * (1 + |u_i|)``
    loop_tolerance: float = 1e-10
    #: Newton iterations allowed per solve
    loop_max_iterations: int = 50
    name: str = "system"
    #: relative FMU and map paths are relative to this folder (default: the working folder)
    base_dir: Path | None = None
    #: prefix of error messages (the scenario file)
    where: str = "system"
    #: the limit (MiB) of an FMU archive's unpacked size (None: the environment's or 512;
    #: :func:`uwcosim.fmi.archive.unpacked_limit`)
    fmu_max_unpacked_mb: float | None = None

    def resolve(self, path: str | Path) -> Path:
        p = Path(path)
        if p.is_absolute() or self.base_dir is None:
            return p.resolve()
        return (Path(self.base_dir) / p).resolve()


@dataclass(frozen=True)
class Termination:
    """An FMU's request to stop the simulation: who, when, why."""

    fmu: str
    time: float
    reason: str

    def message(self) -> str:
        why = f": {self.reason}" if self.reason else ""
        return f"FMU '{self.fmu}' requested termination at t={self.time:g}{why}"
