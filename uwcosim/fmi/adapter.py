"""One FMU instance behind one small interface, whatever its FMI version and interface type.

:class:`FMUAdapter` wraps fmpy's low-level classes (``FMU2Slave``, ``FMU3Slave`` for
co-simulation; ``FMU2Model``, ``FMU3Model`` for model exchange, stepped by
:class:`~uwcosim.fmi.solvers.ModelExchange`). Everything that can be done once is done once:
the archive is checked (:mod:`uwcosim.fmi.archive`) and unzipped once, value references are
resolved by name once, and :class:`~uwcosim.fmi.binding.Binding` keeps ctypes arrays (with
numpy views on them) ready so a step costs only the FMI calls themselves. Every FMI 2/3 scalar
type is handled (:mod:`uwcosim.fmi.vartypes`); FMI 3 arrays as parameters, start values,
inputs and outputs; FMI 3 structural parameters are set in configuration mode.
The instantiated FMU is an :class:`~uwcosim.fmi.instance.Instance` (its C functions, component
and status checks; :attr:`FMUAdapter.instance`), the handle the model-exchange integrator gets;
the outputs' direct dependencies on the inputs come from :mod:`uwcosim.fmi.structure`.

An FMU that asks to stop (co-simulation: FMI 2 ``fmi2Discard`` with ``fmi2Terminated``, FMI 3
``terminateSimulation``; model exchange: ``terminateSimulation`` of an event update or of
``completedIntegratorStep``) is not an error: ``do_step`` returns the time reached and
:attr:`FMUAdapter.terminated` holds ``(time, reason)``.
"""

from __future__ import annotations

import ctypes
import difflib
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription, ModelVariable

import numpy as np

from uwcosim.core import fmucall, scratch
from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.fmi.archive import (
    binary_problems,
    open_archive,
    open_description,
    sha256_file,
    unzip,
)
from uwcosim.fmi.binding import Binding, make_binding
from uwcosim.fmi.features import interfaces as fmu_interfaces
from uwcosim.fmi.features import missing_features
from uwcosim.fmi.instance import Instance, status_label
from uwcosim.fmi.solvers import ModelExchange
from uwcosim.fmi.structure import (
    duplicate_references,
    feedthrough,
    provides_directional_derivatives,
)
from uwcosim.fmi.varmap import VariableMap, resolve_map
from uwcosim.fmi.vartypes import (
    FLOAT64,
    bindable,
    coerce,
    describe,
    is_continuous_input,
    type_info,
)

__all__ = ["Binding", "FMUAdapter", "read_description", "sha256_file"]

# the calls of :mod:`uwcosim.core.fmucall`, by index
(_INSTANTIATE, _EXIT_INIT, _SET, _GET, _DO_STEP, _EVENT, _RESET, _TERMINATE, _FREE) = (
    fmucall.CALLS.index(c) for c in ("instantiate", "exit initialization", "set inputs",
                                     "get outputs", "doStep", "event update", "reset",
                                     "terminate", "free instance"))


def read_description(path: Path, interface: str | None = None) -> ModelDescription:
    """Model description of an FMU archive, with one-line errors for the usual faults."""
    return open_description(path, interface)


