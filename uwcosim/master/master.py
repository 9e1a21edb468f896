"""The master algorithm: builds the FMU network of a system and steps it.

The master's input is a :class:`~uwcosim.master.system.System` (FMUs, connections, sources,
sensors, time grid); the scenario layer converts a scenario into one
(:func:`uwcosim.scenario.system.to_system`): the master knows no scenario. Time is an integer count
of base steps: ``t = t0 + k*h``, never accumulated. Each FMU runs at an integer multiple ``period``
of ``h``; FMUs are stepped by the algorithm the system names (:mod:`uwcosim.master.algorithms`:
Gauss-Seidel in dependency order, or Jacobi), in units: one FMU, or the FMUs of an algebraic
loop (solved by :mod:`uwcosim.master.loops`), or model-exchange FMUs integrated together
(:mod:`uwcosim.fmi.coupled`); with Gauss-Seidel and one FMU per unit, the plain loop of
:meth:`Master.step`. Signals live in one flat float64
array, the *bus*: every FMU output (an FMI 3 array: one slot per element) and every source has a
slot, and each FMU input value reads a slot (the layout and wiring: :mod:`uwcosim.master.checks`).
Integer and Boolean values are on the bus as float64 (exact up to 2**53); 64-bit integers also
have an exact copy on the integer side bus :attr:`Master.xbus` (int64; a UInt64 as its bit
pattern), which is what a 64-bit input connected to one reads, so 2**64 - 1 arrives exactly;
narrowing integer connections are checked against the declared ranges at load and, where only a
declaration makes them fit, at each step (a value out of range ends the run). String outputs
have a slot (NaN) and their text in :attr:`Master.text`. Variables named in the system's
``observe`` (locals, states) are read after every step like outputs. Sources
(controls, noise) are sampled from the master's seeded streams in chunks as the run goes
(memory does not depend on the duration); closed-loop sources (waypoints) are evaluated per
step. The sensors (sampling, loss, noise, the measurement vector) are the master's
:class:`~uwcosim.master.measurement.SensorBank` (:attr:`Master.sensors`,
:meth:`Master.measurement`); one FMU bound to the bus is a
:class:`~uwcosim.master.node.Node`.

An FMU that asks to stop (FMI 2 ``fmi2Terminated``, FMI 3 ``terminateSimulation``) ends the run:
:attr:`Master.terminated` holds who, when and why, and :meth:`Master.run_until` returns (or,
with ``stop_on_terminate = "error"``, :class:`~uwcosim.core.errors.FMUError` is raised).

The master owns the folder the FMU archives are unzipped to; :meth:`Master.close` deletes it.

What watches the run is an :class:`~uwcosim.master.observer.Observer` (``on_step(k, view)``
with a read-only :class:`~uwcosim.master.observer.StepView`), called by :meth:`Master.notify`
at the start time and after every step, in the order added.

Step-by-step API::

    m = Master(system, seed=3)
    m.observers.append(PrintX())   # class PrintX: def on_step(self, k, view): ...
    m.initialize()
    m.run_until(100.0)       # or m.step() repeatedly
    m.close()
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from multiprocessing import util as mp_util
from pathlib import Path

import numpy as np

from uwcosim.core import scratch
from uwcosim.core.errors import AlgebraicLoopError, FMUError, ScenarioError, UwcosimError
from uwcosim.fmi import vartypes
from uwcosim.fmi.adapter import FMUAdapter
from uwcosim.fmi.archive import unpacked_limit
from uwcosim.fmi.proxy import ProxyAdapter
from uwcosim.fmi.varmap import ROLES, fmu_unit, load_entries
from uwcosim.master.algorithms import Unit, build_unit, jacobi_keeps, plan, start_value
from uwcosim.master.checks import SystemChecks
from uwcosim.master.measurement import Measurement, SensorBank
from uwcosim.master.node import Node, build_node
from uwcosim.master.observer import Observer, StepView
from uwcosim.master.sources import (
    StageInputs,
    TableControl,
    WaypointHeading,
    control_problem,
    noise_free_sources,
    sample_sources,
)
from uwcosim.master.system import System, Termination


class Master(SystemChecks):
    """Co-simulation of one system with one seed."""

    def __init__(self, system: System, seed: int | None = None,
                 workdir: Path | None = None, check_only: bool = False) -> None:
        """``check_only``: open the FMUs' model descriptions and check the system against them,
        collecting every problem in :attr:`problems` (instead of raising the first); nothing
        is built to run (``uwcosim check``, :mod:`uwcosim.run.preflight`)."""
        if not isinstance(system, System):
            raise TypeError(f"Master takes a uwcosim.master.System, got {type(system).__name__} "
                            f"(a loaded scenario: uwcosim.scenario.to_system(loaded))")
        self.check_only = check_only
        #: the problems found while building (UwcosimError instances)
        self.problems: list[UwcosimError] = []
        self._broken: set[str] = set()  # FMUs that could not be opened
        self.system = system
        self.seed = system.seed if seed is None else int(seed)
        self.h = float(system.step)
        self.t0 = float(system.start_time)
        n = system.duration / self.h
        self.n_steps = int(round(n))
        if abs(n - self.n_steps) > 1e-9 * max(1.0, n):
            raise ScenarioError(f"{self._where('run.duration')}: must be a whole number of "
                                f"steps of {self.h:g} s (got {system.duration:g})")
        self.k = 0
        #: what watches the run (:meth:`notify`), in the order called
        self.observers: list[Observer] = []
        self._view: StepView | None = None
        self.workdir = workdir
        self.master_time_s = 0.0
        self.terminated: Termination | None = None
        self._initialized = False
        self._stopped_inside = False  # an FMU stopped the run between two grid times
        #: the FMU work in progress that spans several FMU calls (instantiation, an
        #: initialization or step loop, a coupled ME step): (fmu, what, t, time.monotonic() at
        #: its start), or None; read by the run-wide watchdog (uwcosim.core.runguard) before
        #: the adapters' record of the single call (uwcosim.core.fmucall)
        self.busy: tuple[str, str, float, float] | None = None
        self.adapters: dict[str, FMUAdapter] = {}
        #: the unzipped FMU archives, deleted by close() (or at process exit)
        self.unzip_root = scratch.make("uwcosim_fmu_")
        self._cleanup = mp_util.Finalize(self, scratch.remove, args=(self.unzip_root,),
                                         exitpriority=0)
        try:
            self._build()
        except BaseException:
            self.close()
            raise

    # -- construction -----------------------------------------------------------------------
    @property
    def unopened(self) -> frozenset[str]:
        """The FMUs that could not be opened (their problems are in :attr:`problems`)."""
        return frozenset(self._broken)

    @property
    def t(self) -> float:
        return self.t0 + self.k * self.h

    def _build(self) -> None:
        """Check every input of the system against the FMUs (all problems, :attr:`problems`),
        raise the first (saying how many more), then build the stepping network."""
        system = self.system
        for name, f in system.fmus.items():
            n = len(self.problems)
            with self._collect():
                self.adapters[name] = self._open(name, f)
            if len(self.problems) > n:
                self._broken.add(name)
        self._init_layout()
        for name, ad in self.adapters.items():
            for out in ad.outputs():
                self._add_output(name, out)
        for signal in system.observe:
            with self._collect():
                self._observe(signal)
        drivers: dict[str, str] = {}  # input signal -> source name (for error messages)
        self.controls: dict[str, object] = {}
        for cname, c in system.controls.items():
            src = TableControl(c) if c.table is not None else WaypointHeading(c)
            self.controls[cname] = src
            self._new_slot(f"controls.{cname}")
            with self._collect():
                if isinstance(src, WaypointHeading):
                    src.pos_slots = [self._numeric_slot(p, f"controls.{cname}.position")
                                     for p in c.position]
            key = f"controls.{cname}.target"
            with self._collect():
                self._check_input(c.target, key, drivers, f"controls.{cname}")
                problem = control_problem(c, self._variable(c.target, key))
                if problem:
                    raise ScenarioError(f"{self._where(key)}: {c.target!r} {problem}")
        #: noise sources none of whose targets the FMU has (a third-party vehicle without
        #: process-noise inputs): the truth runs without them, the filters' model keeps them
        self.noise_free = noise_free_sources(
            system, {n: a for n, a in self.adapters.items() if n not in self._broken})
        for nname, nz in system.noise.items():
            if nname in self.noise_free:
                continue
            for i, tgt in enumerate(nz.targets):
                key = f"noise.{nname}.{i}"
                self._new_slot(key)
                with self._collect():
                    self._check_input(tgt, f"noise.{nname}.targets", drivers, key,
                                      float_only=True)
        for sname, s in system.sensors.items():
            for i, tgt in enumerate(s.noise_inputs):
                key = f"sensornoise.{sname}.{i}"
                self._new_slot(key)
                with self._collect():
                    self._check_input(tgt, f"sensors.{sname}.noise_inputs", drivers, key,
                                      float_only=True)
        for i, conn in enumerate(system.connections):
            with self._collect():
                self._check_connection(i, conn, drivers)
        with self._collect():
            self._complete_arrays()
        for sname, s in system.sensors.items():
            for o in s.outputs:
                with self._collect():
                    self._numeric_slot(o, f"sensors.{sname}.outputs")
            if s.valid is not None:
                with self._collect():
                    self._numeric_slot(s.valid, f"sensors.{sname}.valid")
        self.drivers = drivers
        if not self.problems:
            with self._collect():
                groups = self._plan()
        if self.check_only:
            return
        if self.problems:
            first = self.problems[0]
            if len(self.problems) > 1:
                first.args = (f"{first} (and {len(self.problems) - 1} more; see uwcosim "
                              f"check)",)
            raise first
        self.bus = np.zeros(self.n_slots)
        #: the integer side bus: the exact values of the 64-bit integer signals (a UInt64 as
        #: its bit pattern), at the positions :attr:`exact` gives their bus slots
        self.xbus = np.zeros(len(self.exact), dtype=np.int64)
        #: text of the String signals, by bus slot
        self.text: dict[int, str] = {}
        nodes = {name: self._node(name) for name in self.adapters}
        units, loops, coupled = groups
        #: the units in stepping order (:mod:`uwcosim.master.algorithms`): one FMU each, or the
        #: FMUs of an algebraic loop, or model-exchange FMUs integrated together
        self.units: list[Unit] = []
        for names in units:
            with self._collect():
                self.units.append(build_unit(names, nodes, loops, coupled,
                                             system.loop_tolerance, system.loop_max_iterations))
        if self.problems:
            raise self.problems[0]
        self.nodes: list[Node] = [n for u in self.units for n in u.nodes]
        #: the algebraic loops solved (:class:`~uwcosim.master.graph.Loop`)
        self.loops = loops
        self._jacobi_keep = jacobi_keeps(self.nodes, self.drivers, self.out_vars) \
            if system.algorithm == "jacobi" else {}
        #: one FMU per unit, Gauss-Seidel: the plain stepping loop
        self._plain = system.algorithm == "gauss-seidel" and all(
            len(u.nodes) == 1 and not u.coupled and u.exchange is None for u in self.units)
        self._sample_sources()

    def _plan(self) -> tuple[list[list[str]], list, list[list[str]]]:
        """The units in stepping order, the algebraic loops, the coupled ME systems
        (:func:`uwcosim.master.algorithms.plan`), errors naming the key."""
        in_process = {n for n, a in self.adapters.items() if isinstance(a, FMUAdapter)}
        try:
            conns = [(self.variable_of(c[0]), self.variable_of(c[1]))
                     for c in self.system.connections]
            return plan(self.system, self.adapters, in_process, conns)
        except AlgebraicLoopError as exc:  # refused: run.algebraic_loops = "error"
            raise AlgebraicLoopError(f"{self._where('connections')}: {exc} "
                                     f"(run.algebraic_loops = \"error\")") from None
        except ScenarioError as exc:  # a loop that cannot be solved
            raise ScenarioError(f"{self._where('run.algebraic_loops')}: {exc}") from None

    def _node(self, name: str) -> Node:
        outs = [k.split(".", 1)[1] for k in self.out_vars if k.split(".", 1)[0] == name]
        out_slots = [self.slots[f"{name}.{o}"] + e for o in outs
                     for e in range(vartypes.size(self.out_vars[f"{name}.{o}"]))]
        node = build_node(name, self.adapters[name], self.system.fmus[name].period,
                          self.wiring.get(name, {}), outs, out_slots, self.exact)
        if node.adapter.interface == "me":
            node.input_fn = self._continuous_inputs(node, name)
        return node

    def _open(self, name: str, f) -> FMUAdapter | ProxyAdapter:
        """The adapter of FMU ``name``: in this process, or in a worker when ``timeout_s``."""
        path = self.system.resolve(f.path)
        unzip = str(Path(self.unzip_root) / name)
        try:  # run.fmu_max_unpacked_mb: the limit of the archive's unpacked size
            with unpacked_limit(self.system.fmu_max_unpacked_mb):
                if f.timeout_s is not None and not self.check_only:  # checks call no FMU
                    ad = ProxyAdapter(name, path, f.interface, f.solver, f.substeps, f.rtol,
                                      f.timeout_s, unzip_dir=unzip)
                else:
                    ad = FMUAdapter(name, path, f.interface, f.solver, f.substeps, f.rtol,
                                    unzip_dir=unzip)
        except FMUError as exc:  # missing, corrupt, another platform: say which key
            raise FMUError(f"{exc} [{self._where(f'fmus.{name}.path')}]") from None
        self.adapters[name] = ad  # closed with the others if what follows is refused
        if f.map is not None:
            base = self.system.base_dir or Path.cwd()
            entries, where, prefix = load_entries(f.map, Path(base), self.system.where,
                                                  f"fmus.{name}.map")
            role = f.role or (name if name in ROLES else None)
            ad.use_map(entries, role, where, prefix)
        # start values and parameters: every type, checked against the model description now
        for kind, values in (("parameters", f.parameters), ("start", f.start)):
            ad.check_values(values, f"{self.system.where}: key 'fmus.{name}.{kind}'")
        return ad

    def _continuous_inputs(self, node: Node, name: str) -> Callable | None:
        """For ME FMUs: table controls of Real inputs are evaluated at the integrator's stage
        times (discrete inputs are set at communication points only)."""
        pairs = []
        ad = self.adapters[name]
        b = node.inputs
        for i, pos in zip(b.names, b.offsets):
            src = self.drivers.get(f"{name}.{i}", "")
            if src.startswith("controls.") and vartypes.is_continuous_input(ad.variables[i]):
                ctl = self.controls[src.split(".", 1)[1]]
                if isinstance(ctl, TableControl):
                    pairs.append((pos, ctl))
        return StageInputs(pairs) if pairs else None

    def _sample_sources(self) -> None:
        """The seeded sources of a run: controls, noise, and the sensors (:attr:`sensors`)."""
        system, n = self.system, self.n_steps + 1
        self.sources, self.source_slots, self.dynamic = sample_sources(
            system, self.controls, self.slots, self.seed, n, skip=self.noise_free)
        outputs = {sname: np.array([self._numeric_slot(o, f"sensors.{sname}.outputs")
                                    for o in s.outputs], dtype=np.intp)
                   for sname, s in system.sensors.items()}
        inputs = {sname: [self.slots[f"sensornoise.{sname}.{i}"]
                          for i in range(len(s.noise_inputs))]
                  for sname, s in system.sensors.items()}
        measured = list(system.sensors) if system.measured is None else list(system.measured)
        key = "measured"
        for sname in measured:
            s = system.sensors.get(sname)
            if s is None:
                raise ScenarioError(f"{self._where(key)}: unknown sensor {sname!r} "
                                    f"(sensors: {', '.join(system.sensors)})")
            if s.sigma and not s.noise_inputs and len(s.sigma) != len(s.outputs):
                raise ScenarioError(f"{self._where(f'sensors.{sname}.sigma')}: additive noise "
                                    f"needs one sigma per output ({len(s.outputs)})")
        valid = {sname: self._numeric_slot(s.valid, f"sensors.{sname}.valid")
                 for sname, s in system.sensors.items() if s.valid is not None}
        #: sampling, loss, noise and assembly of the measurements
        self.sensors = SensorBank(system.sensors, outputs, inputs, measured, self.seed, n,
                                  valid_slots=valid)

    def reset(self, seed: int | None = None) -> None:
        """Prepare another run of the same system (``seed`` or the system's): new noise,
        losses and initial time; FMU instances are kept and reset by :meth:`initialize`."""
        self.seed = self.system.seed if seed is None else int(seed)
        for ctl in self.controls.values():
            if isinstance(ctl, WaypointHeading):
                ctl.reset()
        self._sample_sources()
        self.bus[:] = 0.0
        self.xbus[:] = 0
        self.text.clear()
        self.k = 0
        self.observers = []
        self.master_time_s = 0.0
        self.terminated = None
        self._stopped_inside = False
        for node in self.nodes:
            node.time_s = 0.0
        self._initialized = False

    # -- signals ----------------------------------------------------------------------------
    def signal(self, name: str) -> float:
        slot = self.slots.get(name)
        return float(self.bus[slot if slot is not None else self.slot(name, "signal")])

    def signals(self, names: list[str]) -> np.ndarray:
        return self.bus[[self.slots[n] if n in self.slots else self.slot(n, "signal")
                         for n in names]]

    def measurement(self) -> Measurement:
        """The measurement of the current step (:class:`~uwcosim.master.measurement.SensorBank`:
        the measured sensors' outputs with their noise, NaN where not received)."""
        return self.sensors.measure(self.k, self.t, self.bus)

    def value_at(self, slot: int) -> str | int | bool | float | None:
        """The current value of a bus slot as its own type (None: a slot without a type)."""
        ex = self.exact.get(slot)
        if ex is not None:
            x = self.xbus[ex[0]]
            return int(x.view(np.uint64)) if ex[1] else int(x)
        if slot in self.text:
            return self.text[slot]
        return None

    def value(self, name: str) -> str | int | bool | float:
        """The current value of a signal (or array element) as its own type (str, int, bool
        or float)."""
        slot = self.slots.get(name)
        var = self.out_vars.get(name)
        if slot is None:
            slot = self.slot(name, "value")
            var = self._element(name, "value")[1]
        if var is None:
            return float(self.bus[slot])
        typed = self.value_at(slot)
        if typed is not None:
            return typed
        kind = vartypes.kind(var)
        x = self.bus[slot]
        return int(x) if kind == "int" else bool(x) if kind == "bool" else \
            ("" if kind == "string" else float(x))

    @property
    def native(self) -> dict[int, object]:
        """The exact values of the String and 64-bit integer signals, by bus slot (built on
        demand; the recorder reads :attr:`xbus` and :attr:`text` directly)."""
        out: dict[int, object] = {slot: self.value_at(slot) for slot in self.exact}
        out.update(self.text)
        return out

    def signal_dtype(self, name: str) -> np.dtype:
        """numpy dtype of a signal (float64 for sources; the FMI type for FMU outputs and
        observed variables, array elements included)."""
        var = self.out_vars.get(name)
        if var is None and name not in self.slots:
            var = self._element(name, "signal")[1]
        if var is None:
            return np.dtype(np.float64)
        return np.dtype(vartypes.numpy_dtype(var))

    def signal_unit(self, name: str) -> str | None:
        """The unit of a signal's bus values (an array element: its array's): an FMU output's
        or observed variable's declared unit (its own or its declared type's; a variable map's
        role: the role's unit), a source's the unit of the FMU input it drives; None when
        nothing declares one."""
        base = name.split("[", 1)[0]
        fmu, _, var = base.partition(".")
        ad = self.adapters.get(fmu)
        if ad is not None and var in ad.variables:
            alias = ad.varmap.aliases.get(var)
            if alias is not None and alias.our_unit:
                return alias.our_unit
            return fmu_unit(ad.variables[var])
        for (f, v), by in self._wired_by.items():
            if base in by:
                return self.signal_unit(f"{f}.{v}")
        return None

    # -- running ----------------------------------------------------------------------------
    def initialize(self, start_overrides: dict[str, dict] | None = None) -> None:
        """Instantiate and initialize every FMU at ``t0`` and read the outputs at ``t0``.

        FMUs are initialized in stepping order; each one's inputs (sources at ``t0`` and the
        outputs of the FMUs before it) are set in initialization mode, with its start values,
        so that its outputs at ``t0`` already see them (as ``fmpy.simulate_fmu`` does). The FMUs
        of an algebraic loop are held in initialization mode together while the loop is solved
        (from the loop inputs' start values); model-exchange FMUs integrated together get
        their joint integrator."""
        t_stop = self.t0 + self.n_steps * self.h
        self.k = 0
        self.terminated = None
        self._load_sources(0)
        overrides = start_overrides or {}
        for unit in self.units:
            ex = unit.init_exchange
            guesses = ex.unknowns() if ex is not None else set()
            for node in unit.nodes:
                self._instantiate(node, overrides, t_stop, guesses, hold=ex is not None)
            if ex is not None:
                self._solve_init(unit, ex)
            for system in unit.coupled:
                system.start(self.t0, t_stop)
        self._initialized = True
        for node in self.nodes:  # a request to stop in the initial event iteration
            if node.adapter.terminated is not None:
                self._stop(node.adapter)
                break
        self.notify()
        self._stop_as_error()

    def _instantiate(self, node: Node, overrides: dict, t_stop: float,
                     guesses: set[tuple[str, str]], hold: bool) -> None:
        """Instantiate and initialize one FMU (``hold``: leave it in initialization mode)."""
        name = node.adapter.name
        f = self.system.fmus[name]
        params = dict(f.parameters)
        params.update(overrides.get(name, {}))
        node.set_text(self.text)
        node.gather(self.bus, self.xbus, self.t0)
        view = node.inputs.view
        for j in self._jacobi_keep.get(name, ()):  # Jacobi: no previous point to take it from
            view[j] = start_value(node, self.system.fmus[node.adapter.name], j)
        for j, var in zip(node.inputs.offsets, node.inputs.names):
            if (name, var) in guesses:  # the guess of an algebraic loop: its start value
                view[j] = start_value(node, self.system.fmus[node.adapter.name], j)
        start = {**f.start, **node.input_values()}  # driven inputs: their driver
        self.busy = (name, "instantiate", self.t0, time.monotonic())
        try:
            node.adapter.instantiate(params, start, self.t0, t_stop, hold=hold) if hold else \
                node.adapter.instantiate(params, start, self.t0, t_stop)
        except FMUError as exc:
            raise FMUError(f"{exc} [{self._where(f'fmus.{name}')}]") from None
        finally:
            self.busy = None
        if hold:
            return
        node.adapter.set_inputs(node.inputs, self.t0)
        node.read(self.t0, self.bus, self.xbus, self.text)

    def _solve_init(self, unit: Unit, ex) -> None:
        """The algebraic loops of ``unit`` in initialization mode, then its FMUs leave it."""
        self.busy = (unit.nodes[0].adapter.name, "initialization (algebraic loop)", self.t0,
                     time.monotonic())
        try:
            ex.run(self.t0, "init")
            for node in unit.nodes:
                node.read(self.t0, self.bus, self.xbus, self.text)
            for node in unit.nodes:
                node.adapter.exit_initialization()
        finally:
            self.busy = None
        for node in unit.nodes:
            node.gather(self.bus, self.xbus, self.t0)
            for j in self._jacobi_keep.get(node.adapter.name, ()):
                node.inputs.view[j] = start_value(node, self.system.fmus[node.adapter.name], j)
            node.adapter.set_inputs(node.inputs, self.t0)
            node.read(self.t0, self.bus, self.xbus, self.text)

    def _stop(self, ad) -> None:
        """Record ``ad``'s request to stop (:meth:`_stop_as_error` raises once the step, or the
        initialization, is complete and observed)."""
        t, reason = ad.terminated
        self.terminated = Termination(ad.name, float(t), str(reason))

    def _stop_as_error(self) -> None:
        """With ``stop_on_terminate = "error"``, a request to stop is an :class:`FMUError`:
        raised after the observers saw the step (the log keeps the same rows as with
        ``"stop"``; a stop between two grid times: :meth:`stopped_between_steps`)."""
        if self.terminated is not None and self.system.stop_on_terminate == "error":
            raise FMUError(f"{self.terminated.message()} (run.stop_on_terminate = \"error\")")

    def _load_sources(self, k: int) -> None:
        if self.source_slots.size:
            self.bus[self.source_slots] = self.sources.row(k)
        self.sensors.load_inputs(k, self.bus)
        for slot, ctl in self.dynamic:
            x, y = self.bus[ctl.pos_slots]
            self.bus[slot] = ctl.value_at(x, y)

    def step(self) -> None:
        """Advance one base step: ``t_k -> t_{k+1}``, then :meth:`notify` the observers.

        When an FMU asks to stop inside the step, :attr:`terminated` is set: if it reached the
        end of the step the others complete it and the observers are notified; otherwise the run
        stops at ``t_k`` (the bus then holds that FMU's outputs at its termination time)."""
        if not self._initialized:
            raise ScenarioError("Master.step() called before initialize()")
        if self.terminated is not None:
            raise ScenarioError(f"run already ended: {self.terminated.message()}")
        if self.k >= self.n_steps:
            raise ScenarioError(f"run already at its end t={self.t:g} (duration reached)")
        c0 = time.perf_counter()
        k = self.k
        self._load_sources(k)
        t_k = self.t0 + k * self.h
        t_next = self.t0 + (k + 1) * self.h
        if not self._plain:
            fmu_time = self._step_units(k, t_next)
            self.master_time_s += time.perf_counter() - c0 - fmu_time
            if self._stopped_inside:
                self._stop_as_error()
                return
            self.k = k + 1
            self.notify()
            self._stop_as_error()
            return
        fmu_time = 0.0
        for node in self.nodes:
            p = node.period
            if (k + 1) % p:
                continue
            a = time.perf_counter()
            if node.str_inputs:
                node.set_text(self.text)
            node.gather(self.bus, self.xbus, t_k)
            ad = node.adapter
            # the step is the difference of two grid times (as fmpy's loop does), so the FMU
            # lands on t_{k+1} without accumulating rounding
            t_start = self.t0 + (k + 1 - p) * self.h
            # timed by the watchdog through the adapter's record (uwcosim.core.fmucall)
            t_reached = ad.do_step(t_start, t_next - t_start, node.inputs, node.input_fn)
            stop = ad.terminated
            if stop is not None:
                t_reached = stop[0]
            node.read(t_next if t_reached is None else t_reached, self.bus, self.xbus,
                      self.text)
            dt = time.perf_counter() - a
            node.time_s += dt
            fmu_time += dt
            if stop is not None and self.terminated is None:
                self._stop(ad)
                if stop[0] < t_next - 1e-9 * self.h:  # stopped inside the step: not on the grid
                    self._stopped_inside = True
                    self.master_time_s += time.perf_counter() - c0 - fmu_time
                    self._stop_as_error()
                    return
        self.k = k + 1
        self.master_time_s += time.perf_counter() - c0 - fmu_time
        self.notify()
        self._stop_as_error()

    # -- units: loops, coupled model exchange, Jacobi (:mod:`uwcosim.master.algorithms`) ------
    def _step_units(self, k: int, t_next: float) -> float:
        """One step of the units: Gauss-Seidel (each unit gathers its inputs when its turn
        comes) or Jacobi (all gather first, from ``t_k``); the FMUs' time spent."""
        ticking = [u for u in self.units if not (k + 1) % u.period]
        t_k = self.t0 + k * self.h
        reached: dict[int, tuple[float, bool]] = {}
        clock = time.perf_counter
        if self.system.algorithm != "jacobi":
            a = clock()
            for unit in ticking:
                self._gather(unit, t_k)
                self._advance(unit, k, t_next, reached)
                self._finish(unit, t_next, reached)
                if self._stopped_inside:
                    break
            return self._share(ticking, clock() - a)
        a = clock()
        for unit in ticking:
            self._gather(unit, t_k)
        for unit in ticking:
            self._advance(unit, k, t_next, reached)
        for unit in ticking:  # a stop inside the step: that FMU's outputs, the others' at t_k
            for node in unit.nodes:
                stop = node.adapter.terminated
                if stop is not None and stop[0] < t_next - 1e-9 * self.h:
                    node.read(stop[0], self.bus, self.xbus, self.text)
                    self._stop(node.adapter)
                    self._stopped_inside = True
                    return self._share(ticking, clock() - a)
        for unit in ticking:
            self._finish(unit, t_next, reached)
        return self._share(ticking, clock() - a)

    @staticmethod
    def _share(units: list[Unit], dt: float) -> float:
        """Split the FMUs' time of a step among the FMUs that stepped (equal shares)."""
        n = sum(len(u.nodes) for u in units)
        for unit in units:
            for node in unit.nodes:
                node.time_s += dt / n
        return dt

    def _gather(self, unit: Unit, t_k: float) -> None:
        for node in unit.gathered:
            if node.str_inputs:
                node.set_text(self.text)
            node.gather(self.bus, self.xbus, t_k)
        for system in unit.coupled:
            system.exchange.mark_fresh()

    def _advance(self, unit: Unit, k: int, t_next: float, reached: dict) -> None:
        """Step the FMUs of ``unit`` to ``t_next`` (``reached``: by ``id(node)``, the time it
        reached and whether its outputs binding was read there already)."""
        t_start = self.t0 + (k + 1 - unit.period) * self.h
        for system in unit.coupled:
            self.busy = (system.nodes[0].adapter.name, system.call, t_start, time.monotonic())
            try:
                t_reached = system.integrator.step(t_start, t_next - t_start)
            finally:
                self.busy = None
                if system.integrator.terminated is not None:
                    for node in system.nodes:
                        node.adapter.sync_terminated()
            # the exchange at the end of the step read the outputs of the fresh ones at t_next
            fresh = system.fresh if system.integrator.terminated is None else ()
            for node in system.nodes:
                reached[id(node)] = (t_reached, id(node) in fresh)
        for node in unit.single:
            ad = node.adapter
            t_reached = ad.do_step(t_start, t_next - t_start, node.inputs, node.input_fn)
            stop = ad.terminated
            reached[id(node)] = (stop[0] if stop is not None else (
                t_next if t_reached is None else t_reached), False)

    def _finish(self, unit: Unit, t_next: float, reached: dict) -> None:
        """Read the outputs of ``unit`` after its step, record a request to stop, solve its
        algebraic loops at ``t_next``."""
        stopped = False
        for node in unit.nodes:
            t_reached, fresh = reached[id(node)]
            node.read(t_reached, self.bus, self.xbus, self.text, fresh=fresh)
            stop = node.adapter.terminated
            if stop is None:
                continue
            stopped = True
            if self.terminated is None:
                self._stop(node.adapter)
                if stop[0] < t_next - 1e-9 * self.h:  # inside the step: not on the grid
                    self._stopped_inside = True
        if unit.exchange is not None and not stopped:
            self.busy = (unit.nodes[0].adapter.name, "algebraic loop", t_next,
                         time.monotonic())
            try:
                unit.exchange.run(t_next, "point")
            finally:
                self.busy = None
            for node in unit.nodes:
                node.read(t_next, self.bus, self.xbus, self.text)

    def view(self) -> StepView:
        """The read-only view of the current step that observers get."""
        if self._view is None:
            self._view = StepView(self)
        return self._view

    def step_at(self, t: float) -> int:
        """The first step index ``k`` with ``t0 + k*h >= t`` (to the grid's round-off), for
        times a user gives (snapshot times); 0 for a time before the start."""
        return max(0, math.ceil((t - self.t0) / self.h - 1e-9))

    def stopped_between_steps(self) -> bool:
        """True when an FMU's request to stop came inside the last step (its termination time
        is not on the grid; the bus holds its outputs at that time)."""
        return self._stopped_inside

    def notify(self) -> None:
        """Call ``on_step(k, view)`` of every observer, in the order of :attr:`observers`: the
        one place the master hands its state out (at the start time, by :meth:`initialize`,
        and after every step, by :meth:`step`)."""
        if not self.observers:
            return
        view = self.view()
        for obs in self.observers:
            obs.on_step(self.k, view)

    def run_until(self, t: float) -> None:
        """Step until ``t`` (rounded to the base grid), the end of the run or an FMU's request
        to stop (:attr:`terminated`)."""
        k_end = min(self.n_steps, int(round((t - self.t0) / self.h)))
        while self.k < k_end and self.terminated is None:
            self.step()

    def timing(self) -> dict[str, float]:
        out = {f"fmu.{n.adapter.name}_s": n.time_s for n in self.nodes}
        out["master_s"] = self.master_time_s
        return out

    def variable_maps(self) -> dict[str, dict[str, list]]:
        """``{fmu: {role: [FMU variable, scale, offset]}}`` of the FMUs with a variable map."""
        return {n: {r: [a.var.name, a.scale, a.offset] for r, a in ad.varmap.aliases.items()}
                for n, ad in self.adapters.items() if ad.varmap.aliases}

    def me_solvers(self) -> dict[str, str]:
        """``{fmu: "rk4" | "adaptive" | "cvode"}``: the integrator of each ME FMU (the last one
        used; kept after :meth:`close`: the adapters keep it)."""
        out = {name: ad.solver_used for name, ad in self.adapters.items()
               if ad.interface == "me" and ad.solver_used is not None}
        for unit in getattr(self, "units", ()):
            for system in unit.coupled:
                if system.integrator is not None:
                    for name in system.names:
                        others = ", ".join(n for n in system.names if n != name)
                        out[name] = f"{system.integrator.solver_name} (integrated with {others})"
        return out

    def fmu_hashes(self) -> dict[str, str]:
        return {n: a.sha256 for n, a in self.adapters.items()}

    def close(self) -> None:
        """Free every FMU instance and delete the unzipped archives (idempotent)."""
        try:
            for ad in self.adapters.values():
                ad.close()
        finally:
            self._cleanup()
