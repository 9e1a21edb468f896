"""The master algorithm: builds the FMU network of a scenario and steps it.

Time is an integer count of base steps: ``t = t0 + k*h``, never accumulated. Each FMU runs at
an integer multiple ``period`` of ``h``; FMUs are stepped Gauss-Seidel in dependency order.
Signals live in one flat array, the *bus*: every FMU output and every source has a slot, and
each FMU input reads a slot. Sources (controls, noise, sensor sampling and losses) are sampled
from the master's seeded streams in chunks as the run goes (memory does not depend on the
duration); closed-loop sources (waypoints) are evaluated per step.

Step-by-step API::

    m = Master(loaded_scenario, seed=3)
    m.hooks.append(lambda m: print(m.t, m.signal("vehicle.x")))
    m.initialize()
    m.run_until(100.0)       # or m.step() repeatedly
    m.close()
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uwcosim.errors import FMUError, ScenarioError
from uwcosim.master.adapter import Binding, FMUAdapter
from uwcosim.master.graph import stepping_order
from uwcosim.master.proxy import ProxyAdapter
from uwcosim.master.sources import (
    ChunkedTable,
    TableControl,
    WaypointHeading,
    gaussian_drawer,
    loss_drawer,
    noise_drawer,
    stream,
)
from uwcosim.master.varmap import ROLES, load_entries
from uwcosim.scenario.load import LoadedScenario


@dataclass
class _Node:
    adapter: FMUAdapter
    period: int
    inputs: Binding
    in_slots: np.ndarray
    outputs: Binding
    out_slots: np.ndarray
    input_fn: Callable | None = None
    time_s: float = 0.0


@dataclass
class Sensor:
    """A group of FMU outputs measured together, with its sampling and loss."""

    name: str
    outputs: list[str]
    slots: np.ndarray
    period: int
    mask: ChunkedTable  # column 0: sampled and not lost at step k

    def received_at(self, k: int) -> bool:
        """Sampled and not lost at step ``k`` (steps are read in increasing order)."""
        return bool(self.mask.row(k)[0])

    def sampled_at(self, k: int) -> bool:
        return k > 0 and k % self.period == 0


class StageInputs:
    """Refreshes an ME FMU's table-control inputs at the integrator's stage times (picklable,
    so that an FMU in a worker process can take it along)."""

    def __init__(self, pairs: list[tuple[int, TableControl]]) -> None:
        self.pairs = pairs

    def __call__(self, t: float, view: np.ndarray) -> None:
        for j, ctl in self.pairs:
            view[j] = ctl.value(t)


class Master:
    """Co-simulation of one scenario with one seed."""

    def __init__(self, loaded: LoadedScenario, seed: int | None = None,
                 workdir: Path | None = None) -> None:
        self.loaded = loaded
        spec = loaded.spec
        self.spec = spec
        self.seed = spec.run.seed if seed is None else int(seed)
        self.h = spec.run.step
        self.t0 = spec.run.start_time
        n = spec.run.duration / self.h
        self.n_steps = int(round(n))
        if abs(n - self.n_steps) > 1e-9 * max(1.0, n):
            raise ScenarioError(f"{loaded.path}: key 'run.duration': must be a whole number of "
                                f"steps of {self.h:g} s (got {spec.run.duration:g})")
        self.k = 0
        self.hooks: list[Callable[[Master], None]] = []
        self.workdir = workdir
        self.master_time_s = 0.0
        self._initialized = False
        #: the FMU call in progress: (fmu, call, t, time.monotonic() at its start), or None
        #: (read by the run-wide watchdog, uwcosim.runguard)
        self.busy: tuple[str, str, float, float] | None = None
        self.adapters: dict[str, FMUAdapter] = {}
        try:
            self._build()
        except BaseException:
            self.close()
            raise

    # -- construction -----------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self.t0 + self.k * self.h

    def _where(self, key: str) -> str:
        return f"{self.loaded.path}: key '{key}'"

    def _build(self) -> None:
        spec = self.spec
        for name, f in spec.fmus.items():
            self.adapters[name] = self._open(name, f)
        self.slots: dict[str, int] = {}
        for name, ad in self.adapters.items():
            for out in ad.real_outputs():
                self.slots[f"{name}.{out}"] = len(self.slots)
        drivers: dict[str, str] = {}  # input signal -> source name (for error messages)
        self.controls: dict[str, object] = {}
        for cname, c in spec.controls.items():
            src = TableControl(c) if c.table is not None else WaypointHeading(c)
            if isinstance(src, WaypointHeading):
                src.pos_slots = [self._slot(p, f"controls.{cname}.position") for p in c.position]
            self.controls[cname] = src
            self.slots[f"controls.{cname}"] = len(self.slots)
            self._check_input(c.target, f"controls.{cname}.target", drivers, f"controls.{cname}")
        self.noise_sources = []
        for nname, nz in spec.noise.items():
            for i, tgt in enumerate(nz.targets):
                key = f"noise.{nname}.{i}"
                self.slots[key] = len(self.slots)
                self._check_input(tgt, f"noise.{nname}.targets", drivers, key)
        for sname, s in spec.sensors.items():
            for i, tgt in enumerate(s.noise_inputs):
                key = f"sensornoise.{sname}.{i}"
                self.slots[key] = len(self.slots)
                self._check_input(tgt, f"sensors.{sname}.noise_inputs", drivers, key)
        for i, (src, dst) in enumerate(spec.connections):
            self._slot(src, f"connections[{i}]")
            self._check_input(dst, f"connections[{i}]", drivers, src)
        self.drivers = drivers
        self.bus = np.zeros(len(self.slots))
        deps = {n: a.feedthrough() for n, a in self.adapters.items()}
        order = stepping_order(list(self.adapters), list(spec.connections), deps)
        self.nodes: list[_Node] = []
        for name in order:
            ad = self.adapters[name]
            ins = sorted(k.split(".", 1)[1] for k in drivers if k.split(".", 1)[0] == name)
            outs = [k.split(".", 1)[1] for k in self.slots
                    if k.split(".", 1)[0] == name and k.split(".", 1)[1] in ad.variables]
            node = _Node(
                adapter=ad, period=spec.fmus[name].period,
                inputs=ad.bind(ins),
                in_slots=np.array([self.slots[drivers[f"{name}.{i}"]] for i in ins],
                                  dtype=np.intp),
                outputs=ad.bind(outs),
                out_slots=np.array([self.slots[f"{name}.{o}"] for o in outs], dtype=np.intp),
            )
            if ad.interface == "me":
                node.input_fn = self._continuous_inputs(node, ins, name)
            self.nodes.append(node)
        self._sample_sources()
        self.sensors = self._build_sensors()

    def _open(self, name: str, f) -> FMUAdapter | ProxyAdapter:
        """The adapter of FMU ``name``: in this process, or in a worker when ``timeout_s``."""
        path = self.loaded.resolve(f.path)
        if f.timeout_s is not None:
            ad = ProxyAdapter(name, path, f.interface, f.solver, f.substeps, f.rtol, f.timeout_s)
        else:
            ad = FMUAdapter(name, path, f.interface, f.solver, f.substeps, f.rtol)
        if f.map is not None:
            self.adapters[name] = ad  # closed with the others if the map is refused
            entries, where, prefix = load_entries(f.map, self.loaded.base_dir,
                                                  str(self.loaded.path), f"fmus.{name}.map")
            role = f.role or (name if name in ROLES else None)
            ad.use_map(entries, role, where, prefix)
        return ad

    def _variable(self, signal: str, key: str):
        """The FMU variable named by ``fmu.variable``, or a one-line ScenarioError."""
        fmu, _, var = signal.partition(".")
        if fmu not in self.adapters:
            raise ScenarioError(f"{self._where(key)}: unknown FMU {fmu!r} in {signal!r} "
                                f"(FMUs: {', '.join(self.adapters)})")
        v = self.adapters[fmu].variables.get(var)
        if v is None:
            raise ScenarioError(self._no_variable(fmu, var, key))
        return v

    def _slot(self, signal: str, key: str) -> int:
        if signal not in self.slots:
            v = self._variable(signal, key)
            raise ScenarioError(f"{self._where(key)}: {signal!r} is not a Real output "
                                f"(causality {v.causality!r}, type {v.type})")
        return self.slots[signal]

    def _no_variable(self, fmu: str, var: str, key: str) -> str:
        vmap = self.adapters[fmu].varmap
        hint = ""
        if vmap.aliases:
            hint = (f" (fmus.{fmu}.map gives roles {', '.join(vmap.aliases)}; "
                    f"map {var!r} there)")
        return f"{self._where(key)}: FMU {fmu!r} has no variable {var!r}{hint}"

    def _check_input(self, signal: str, key: str, drivers: dict, source: str) -> None:
        v = self._variable(signal, key)
        if v.causality != "input":
            raise ScenarioError(f"{self._where(key)}: {signal!r} has causality "
                                f"{v.causality!r}, expected 'input'")
        if signal in drivers:
            raise ScenarioError(f"{self._where(key)}: input {signal!r} is already driven by "
                                f"{drivers[signal]!r}")
        drivers[signal] = source

    def _continuous_inputs(self, node: _Node, ins: list[str], name: str) -> Callable | None:
        """For ME FMUs: table controls are evaluated at the integrator's stage times."""
        pairs = []
        for j, i in enumerate(ins):
            src = self.drivers[f"{name}.{i}"]
            if src.startswith("controls."):
                ctl = self.controls[src.split(".", 1)[1]]
                if isinstance(ctl, TableControl):
                    pairs.append((j, ctl))
        return StageInputs(pairs) if pairs else None

    def _sample_sources(self) -> None:
        n = self.n_steps + 1
        seed, t0, h = self.seed, self.t0, self.h
        makers, slots = [], []
        for cname, ctl in self.controls.items():
            if isinstance(ctl, TableControl):
                makers.append(lambda ctl=ctl: lambda k0, m: ctl.samples(
                    t0 + h * np.arange(k0, k0 + m))[:, None])
                slots.append([self.slots[f"controls.{cname}"]])
        for nname, nz in self.spec.noise.items():
            makers.append(lambda nname=nname, nz=nz: noise_drawer(
                stream(seed, f"noise:{nname}"), nz.psd, h))
            slots.append([self.slots[f"noise.{nname}.{i}"] for i in range(len(nz.targets))])
        for sname, s in self.spec.sensors.items():
            if s.noise_inputs:
                makers.append(lambda sname=sname, s=s: gaussian_drawer(
                    stream(seed, f"sensor-noise:{sname}"), s.sigma))
                slots.append([self.slots[f"sensornoise.{sname}.{i}"]
                              for i in range(len(s.noise_inputs))])
        self.source_slots = np.array([s for group in slots for s in group], dtype=np.intp)
        self.sources = ChunkedTable(n, makers, len(self.source_slots))
        self.dynamic = [(self.slots[f"controls.{c}"], ctl) for c, ctl in self.controls.items()
                        if not isinstance(ctl, TableControl)]

    def _build_sensors(self) -> dict[str, Sensor]:
        out = {}
        n = self.n_steps + 1
        seed = self.seed
        for sname, s in self.spec.sensors.items():
            slots = np.array([self._slot(o, f"sensors.{sname}.outputs") for o in s.outputs],
                             dtype=np.intp)

            def maker(sname=sname, s=s):
                lost = loss_drawer(stream(seed, f"loss:{sname}"), n, s.loss)

                def draw(k0: int, m: int) -> np.ndarray:
                    k = np.arange(k0, k0 + m)
                    return ((k % s.period == 0) & (k > 0)) & lost(k0, m)
                return draw

            out[sname] = Sensor(sname, list(s.outputs), slots, s.period,
                                ChunkedTable(n, [maker], 1, dtype=bool))
        return out

    def reset(self, seed: int | None = None) -> None:
        """Prepare another run of the same scenario (``seed`` or the scenario's): new noise,
        losses and initial time; FMU instances are kept and reset by :meth:`initialize`."""
        self.seed = self.spec.run.seed if seed is None else int(seed)
        for ctl in self.controls.values():
            if isinstance(ctl, WaypointHeading):
                ctl.reset()
        self._sample_sources()
        self.sensors = self._build_sensors()
        self.bus[:] = 0.0
        self.k = 0
        self.hooks = []
        self.master_time_s = 0.0
        for node in self.nodes:
            node.time_s = 0.0
        self._initialized = False

    # -- running ----------------------------------------------------------------------------
    def signal(self, name: str) -> float:
        return float(self.bus[self.slots[name]])

    def signals(self, names: list[str]) -> np.ndarray:
        return self.bus[[self.slots[n] for n in names]]

    def initialize(self, start_overrides: dict[str, dict] | None = None) -> None:
        """Instantiate and initialize every FMU at ``t0`` and read the outputs at ``t0``."""
        t_stop = self.t0 + self.n_steps * self.h
        for name, node in zip([n.adapter.name for n in self.nodes], self.nodes):
            f = self.spec.fmus[name]
            params = dict(f.parameters)
            params.update((start_overrides or {}).get(name, {}))
            self.busy = (name, "instantiate", self.t0, time.monotonic())
            try:
                node.adapter.instantiate(params, dict(f.start), self.t0, t_stop)
            except FMUError as exc:
                raise FMUError(f"{exc} [scenario key 'fmus.{name}']") from None
            finally:
                self.busy = None
        self.k = 0
        self._load_sources(0)
        for node in self.nodes:
            np.take(self.bus, node.in_slots, out=node.inputs.view)
            node.adapter.set_inputs(node.inputs, self.t0)
            self._read(node, self.t0)
        self._initialized = True

    def _load_sources(self, k: int) -> None:
        self.bus[self.source_slots] = self.sources.row(k)
        for slot, ctl in self.dynamic:
            x, y = self.bus[ctl.pos_slots]
            self.bus[slot] = ctl.value_at(x, y)

    def _read(self, node: _Node, t: float) -> None:
        out = node.adapter.get_outputs(node.outputs, t)
        if not np.all(np.isfinite(out)):
            bad = [n for n, v in zip(node.outputs.names, out) if not np.isfinite(v)]
            raise FMUError(f"FMU '{node.adapter.name}' returned a non-finite value for "
                           f"{', '.join(bad)} at t={t:g}")
        self.bus[node.out_slots] = out

    def step(self) -> None:
        """Advance one base step: ``t_k -> t_{k+1}``, then call the hooks."""
        if not self._initialized:
            raise ScenarioError("Master.step() called before initialize()")
        if self.k >= self.n_steps:
            raise ScenarioError(f"run already at its end t={self.t:g} (duration reached)")
        c0 = time.perf_counter()
        k = self.k
        self._load_sources(k)
        t_next = self.t0 + (k + 1) * self.h
        fmu_time = 0.0
        for node in self.nodes:
            p = node.period
            if (k + 1) % p:
                continue
            a = time.perf_counter()
            np.take(self.bus, node.in_slots, out=node.inputs.view)
            t_start = self.t0 + (k + 1 - p) * self.h
            self.busy = (node.adapter.name, "doStep", t_start, time.monotonic())
            try:
                node.adapter.do_step(t_start, p * self.h, node.inputs, node.input_fn)
            finally:
                self.busy = None
            self._read(node, t_next)
            dt = time.perf_counter() - a
            node.time_s += dt
            fmu_time += dt
        self.k = k + 1
        self.master_time_s += time.perf_counter() - c0 - fmu_time
        for hook in self.hooks:
            hook(self)

    def run_until(self, t: float) -> None:
        """Step until ``t`` (rounded to the base grid) or the end of the run."""
        k_end = min(self.n_steps, int(round((t - self.t0) / self.h)))
        while self.k < k_end:
            self.step()

    def timing(self) -> dict[str, float]:
        out = {f"fmu.{n.adapter.name}_s": n.time_s for n in self.nodes}
        out["master_s"] = self.master_time_s
        return out

    def variable_maps(self) -> dict[str, dict[str, list]]:
        """``{fmu: {role: [FMU variable, scale, offset]}}`` of the FMUs with a variable map."""
        return {n: {r: [a.var.name, a.scale, a.offset] for r, a in ad.varmap.aliases.items()}
                for n, ad in self.adapters.items() if ad.varmap.aliases}

    def fmu_hashes(self) -> dict[str, str]:
        return {n: a.sha256 for n, a in self.adapters.items()}

    def close(self) -> None:
        for ad in self.adapters.values():
            ad.close()
