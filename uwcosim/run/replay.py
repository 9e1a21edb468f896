"""A replay: the rows of a recorded file as the steps of a run, for the same observers.

:class:`ReplaySource` plays the master's role for the observers of a run
(:mod:`uwcosim.master.observer`): it calls ``on_step(k, view)`` of each, in order, at
``k = 0`` and after every step, where step ``k`` is row ``k`` of the
:class:`~uwcosim.scenario.replay.Recording` (:func:`uwcosim.scenario.replay.read_recording`).
Its view (:class:`ReplayView`) shows the same things a master's does: ``t`` (the row's time
stamp, as the file gives it), the bus (the controls held over the step that ended at the row,
``controls.NAME``, and the reference, under the ``[model] truth`` names), and the
measurement (NaN where lost); its ``dt`` is ``t_k - t_{k-1}``, which the filters predict over.
So the estimator bank, the log recorder, the density snapshots and the signal guard run
unchanged (:func:`uwcosim.run.simulate.simulate` composes a replay as it does a simulation).

The source also answers what :func:`~uwcosim.run.simulate.simulate` asks of a master (seed,
slots, the sensors' names, :meth:`slot`, :meth:`step_at`, timing, an empty set of FMUs), and
:meth:`record` is its part of ``simulation.json``.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np

from uwcosim.core.errors import ScenarioError
from uwcosim.master.measurement import Measurement
from uwcosim.master.observer import Observer, StepView
from uwcosim.scenario.geo import position_signals, scenario_frame
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.replay import Recording, read_recording


class ReplaySensors:
    """The measurement layout of a replay (what the run layer reads of a master's sensor
    bank): the components' names and the sensor of each."""

    def __init__(self, names: list[str], sensor_of: list[str]) -> None:
        self.names = list(names)
        self.sensor_of = list(sensor_of)


class ReplayTotal(NamedTuple):
    """What a whole replay spans (a progress bar's total): its steps (the rows after the
    first), the first and last time stamps, the file's name."""

    steps: int
    t_first: float
    t_last: float
    file: str


class ReplayView(StepView):
    """A master's view of a replay's current row; ``dt`` is the gap since the previous one,
    ``total`` what the whole replay spans."""

    __slots__ = ("_source",)

    def __init__(self, source: ReplaySource) -> None:
        super().__init__(source)
        self._source = source

    @property
    def dt(self) -> float:
        return self._source.dt

    @property
    def total(self) -> ReplayTotal:
        rec = self._source.recording
        return ReplayTotal(rec.steps, float(rec.time[0]), float(rec.time[-1]), rec.path.name)


