"""A plain description of a co-simulation system, the master's only input.

:class:`System` lists the FMUs (:class:`FMU`: archive, interface, solver, period, parameters,
start values, variable map), the connections between their variables, the sources the master
drives inputs with (table or waypoint controls, white noise), the sensors and the time grid. The
scenario loader produces one (:func:`from_scenario`); a Python user builds one in code::

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

Controls, noise and sensors are the scenario's own records (:class:`Control`, :class:`Noise`,
:class:`Sensor`: pydantic models, checked when built). Nothing here touches an FMU: names are
checked against the FMUs' model descriptions when the :class:`~uwcosim.master.master.Master`
is built, with one-line errors that name ``where`` (the scenario file, or ``"system"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from uwcosim.scenario.schema import ControlSpec as Control
from uwcosim.scenario.schema import NoiseSpec as Noise
from uwcosim.scenario.schema import SensorSpec as Sensor

if TYPE_CHECKING:
    from uwcosim.scenario.load import LoadedScenario

__all__ = ["FMU", "Control", "Noise", "Sensor", "System", "Termination", "from_scenario"]


@dataclass
class FMU:
    """One FMU of a system (the keys of a scenario's ``[fmus.NAME]``)."""

    path: str | Path
    interface: Literal["cs", "me"] = "cs"
    #: ME only: ``rk4`` (fixed step, ``substeps`` per communication step) or ``adaptive``
    solver: str = "rk4"
    substeps: int = 1
    #: communication period as an integer multiple of the system's step
    period: int = 1
    rtol: float = 1e-8
    #: values of any FMI type by variable name (TOML-like: float, int, bool, str, list of float)
    parameters: dict[str, Any] = field(default_factory=dict)
    start: dict[str, Any] = field(default_factory=dict)
    #: roles -> FMU variables (a TOML file name or the entries; :mod:`uwcosim.master.varmap`)
    map: str | dict | None = None
    role: str | None = None
    #: per-call time limit (s): the FMU then runs in a worker process
    timeout_s: float | None = None


@dataclass
class System:
    """FMUs, connections, sources, sensors and the time grid ``t = start_time + k*step``."""

    fmus: dict[str, FMU]
    step: float
    duration: float
    start_time: float = 0.0
    seed: int = 0
    #: ``[("fmu.output", "fmu.input"), ...]``
    connections: list[tuple[str, str]] = field(default_factory=list)
    controls: dict[str, Control] = field(default_factory=dict)
    noise: dict[str, Noise] = field(default_factory=dict)
    sensors: dict[str, Sensor] = field(default_factory=dict)
    #: the sensors whose outputs form the measurement vector ``z``, in order (None: all;
    #: :mod:`uwcosim.master.measurement`)
    measured: list[str] | None = None
    #: what an FMU's request to stop means: ``"stop"`` (status terminated) or ``"error"``
    stop_on_terminate: Literal["stop", "error"] = "stop"
    name: str = "system"
    #: relative FMU and map paths are relative to this folder (default: the working folder)
    base_dir: Path | None = None
    #: prefix of error messages (the scenario file)
    where: str = "system"

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


def from_scenario(loaded: LoadedScenario) -> System:
    """The system of a loaded scenario (:class:`~uwcosim.scenario.load.LoadedScenario`)."""
    spec = loaded.spec
    fmus = {
        name: FMU(path=f.path, interface=f.interface, solver=f.solver, substeps=f.substeps,
                  period=f.period, rtol=f.rtol, parameters=dict(f.parameters),
                  start=dict(f.start), map=f.map, role=f.role, timeout_s=f.timeout_s)
        for name, f in spec.fmus.items()
    }
    return System(
        fmus=fmus, step=spec.run.step, duration=spec.run.duration,
        start_time=spec.run.start_time, seed=spec.run.seed,
        connections=[tuple(c) for c in spec.connections], controls=dict(spec.controls),
        noise=dict(spec.noise), sensors=dict(spec.sensors),
        measured=list(spec.model.sensors) if spec.model is not None else [],
        stop_on_terminate=spec.run.stop_on_terminate, name=spec.name,
        base_dir=loaded.base_dir, where=str(loaded.path),
    )
