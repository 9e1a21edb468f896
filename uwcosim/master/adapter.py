"""One FMU instance behind one small interface, whatever its FMI version and interface type.

:class:`FMUAdapter` wraps fmpy's low-level classes (``FMU2Slave``, ``FMU3Slave`` for
co-simulation; ``FMU2Model``, ``FMU3Model`` for model exchange, integrated here with fixed-step
RK4 or an adaptive scipy solver). Everything that can be done once is done once: the archive is
unzipped once, value references are resolved by name once, and :class:`Binding` keeps ctypes
arrays (with numpy views on them) ready so a step costs only the FMI calls themselves.
"""

from __future__ import annotations

import ctypes
import hashlib
import shutil
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uwcosim.errors import FMUError, ScenarioError
from uwcosim.master.varmap import VariableMap, resolve_map

STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _build_hint(path: Path) -> str:
    """The 'uwcosim fmu build' hint, for the project's own FMUs only."""
    from uwcosim.fmu.build import FMI_VERSIONS, archive_name
    from uwcosim.fmu.specs import MODELS

    own = {archive_name(m, v) for m in MODELS for v in FMI_VERSIONS}
    return " (build the project's FMUs with 'uwcosim fmu build')" if path.name in own else ""


def read_description(path: Path):
    """Model description of an FMU archive, with one-line errors for the usual faults."""
    import fmpy
    from fmpy.model_description import read_model_description

    path = Path(path)
    if not path.is_file():
        raise FMUError(f"{path}: FMU not found{_build_hint(path)}")
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
            if bad is not None:
                raise FMUError(f"{path}: corrupt FMU archive (bad CRC in {bad})")
            names = zf.namelist()
    except zipfile.BadZipFile as exc:
        raise FMUError(f"{path}: not a valid FMU archive ({exc})") from None
    if "modelDescription.xml" not in names:
        raise FMUError(f"{path}: not an FMU (no modelDescription.xml in the archive)")
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions for bad XML
        raise FMUError(f"{path}: invalid modelDescription.xml ({exc})") from None
    platforms = fmpy.supported_platforms(str(path))  # fmpy's names for FMI 2 and 3 alike
    here = fmpy.platform
    if here not in platforms:
        raise FMUError(
            f"{path}: no binary for this platform {here} (the FMU has: "
            f"{', '.join(p for p in platforms if p not in ('c-code',)) or 'none'})"
        )
    return md


class _Unzipped:
    """Unzip each archive once per process; removed by :func:`cleanup_unzipped`."""

    dirs: dict[str, str] = {}

    @classmethod
    def get(cls, path: Path, sha: str) -> str:
        d = cls.dirs.get(sha)
        if d is None:
            from fmpy import extract

            d = tempfile.mkdtemp(prefix="uwcosim_fmu_")
            extract(str(path), unzipdir=d)
            cls.dirs[sha] = d
        return d


def cleanup_unzipped() -> None:
    for d in _Unzipped.dirs.values():
        shutil.rmtree(d, ignore_errors=True)
    _Unzipped.dirs.clear()