class FMUAdapter:
    """A single FMU instance (FMI 2.0/3.0, CS/ME) with a uniform stepping interface."""

    def __init__(
        self,
        name: str,
        path: Path,
        interface: str = "cs",
        solver: str = "rk4",
        substeps: int = 1,
        rtol: float = 1e-8,
        varmap: VariableMap | None = None,
        unzip_dir: str | Path | None = None,
    ) -> None:
        self.name = name
        self._ci = fmucall.fmu_index(name)  # this FMU in the record of the call in progress
        self.path = Path(path)
        self.md = open_archive(self.path)
        self.sha256 = sha256_file(self.path) if self.path.is_file() else ""
        self.fmi3 = self.md.fmiVersion.startswith("3")
        self.interface = interface
        self.solver = solver
        self.substeps = substeps
        self.rtol = rtol
        self.unzip_dir = None if unzip_dir is None else Path(unzip_dir)
        self._own_unzip: str | None = None
        self.fmu_variables = {v.name: v for v in self.md.modelVariables}
        self.varmap = varmap or VariableMap.identity(self.md)
        #: the variables under the names the master uses (roles of a variable map, or as is)
        self.variables = self.varmap.exposed
        self.messages: list[str] = []
        #: ``(time, reason)`` once the FMU asked to stop the simulation, else None
        self.terminated: tuple[float, str] | None = None
        missing = missing_features(self.md)
        if missing:
            raise FMUError(f"{self.path}: FMU '{name}' cannot be run: {missing[0]}")
        token = self.md.instantiationToken if self.fmi3 else self.md.guid
        if not token:  # fmpy would pass None to the library's instantiate function
            raise FMUError(f"{self.path}: FMU '{name}' cannot be run: its modelDescription.xml "
                           f"has no {'instantiationToken' if self.fmi3 else 'guid'} (FMI "
                           f"{self.md.fmiVersion} requires one)")
        clashes = duplicate_references(self.md)
        if clashes:  # one value for two variables: silently wrong inputs or outputs
            raise FMUError(f"{self.path}: FMU '{name}' cannot be run: {clashes[0]} (an FMU's "
                           f"inputs and outputs need value references of their own)")
        kind_ = self.md.coSimulation if interface == "cs" else self.md.modelExchange
        if kind_ is None:
            raise FMUError(
                f"{self.path}: FMU '{name}' does not support interface '{interface}' "
                f"(it supports: {', '.join(fmu_interfaces(self.md))})"
            )
        problems = binary_problems(self.path, self.md, (interface,))
        if problems:
            raise FMUError(problems[0])
        self.model_identifier = kind_.modelIdentifier
        self.nx = int(self.md.numberOfContinuousStates or 0) if interface == "me" else 0
        self.nz = int(self.md.numberOfEventIndicators or 0) if interface == "me" else 0
        self._inst: Instance | None = None
        self._me: ModelExchange | None = None
        self._closed_solver: str | None = None  # the ME integrator used, kept by close()
        self._pending: list[Binding] = []  # typed bindings made before the library is loaded
        self._typed: list[Binding] = []  # every typed binding (discrete inputs: last values)
        self._held: tuple[float, float] | None = None  # (t0, t_stop) while held in init mode
        self.time_s = 0.0  # wall time spent in this FMU's calls (set by the master)
        #: the FMU gives the partial derivatives of its outputs (:meth:`output_derivatives`)
        self.provides_derivatives = provides_directional_derivatives(self.md, self.path,
                                                                     interface)

    # -- variables --------------------------------------------------------------------------
    def variable(self, name: str) -> ModelVariable:
        v = self.variables.get(name)
        if v is None:
            mapped = " (variable map: roles " + ", ".join(self.varmap.aliases) + ")" \
                if self.varmap.aliases else ""
            raise FMUError(f"{self.path}: FMU '{self.name}' has no variable {name!r}{mapped}")
        return v

    def use_map(self, entries: dict[str, dict], role: str | None = None, where: str = "",
                prefix: str = "") -> VariableMap:
        """Expose the FMU under the roles of a variable map (before :meth:`bind`)."""
        vmap, problems = resolve_map(entries, self.md, role, where or str(self.path), prefix)
        if problems:
            raise ScenarioError(problems[0])
        self.varmap = vmap
        self.variables = vmap.exposed
        return vmap

    def real_outputs(self) -> list[str]:
        """Names (as exposed) of the Real outputs, in model-description order."""
        return [n for n, v in self.variables.items()
                if v.causality == "output" and v.type in FLOAT64]

    def outputs(self) -> list[str]:
        """Names (as exposed) of the outputs of every supported type, FMI 3 arrays included
        (not String arrays)."""
        return [n for n, v in self.variables.items() if v.causality == "output"
                and bindable(v)]

    def feedthrough(self) -> dict[str, set[str]]:
        """``{output: {inputs it depends on directly}}`` under the exposed names
        (:func:`uwcosim.fmi.structure.feedthrough`)."""
        ren = self.varmap.raw_to_exposed
        return {ren[o]: {ren[i] for i in ins if i in ren}
                for o, ins in feedthrough(self.md).items() if o in ren}

    def _discrete_input(self, v) -> bool:
        return self.interface == "me" and v.causality == "input" and not is_continuous_input(v)

    def bind(self, names: list[str] | tuple[str, ...]) -> Binding:
        variables = [self.variable(n) for n in names]
        for v in variables:
            if not bindable(v):
                raise FMUError(f"{self.path}: FMU '{self.name}': variable {v.name!r} has type "
                               f"{describe(v)}, which cannot be connected or logged")
        affine = [self.varmap.affine(n) for n in names]
        b = make_binding(tuple(names), variables, affine, self.fmi3,
                         [self._discrete_input(v) for v in variables])
        if not b.groups:
            return b
        self._typed.append(b)
        if self._inst is not None:
            self._inst.resolve(b)
        else:
            self._pending.append(b)
        return b

    def check_values(self, values: dict, where: str = "") -> dict:
        """Parameters/start values checked against the declared types and converted (native
        Python values); ScenarioError naming the variable and the expected type otherwise."""
        given = where
        where = where or f"{self.path}: FMU '{self.name}'"
        out = {}
        for name, value in values.items():
            alias = self.varmap.aliases.get(name)
            if alias is not None:
                out[name] = coerce(alias.start_var or alias.var, value, where)
                continue
            v = self.fmu_variables.get(name)
            if v is None:
                if given:  # a scenario key named it: the user's error (exit 2), by that key
                    near = difflib.get_close_matches(name, list(self.fmu_variables), 3)
                    hint = f" (nearest: {', '.join(near)})" if near else ""
                    key = f"{given[:-1]}.{name}'" if given.endswith("'") else given
                    raise ScenarioError(f"{key}: FMU '{self.name}' "
                                        f"({self.path.name}) has no variable {name!r}{hint}")
                raise FMUError(f"{self.path}: FMU '{self.name}' has no variable {name!r}")
            out[name] = coerce(v, value, where)
        return out

    # -- life cycle -------------------------------------------------------------------------
    def _log(self, *args) -> None:
        # FMI 2: (component, instanceName, status, category, message)
        # FMI 3: (instanceEnvironment, status, category, message)
        message = args[-1]
        status = args[-3]
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        text = text.replace("%%", "%")  # FMI 2 messages are printf formats
        self.messages.append(f"[{status_label(status)}] {text}")
        del self.messages[:-20]

    def _unzip(self) -> str:
        if self.path.is_dir():  # an unzipped FMU: used where it is
            return str(self.path)
        if self.unzip_dir is not None:
            return str(unzip(self.path, self.unzip_dir))
        if self._own_unzip is None:
            self._own_unzip = scratch.make("uwcosim_fmu_")
            unzip(self.path, self._own_unzip)
        return self._own_unzip

    def instantiate(self, parameters: dict, start: dict, t0: float, t_stop: float,
                    hold: bool = False) -> None:
        """Instantiate, set parameters and start values, and initialize at ``t0``.

        An adapter that already holds an instance resets it (``fmi2Reset``/``fmi3Reset``) and
        initializes it again instead: campaigns reuse one instance per worker for many runs.
        ``hold``: stay in initialization mode (inputs may be set and outputs read, e.g. to
        solve an algebraic loop) until :meth:`exit_initialization`.
        """
        values = self.check_values({**parameters, **start})
        fmucall.begin(self._ci, _INSTANTIATE, t0)
        try:
            self._instantiate(values, t0, t_stop, hold)
        finally:
            fmucall.end()

    def _instantiate(self, values: dict, t0: float, t_stop: float, hold: bool) -> None:
        from fmpy import fmi2, fmi3  # lazy: fmpy (0.1 s) only once an FMU is instantiated

        self.terminated = None
        inst = self._inst
        if inst is not None:
            self.messages.clear()
            inst.guard("reset", inst.fmu.reset, t0)
            inst.guard("setup", lambda: self._initialize(values, t0, t_stop, hold), t0)
            return
        unzip_dir = self._unzip()
        guid = self.md.instantiationToken if self.fmi3 else self.md.guid
        cls = {
            (False, "cs"): fmi2.FMU2Slave, (False, "me"): fmi2.FMU2Model,
            (True, "cs"): fmi3.FMU3Slave, (True, "me"): fmi3.FMU3Model,
        }[(self.fmi3, self.interface)]
        cwd = os.getcwd()  # fmpy changes into the binary's folder and, if loading fails, stays
        try:
            fmu = cls(guid=guid, unzipDirectory=unzip_dir, modelIdentifier=self.model_identifier,
                      instanceName=self.name)
            if self.fmi3:
                fmu.instantiate(logMessage=self._log, loggingOn=False)
            else:
                cb = fmi2.fmi2CallbackFunctions()
                cb.logger = fmi2.fmi2CallbackLoggerTYPE(self._log)
                cb.allocateMemory = fmi2.fmi2CallbackAllocateMemoryTYPE(fmi2.calloc)
                cb.freeMemory = fmi2.fmi2CallbackFreeMemoryTYPE(fmi2.free)
                # no fmpy logger proxy: it keeps one process-wide logger, which would route every
                # instance's messages to the last adapter (and crash once that one is gone)
                self._callbacks = cb
                fmu.instantiate(callbacks=cb)
        except FMUError:
            raise
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions here
            raise FMUError(f"{self.path}: cannot instantiate FMU '{self.name}' ({exc})") from None
        finally:
            if os.getcwd() != cwd:
                os.chdir(cwd)
        self._inst = inst = Instance(fmu, self.name, self.path, self.fmi3, self.messages)
        self._prepare_fast_calls(inst)
        for b in self._pending:
            inst.resolve(b)
        self._pending = []
        inst.guard("setup", lambda: self._initialize(values, t0, t_stop, hold), t0)

    def exit_initialization(self) -> None:
        """Leave the initialization mode :meth:`instantiate` held the FMU in."""
        if self._held is None:
            return
        (t0, t_stop), self._held = self._held, None
        fmucall.begin(self._ci, _EXIT_INIT, t0)
        try:
            self._inst.guard("setup", lambda: self._exit_initialization(t0, t_stop), t0)
        finally:
            fmucall.end()

    @property
    def instance(self) -> Instance | None:
        """The handle of the FMU instance (None before :meth:`instantiate`, after :meth:`close`);
        one instance serves every run of a reused adapter."""
        return self._inst

    def _initialize(self, values: dict, t0: float, t_stop: float, hold: bool = False) -> None:
        fmu = self._inst.fmu
        self._me = None  # a reused instance: the integrator of the last run is gone
        if not self.fmi3:
            fmu.setupExperiment(startTime=t0)
        structural = {n: v for n, v in values.items() if self._structural(n)}
        if structural:  # FMI 3: structural parameters are set in configuration mode
            fmu.enterConfigurationMode()
            self.set_values(structural, checked=True)
            fmu.exitConfigurationMode()
            values = {n: v for n, v in values.items() if n not in structural}
        self.set_values(values, checked=True)
        if self.fmi3:
            fmu.enterInitializationMode(startTime=t0)
        else:
            fmu.enterInitializationMode()
        if hold:
            self._held = (t0, t_stop)
            return
        self._exit_initialization(t0, t_stop)

    def _exit_initialization(self, t0: float, t_stop: float) -> None:
        self._inst.fmu.exitInitializationMode()
        if self.interface == "me":
            for b in self._typed:  # a new run: every discrete input is set again
                for g in b.groups:
                    g.last = None
            self._me = ModelExchange(self._inst, self.set_continuous, t0, t_stop, nx=self.nx,
                                     nz=self.nz, solver=self.solver, substeps=self.substeps,
                                     rtol=self.rtol)
            try:
                self._me.initial_event(t0)
            finally:  # a request to stop, even if an error follows it
                self.terminated = self._me.terminated

    def _structural(self, name: str) -> bool:
        alias = self.varmap.aliases.get(name)
        v = (alias.start_var or alias.var) if alias is not None else self.fmu_variables.get(name)
        return self.fmi3 and v is not None and v.causality == "structuralParameter"

    def set_values(self, values: dict, checked: bool = False) -> None:
        """Set parameters/start values of any type by name (setup only, not the hot path)."""
        fmu = self._inst.fmu
        if not checked:
            values = self.check_values(values)
        for name, value in values.items():
            alias = self.varmap.aliases.get(name)
            if alias is not None:  # a role: its start variable (or itself), converted
                v = alias.start_var or alias.var
                value = alias.to_fmu(value)
            else:
                v = self.fmu_variables[name]
            vals = value if isinstance(value, list) else [value]
            suffix = type_info(v, self.fmi3)[2]
            getattr(fmu, f"set{suffix}")([v.valueReference], vals)

    def get_values(self, names: list[str]) -> dict:
        """Current values of any type by name (native Python values; arrays as lists)."""
        out = {}
        for name in names:
            v = self.variable(name)
            info = type_info(v, self.fmi3)
            if info is None:
                raise FMUError(f"{self.path}: FMU '{self.name}': cannot get {name!r} of type "
                               f"{v.type}")
            getter = getattr(self._inst.fmu, f"get{info[2]}")
            n = int(np.prod(v.shape)) if getattr(v, "dimensions", None) else 1
            vals = getter([v.valueReference], n) if self.fmi3 else getter([v.valueReference])
            vals = [bool(x) for x in vals] if info[0] == "bool" else [
                x.decode("utf-8", "replace") if isinstance(x, bytes) else x for x in vals]
            a = self.varmap.aliases.get(name)
            out[name] = vals if n != 1 or getattr(v, "dimensions", None) else (
                a.to_ours(vals[0]) if a is not None else vals[0])
        return out

    def _prepare_fast_calls(self, inst: Instance) -> None:
        p = "fmi3" if self.fmi3 else "fmi2"
        self._c = inst.component
        self._check = inst.check  # bound once: the status check of every hot-path call
        self._set = inst.function(f"{p}SetFloat64" if self.fmi3 else "fmi2SetReal")
        self._get = inst.function(f"{p}GetFloat64" if self.fmi3 else "fmi2GetReal")
        if self.interface == "cs":
            self._do_step = inst.function(f"{p}DoStep")
            self._flags = [ctypes.c_bool() for _ in range(3)] + [ctypes.c_double()]
            self._flag_refs = [ctypes.byref(f) for f in self._flags]
            self._terminate_flag, self._early_flag = self._flags[1], self._flags[2]

    # -- hot path ---------------------------------------------------------------------------
    def _set_groups(self, b: Binding, groups, t: float) -> None:
        b.to_fmu()
        for g in groups:
            b.raw_to_group(g)
            if self.fmi3:
                st = g.set(self._c, g.vr, g.nvr, g.buf, g.n)
            else:
                st = g.set(self._c, g.vr, g.nvr, g.buf)
            self._check(st, "set inputs", t)

    def set_continuous(self, b: Binding, t: float) -> None:
        """Set the inputs that may change in continuous-time mode (all of them for CS)."""
        if not b.n:
            return
        fmucall.begin(self._ci, _SET, t)
        try:
            self._set_continuous(b, t)
        finally:
            fmucall.end()

    def _set_continuous(self, b: Binding, t: float) -> None:
        if b.groups:
            self._set_groups(b, b.continuous_groups, t)
            return
        if b.scale is not None:
            b.to_fmu()
        if self.fmi3:
            st = self._set(self._c, b.vr, b.n, b.buf, b.n)
        else:
            st = self._set(self._c, b.vr, b.n, b.buf)
        self._check(st, "set inputs", t)

    def set_inputs_now(self, b: Binding, t: float) -> bool:
        """Set the inputs of ``b`` in initialization mode, or (model exchange) in event mode:
        the discrete ones too (those that changed, in event mode), without an event of their
        own (a joint event loop or an initialization iteration is in progress). True if a
        discrete input changed (event mode)."""
        if not b.n:
            return False
        fmucall.begin(self._ci, _SET, t)
        try:
            return self._set_inputs_now(b, t)
        finally:
            fmucall.end()

    def _set_inputs_now(self, b: Binding, t: float) -> bool:
        if not b.groups:
            self.set_continuous(b, t)
        elif self._me is None:
            self._set_groups(b, b.groups, t)
        else:
            self._set_groups(b, b.continuous_groups, t)
            changed = self._me.discrete_changes(b)
            self._me.apply_discrete(changed, t)
            return bool(changed)
        return False

    def output_derivatives(self, outputs: Binding, inputs: Binding, t: float) -> np.ndarray:
        """``d outputs / d inputs`` (in our units) from the FMU's directional derivatives
        (:attr:`provides_derivatives`), one directional derivative per input."""
        fmu = self._inst.fmu
        unknowns = [self.variable(n).valueReference for n in outputs.names]
        knowns = [self.variable(n).valueReference for n in inputs.names]
        jac = np.empty((len(unknowns), len(knowns)))
        for j in range(len(knowns)):
            seed = [0.0] * len(knowns)
            seed[j] = 1.0
            jac[:, j] = self._inst.guard(
                "getDirectionalDerivative",
                lambda seed=seed: fmu.getDirectionalDerivative(unknowns, knowns, seed), t)
        s_out = np.array([self.varmap.affine(n)[0] for n in outputs.names])
        s_in = np.array([self.varmap.affine(n)[0] for n in inputs.names])
        return jac * s_out[:, None] / s_in[None, :]

    def set_inputs(self, b: Binding, t: float) -> None:
        """Set the inputs at a communication point. Model exchange: discrete inputs that changed
        are set in event mode (with the event iteration that follows)."""
        self.set_continuous(b, t)
        if b.groups and self._me is not None and b.discrete_groups:
            fmucall.begin(self._ci, _EVENT, t)
            try:
                self._me.set_discrete(b, t)
            finally:
                fmucall.end()
                self.terminated = self._me.terminated

    def get_outputs(self, b: Binding, t: float) -> np.ndarray:
        if not b.n:
            return b.view
        fmucall.begin(self._ci, _GET, t)
        try:
            return self._get_outputs(b, t)
        finally:
            fmucall.end()

    def _get_outputs(self, b: Binding, t: float) -> np.ndarray:
        if b.groups:
            for g in b.groups:
                if self.fmi3:
                    st = g.get(self._c, g.vr, g.nvr, g.buf, g.n)
                else:
                    st = g.get(self._c, g.vr, g.nvr, g.buf)
                self._check(st, "get outputs", t)
            b.groups_to_raw()
            return b.view
        st = (self._get(self._c, b.vr, b.n, b.buf, b.n) if self.fmi3 else
              self._get(self._c, b.vr, b.n, b.buf))
        if st > 1:
            self._check(st, "get outputs", t)
        if b.scale is not None:
            b.from_fmu()
        return b.view

    def do_step(self, t: float, h: float, inputs: Binding, input_fn: Callable | None) -> float:
        """Advance from ``t`` to ``t + h``; return the time reached (earlier than ``t + h`` only
        when the FMU asked to stop: see :attr:`terminated`). Inputs are in ``inputs.view``
        (held over the step); for model exchange ``input_fn(t, view)`` may refresh the
        continuous ones at the integrator's stage times."""
        fmucall.begin(self._ci, _DO_STEP, t)
        try:
            return self._step(t, h, inputs, input_fn)
        finally:
            fmucall.end()

    def _step(self, t: float, h: float, inputs: Binding, input_fn: Callable | None) -> float:
        if self.terminated is not None:
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): doStep at t={t:g} after the "
                           f"FMU asked to stop at t={self.terminated[0]:g}")
        if self._me is not None:
            try:
                return self._me.step(t, h, inputs, input_fn)
            finally:
                self.terminated = self._me.terminated
        b = inputs
        if b.n:  # set_inputs inlined: the co-simulation hot path
            if b.groups:
                self._set_groups(b, b.groups, t)
            else:
                if b.scale is not None:
                    b.to_fmu()
                st = (self._set(self._c, b.vr, b.n, b.buf, b.n) if self.fmi3 else
                      self._set(self._c, b.vr, b.n, b.buf))
                if st > 1:
                    self._check(st, "set inputs", t)
        if self.fmi3:
            st = self._do_step(self._c, t, h, True, *self._flag_refs)
            if self._terminate_flag.value or self._early_flag.value:
                return self._fmi3_stopped(st, t, h)
        else:
            st = self._do_step(self._c, t, h, 1)
            if st == 2 and self._fmi2_terminated():
                t_end = self._fmi2_last_time(t)
                self.terminated = (t_end, self._inst.reason("fmi2Terminated"))
                return t_end
        if st > 1:
            self._check(st, "doStep", t)
        return t + h

    def _fmi3_stopped(self, st: int, t: float, h: float) -> float:
        """FMI 3 doStep with terminateSimulation or earlyReturn set."""
        if self._terminate_flag.value and st <= 2:
            last = self._flags[3].value  # the FMU's time when doStep returned
            t_end = last if t <= last <= t + h else t + h
            self.terminated = (t_end, self._inst.reason("terminateSimulation"))
            return t_end
        self._check(st, "doStep", t)
        raise FMUError(f"FMU '{self.name}' ({self.path.name}): doStep returned early at "
                       f"t={self._flags[3].value:g} (early return was not allowed)")

    def _fmi2_terminated(self) -> bool:
        flag = ctypes.c_int(0)
        get_status = self._inst.function("fmi2GetBooleanStatus")
        st = get_status(self._c, 3, ctypes.byref(flag))  # fmi2Terminated
        return st <= 1 and bool(flag.value)

    def _fmi2_last_time(self, t: float) -> float:
        value = ctypes.c_double(t)
        st = self._inst.function("fmi2GetRealStatus")(self._c, 2, ctypes.byref(value))
        return value.value if st <= 1 else t

    # -- model exchange -----------------------------------------------------------------------
    @property
    def solver_used(self) -> str | None:
        """``rk4``/``adaptive`` (no events) or ``cvode`` (event-aware): the integrator of the
        instance (the last one used after :meth:`close`; None before :meth:`instantiate`)."""
        if self._me is not None:
            return self._me.solver_name
        return self.solver if self._inst is not None else self._closed_solver

    @property
    def model_exchange(self) -> ModelExchange | None:
        """The model-exchange integrator of the instance (None for co-simulation, before
        :meth:`instantiate` and while held in initialization mode): a joint integrator of
        several FMUs (:mod:`uwcosim.fmi.coupled`) drives it instead of :meth:`do_step`."""
        return self._me

    def sync_terminated(self) -> None:
        """Take the integrator's request to stop after a joint integration step."""
        if self._me is not None and self._me.terminated is not None:
            self.terminated = self._me.terminated

    @property
    def event_times(self) -> list[float]:
        """Model exchange: times of the events handled since initialization."""
        return self._me.event_times if self._me is not None else []

    def states(self) -> np.ndarray:
        return self._me.states()

    # -- end ----------------------------------------------------------------------------------
    def reset(self) -> None:
        if self._inst is not None:
            fmucall.begin(self._ci, _RESET, 0.0)
            try:
                self._inst.guard("reset", self._inst.fmu.reset, 0.0)
            finally:
                fmucall.end()

    def close(self) -> None:
        self._closed_solver = self.solver_used  # kept: the integrator this instance used
        inst, self._inst = self._inst, None
        self._me = None
        fmu = None if inst is None else inst.fmu
        if fmu is not None:
            fmucall.begin(self._ci, _TERMINATE, 0.0)
            try:
                fmu.terminate()
            except Exception:  # noqa: BLE001 - terminate after an error may fail; free anyway
                pass
            finally:
                fmucall.end()
            fmucall.begin(self._ci, _FREE, 0.0)
            try:
                fmu.freeInstance()
            except Exception:  # noqa: BLE001
                pass
            finally:
                fmucall.end()
        if self._own_unzip is not None:
            d, self._own_unzip = self._own_unzip, None
            try:
                fmu.freeLibrary() if fmu is not None else None
            except Exception:  # noqa: BLE001
                pass
            scratch.remove(d)