class ReplaySource:
    """Steps through a recording, calling the observers like a master (module docstring)."""

    #: no FMU: the parts of a master's interface the run layer reads
    nodes: tuple = ()
    out_vars: dict = {}
    noise_free: dict = {}
    terminated = None
    busy = None

    def __init__(self, recording: Recording, seed: int, name: str = "replay",
                 where: str = "replay", sensor_of: list[str] | None = None) -> None:
        self.recording = recording
        self.seed = int(seed)
        self.name, self.where = name, where
        rec = recording
        self.time = rec.time
        self.t0 = float(rec.time[0])
        dt = np.diff(rec.time)
        #: the median gap (the nominal step the summary reports)
        self.h = float(np.median(dt))
        self.n_steps = rec.steps
        self.slots: dict[str, int] = {}
        for c in rec.control_names:
            self.slots[f"controls.{c}"] = len(self.slots)
        for r in rec.reference_names:
            self.slots.setdefault(r, len(self.slots))
        self._u_slots = np.array([self.slots[f"controls.{c}"] for c in rec.control_names],
                                 dtype=np.intp)
        self._r_slots = np.array([self.slots[r] for r in rec.reference_names], dtype=np.intp)
        self.bus = np.zeros(len(self.slots))
        self.native: dict[int, object] = {}
        self.text: dict[int, str] = {}
        #: no array signal and no 64-bit integer in a recording (what the recorder asks)
        self.shapes: dict[str, tuple[int, ...]] = {}
        self.exact: dict[int, tuple[int, bool]] = {}
        self.xbus = np.zeros(0, dtype=np.int64)
        #: no FMU (what the log's pattern check asks)
        self.adapters: dict = {}
        self.unopened: frozenset[str] = frozenset()
        self.sensors = ReplaySensors(list(rec.measurement_names),
                                     sensor_of or list(rec.measurement_names))
        self.observers: list[Observer] = []
        self.k = 0
        self.master_time_s = 0.0
        self._view: ReplayView | None = None

    # -- what observers read ----------------------------------------------------------------
    @property
    def t(self) -> float:
        return float(self.time[self.k])

    @property
    def dt(self) -> float:
        """``t_k - t_{k-1}`` (0 at ``k = 0``)."""
        return float(self.time[self.k] - self.time[self.k - 1]) if self.k else 0.0

    def measurement(self) -> Measurement:
        rec = self.recording
        return Measurement(self.k, self.t, rec.z[self.k], rec.received[self.k])

    def value(self, name: str) -> float:
        return float(self.bus[self.slots[name]])

    def signal(self, name: str) -> float:
        return float(self.bus[self.slots[name]])

    def view(self) -> ReplayView:
        if self._view is None:
            self._view = ReplayView(self)
        return self._view

    # -- what the run layer asks of a master --------------------------------------------------
    def slot(self, name: str, key: str) -> int:
        """The bus slot of ``name`` (a truth signal, ``controls.NAME``)."""
        if name not in self.slots:
            raise ScenarioError(f"{self.where}: key '{key}': {name!r} is not a signal of the "
                                f"replay (signals: {', '.join(self.slots)})")
        return self.slots[name]

    def step_at(self, t: float) -> int:
        """The first row at or after ``t`` (the last row for a later time)."""
        return min(int(np.searchsorted(self.time, t - 1e-9 * max(self.h, 1.0))), self.n_steps)

    def signal_dtype(self, name: str) -> np.dtype:
        return np.dtype(np.float64)

    def fmu_hashes(self) -> dict[str, str]:
        return {}

    def variable_maps(self) -> dict:
        return {}

    def me_solvers(self) -> dict:
        return {}

    def timing(self) -> dict[str, float]:
        return {"replay_s": self.master_time_s}

    def stopped_between_steps(self) -> bool:
        return False

    def close(self) -> None:
        """Nothing to free (the recording is in memory)."""

    # -- stepping ----------------------------------------------------------------------------
    def _load(self, k: int) -> None:
        rec = self.recording
        if self._u_slots.size:
            self.bus[self._u_slots] = rec.u[k]
        if self._r_slots.size:
            self.bus[self._r_slots] = rec.reference[k]

    def notify(self) -> None:
        view = self.view()
        for obs in self.observers:
            obs.on_step(self.k, view)

    def initialize(self, start_overrides: dict | None = None) -> None:
        """Row 0: the start (the observers' ``k = 0``)."""
        self.k = 0
        self._load(0)
        self.notify()

    def step(self) -> None:
        """The next row: ``t_{k-1} -> t_k``, then the observers."""
        if self.k >= self.n_steps:
            raise ScenarioError(f"replay already at its last row (t={self.t:g})")
        c0 = time.perf_counter()
        self.k += 1
        self._load(self.k)
        self.master_time_s += time.perf_counter() - c0
        self.notify()

    def run_until(self, t: float = math.inf) -> None:
        """Step through the rows with time stamps up to ``t`` (default: every row)."""
        while self.k < self.n_steps and self.time[self.k + 1] <= t:
            self.step()

    def record(self, status: str, error: str) -> dict:
        """The replay's part of ``simulation.json`` (as a master's run record: status, steps,
        times, timing; ``replay``: the file and its time stamps)."""
        k = max(self.k, 1)
        return {
            "scenario": self.name, "seed": self.seed, "status": status, "error": error,
            "steps": self.k, "step_s": self.h, "start_time_s": self.t0, "end_time_s": self.t,
            "timing": {"replay_s": round(self.master_time_s, 6),
                       "master_overhead_per_step_s": self.master_time_s / k,
                       "fmus_per_step_s": 0.0},
            "fmus": {}, "estimators": {}, "replay": self.recording.metadata(),
        }


def replay_source(loaded: LoadedScenario, seed: int | None,
                  measurement_names: tuple[str, ...]) -> ReplaySource:
    """The replay of a loaded ``[replay]`` scenario, for the filters' model whose measurement
    components are ``measurement_names`` (in order). Reads and checks the file."""
    spec = loaded.spec
    where = str(loaded.path)
    m = spec.model
    frame = scenario_frame(loaded)
    start = None
    geo = spec.geo
    if geo is not None and geo.start is not None and frame is not None:
        pos = position_signals(spec)
        if pos is not None:
            x, y = frame.to_xy(geo.start.lat, geo.start.lon)
            start = (pos[0], pos[1], float(x), float(y))
    run = spec.run
    recording = read_recording(
        spec.replay, loaded.base_dir, where, measurements=measurement_names,
        controls=list(m.controls) if m is not None else [],
        reference=list(m.truth) if m is not None else [], frame=frame,
        start_time=run.start_time if "start_time" in run.model_fields_set else None,
        duration=run.duration, start_position=start)
    sensor_of = []
    if m is not None:
        owner = {o: s for s in m.sensors for o in spec.sensors[s].outputs}
        sensor_of = [owner.get(n, n) for n in measurement_names]
    return ReplaySource(recording, run.seed if seed is None else seed, spec.name, where,
                        sensor_of)