@dataclass
class Binding:
    """Value references and a value buffer ready for one get or set call.

    ``view`` holds the values in our units, ``raw`` (a numpy view on the ctypes buffer) in the
    FMU's. Without a unit conversion they are the same array; with one (a variable map),
    ``ours = scale * theirs + offset`` is applied to the whole vector in one numpy operation.
    """

    names: tuple[str, ...]
    vr: ctypes.Array | None
    buf: ctypes.Array | None
    view: np.ndarray  # values in our units
    raw: np.ndarray | None = None  # numpy view on buf (FMU units); None: same as view
    scale: np.ndarray | None = None  # None: identity conversion
    offset: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.names)

    @classmethod
    def plain(cls, names) -> Binding:
        """A binding without FMU buffers (values only), e.g. for an out-of-process FMU."""
        return cls(tuple(names), None, None, np.zeros(len(names)))

    def to_fmu(self) -> None:
        if self.scale is not None:
            np.subtract(self.view, self.offset, out=self.raw)
            np.divide(self.raw, self.scale, out=self.raw)

    def from_fmu(self) -> None:
        if self.scale is not None:
            np.multiply(self.raw, self.scale, out=self.view)
            np.add(self.view, self.offset, out=self.view)


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
    ) -> None:
        self.name = name
        self.path = Path(path)
        self.md = read_description(self.path)
        self.sha256 = sha256_file(self.path)
        self.fmi3 = self.md.fmiVersion.startswith("3")
        self.interface = interface
        self.solver = solver
        self.substeps = substeps
        self.rtol = rtol
        self.fmu_variables = {v.name: v for v in self.md.modelVariables}
        self.varmap = varmap or VariableMap.identity(self.md)
        #: the variables under the names the master uses (roles of a variable map, or as is)
        self.variables = self.varmap.exposed
        self.messages: list[str] = []
        kind = self.md.coSimulation if interface == "cs" else self.md.modelExchange
        if kind is None:
            have = [n for n, k in (("cs", self.md.coSimulation), ("me", self.md.modelExchange))
                    if k is not None]
            raise FMUError(
                f"{self.path}: FMU '{name}' does not support interface '{interface}' "
                f"(it supports: {', '.join(have)})"
            )
        self.model_identifier = kind.modelIdentifier
        self.nx = int(self.md.numberOfContinuousStates or 0) if interface == "me" else 0
        self._fmu = None
        self._instantiated = False
        self.time_s = 0.0  # wall time spent in this FMU's calls (set by the master)

    # -- variables --------------------------------------------------------------------------
    def variable(self, name: str):
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
                if v.causality == "output" and v.type in ("Real", "Float64")]

    def feedthrough(self) -> dict[str, set[str]]:
        """``{output: {inputs it depends on directly}}`` under the exposed names."""
        from uwcosim.master.graph import feedthrough

        ren = self.varmap.raw_to_exposed
        return {ren[o]: {ren[i] for i in ins if i in ren}
                for o, ins in feedthrough(self.md).items() if o in ren}

    def bind(self, names: list[str] | tuple[str, ...]) -> Binding:
        vrt = ctypes.c_uint32
        vr = (vrt * len(names))(*[self.variable(n).valueReference for n in names])
        buf = (ctypes.c_double * len(names))()
        raw = np.ctypeslib.as_array(buf) if len(names) else np.zeros(0)
        affine = [self.varmap.affine(n) for n in names]
        if all(a == (1.0, 0.0) for a in affine):
            return Binding(tuple(names), vr, buf, raw, raw)
        scale = np.array([a[0] for a in affine])
        offset = np.array([a[1] for a in affine])
        return Binding(tuple(names), vr, buf, np.zeros(len(names)), raw, scale, offset)

    # -- life cycle -------------------------------------------------------------------------
    def _log(self, *args) -> None:
        # FMI 2: (component, instanceName, status, category, message)
        # FMI 3: (instanceEnvironment, status, category, message)
        message = args[-1]
        status = args[-3]
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        text = text.replace("%%", "%")  # FMI 2 messages are printf formats
        label = STATUS[status] if 0 <= status < len(STATUS) else str(status)
        self.messages.append(f"[{label}] {text}")
        del self.messages[:-20]

    def instantiate(self, parameters: dict, start: dict, t0: float, t_stop: float) -> None:
        """Instantiate, set parameters and start values, and initialize at ``t0``.

        An adapter that already holds an instance resets it (``fmi2Reset``/``fmi3Reset``) and
        initializes it again instead: campaigns reuse one instance per worker for many runs.
        """
        from fmpy import fmi2, fmi3

        if self._fmu is not None:
            self.messages.clear()
            self._guard("reset", self._fmu.reset, t0)
            self._guard("setup",
                        lambda: self._initialize(self._fmu, parameters, start, t0, t_stop), t0)
            return

        unzip = _Unzipped.get(self.path, self.sha256)
        guid = self.md.instantiationToken if self.fmi3 else self.md.guid
        cls = {
            (False, "cs"): fmi2.FMU2Slave, (False, "me"): fmi2.FMU2Model,
            (True, "cs"): fmi3.FMU3Slave, (True, "me"): fmi3.FMU3Model,
        }[(self.fmi3, self.interface)]
        try:
            fmu = cls(guid=guid, unzipDirectory=unzip, modelIdentifier=self.model_identifier,
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
        self._fmu = fmu
        self._instantiated = True
        self._raw = fmu._functions
        self._c = fmu.component
        self._guard("setup", lambda: self._initialize(fmu, parameters, start, t0, t_stop), t0)
        self._prepare_fast_calls()

    def _initialize(self, fmu, parameters: dict, start: dict, t0: float, t_stop: float) -> None:
        if not self.fmi3:
            fmu.setupExperiment(startTime=t0)
        values = {**parameters, **start}
        self.set_values(values)
        if self.fmi3:
            fmu.enterInitializationMode(startTime=t0)
        else:
            fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        if self.interface == "me":
            self._event_iteration()
            fmu.enterContinuousTimeMode()

    def set_values(self, values: dict) -> None:
        """Set parameters/start values of any type by name (setup only, not the hot path)."""
        fmu = self._fmu
        for name, value in values.items():
            alias = self.varmap.aliases.get(name)
            if alias is not None:  # a role: its start variable (or itself), converted
                v = alias.start_var or alias.var
                value = alias.to_fmu(value)
            else:
                v = self.fmu_variables.get(name)
                if v is None:
                    raise FMUError(f"{self.path}: FMU '{self.name}' has no variable {name!r}")
            vr = [v.valueReference]
            t = v.type
            if t in ("Real", "Float64", "Float32"):
                (fmu.setFloat64 if self.fmi3 else fmu.setReal)(vr, [float(value)])
            elif t in ("Integer", "Int32", "Int64", "Enumeration", "UInt32"):
                (fmu.setInt32 if self.fmi3 and t == "Int32" else
                 fmu.setInt64 if self.fmi3 and t == "Int64" else
                 fmu.setUInt32 if self.fmi3 and t == "UInt32" else
                 fmu.setInt64 if self.fmi3 else fmu.setInteger)(vr, [int(value)])
            elif t == "Boolean":
                fmu.setBoolean(vr, [bool(value)])
            elif t == "String":
                fmu.setString(vr, [str(value)])
            else:
                raise FMUError(f"{self.path}: cannot set variable {name!r} of type {t}")

    def _event_iteration(self) -> None:
        fmu = self._fmu
        for _ in range(100):
            need = (fmu.updateDiscreteStates() if self.fmi3 else fmu.newDiscreteStates())[0]
            if not need:
                return
        raise FMUError(f"{self.path}: FMU '{self.name}': event iteration did not converge")

    def _prepare_fast_calls(self) -> None:
        p = "fmi3" if self.fmi3 else "fmi2"
        self._set = self._raw[f"{p}SetFloat64" if self.fmi3 else "fmi2SetReal"]
        self._get = self._raw[f"{p}GetFloat64" if self.fmi3 else "fmi2GetReal"]
        if self.interface == "cs":
            self._do_step = self._raw[f"{p}DoStep"]
            self._flags = [ctypes.c_bool() for _ in range(3)] + [ctypes.c_double()]
            self._flag_refs = [ctypes.byref(f) for f in self._flags]
        else:
            self._x = (ctypes.c_double * self.nx)()
            self._dx = (ctypes.c_double * self.nx)()
            self.xv = np.ctypeslib.as_array(self._x) if self.nx else np.zeros(0)
            self.dxv = np.ctypeslib.as_array(self._dx) if self.nx else np.zeros(0)
            self._set_time = self._raw[f"{p}SetTime"]
            self._set_states = self._raw[f"{p}SetContinuousStates"]
            self._get_states = self._raw[f"{p}GetContinuousStates"]
            self._get_der = self._raw[
                "fmi3GetContinuousStateDerivatives" if self.fmi3 else "fmi2GetDerivatives"
            ]
            self._completed = self._raw[f"{p}CompletedIntegratorStep"]
            flag = ctypes.c_bool if self.fmi3 else ctypes.c_int
            self._cflags = [flag(), flag()]
            self._cflag_refs = [ctypes.byref(f) for f in self._cflags]

    # -- hot path ---------------------------------------------------------------------------
    def _check(self, status: int, what: str, t: float) -> None:
        if status > 1:
            label = STATUS[status] if status < len(STATUS) else str(status)
            last = f": {self.messages[-1]}" if self.messages else ""
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): {what} returned {label} "
                           f"at t={t:g}{last}")

    def _guard(self, what: str, fn: Callable, t: float):
        try:
            return fn()
        except FMUError:
            raise
        except Exception as exc:  # noqa: BLE001 - fmpy's FMICallException and friends
            last = f": {self.messages[-1]}" if self.messages else ""
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): {what} failed at t={t:g} "
                           f"({exc}){last}") from None

    def set_inputs(self, b: Binding, t: float) -> None:
        if b.n:
            if b.scale is not None:
                b.to_fmu()
            if self.fmi3:
                st = self._set(self._c, b.vr, b.n, b.buf, b.n)
            else:
                st = self._set(self._c, b.vr, b.n, b.buf)
            self._check(st, "set inputs", t)

    def get_outputs(self, b: Binding, t: float) -> np.ndarray:
        if b.n:
            if self.fmi3:
                st = self._get(self._c, b.vr, b.n, b.buf, b.n)
            else:
                st = self._get(self._c, b.vr, b.n, b.buf)
            self._check(st, "get outputs", t)
            if b.scale is not None:
                b.from_fmu()
        return b.view

    def do_step(self, t: float, h: float, inputs: Binding, input_fn: Callable | None) -> None:
        """Advance from ``t`` to ``t + h``. Inputs are in ``inputs.view`` (held over the step);
        for model exchange ``input_fn(t)`` may refresh them at the integrator's stage times."""
        if self.interface == "cs":
            self.set_inputs(inputs, t)
            if self.fmi3:
                st = self._do_step(self._c, t, h, True, *self._flag_refs)
            else:
                st = self._do_step(self._c, t, h, 1)
            self._check(st, "doStep", t)
            return
        if self.solver == "rk4":
            self._rk4(t, h, inputs, input_fn)
        else:
            self._adaptive(t, h, inputs, input_fn)
        self._finish_me_step(t + h, inputs, input_fn)

    # -- model exchange -----------------------------------------------------------------------
    def _deriv(self, t: float, x: np.ndarray, inputs: Binding, input_fn) -> np.ndarray:
        self._check(self._set_time(self._c, t), "setTime", t)
        if input_fn is not None:
            input_fn(t, inputs.view)
        self.set_inputs(inputs, t)
        if self.nx:
            self.xv[:] = x
            self._check(self._set_states(self._c, self._x, self.nx), "setContinuousStates", t)
            self._check(self._get_der(self._c, self._dx, self.nx), "getDerivatives", t)
        return self.dxv.copy()

    def states(self) -> np.ndarray:
        if self.nx:
            self._check(self._get_states(self._c, self._x, self.nx), "getContinuousStates", 0.0)
        return self.xv.copy()

    def _rk4(self, t: float, h: float, inputs: Binding, input_fn) -> None:
        x = self.states()
        n = self.substeps
        dt = h / n
        for i in range(n):
            ti = t + i * dt
            k1 = self._deriv(ti, x, inputs, input_fn)
            k2 = self._deriv(ti + dt / 2, x + dt / 2 * k1, inputs, input_fn)
            k3 = self._deriv(ti + dt / 2, x + dt / 2 * k2, inputs, input_fn)
            k4 = self._deriv(ti + dt, x + dt * k3, inputs, input_fn)
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self._x_end = x

    def _adaptive(self, t: float, h: float, inputs: Binding, input_fn) -> None:
        from scipy.integrate import solve_ivp

        x0 = self.states()
        if not self.nx:
            self._x_end = x0
            return
        sol = solve_ivp(lambda tt, xx: self._deriv(tt, xx, inputs, input_fn), (t, t + h), x0,
                        method="DOP853", rtol=self.rtol, atol=self.rtol * 1e-3)
        if not sol.success:
            raise FMUError(f"FMU '{self.name}': adaptive solver failed at t={t:g} ({sol.message})")
        self._x_end = sol.y[:, -1]

    def _finish_me_step(self, t: float, inputs: Binding, input_fn) -> None:
        self._check(self._set_time(self._c, t), "setTime", t)
        if input_fn is not None:
            input_fn(t, inputs.view)
        self.set_inputs(inputs, t)
        if self.nx:
            self.xv[:] = self._x_end
            self._check(self._set_states(self._c, self._x, self.nx), "setContinuousStates", t)
        st = self._completed(self._c, True if self.fmi3 else 1, *self._cflag_refs)
        self._check(st, "completedIntegratorStep", t)
        if self._cflags[0].value:
            self._check(self._raw[("fmi3" if self.fmi3 else "fmi2") + "EnterEventMode"](self._c),
                        "enterEventMode", t)
            self._event_iteration()
            self._fmu.enterContinuousTimeMode()

    # -- end ----------------------------------------------------------------------------------
    def reset(self) -> None:
        if self._fmu is not None:
            self._guard("reset", self._fmu.reset, 0.0)

    def close(self) -> None:
        fmu, self._fmu = self._fmu, None
        if fmu is None:
            return
        try:
            fmu.terminate()
        except Exception:  # noqa: BLE001 - terminate after an error may fail; free anyway
            pass
        try:
            fmu.freeInstance()
        except Exception:  # noqa: BLE001
            pass
