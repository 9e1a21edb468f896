"""Shared fixtures and helpers of the FMU tests (import them; this is not a conftest).

``fmu_dir``: every FMU of the project, copied once per test session into a temporary folder.
:class:`Instance`: one FMU instance driven through fmpy's low-level API by variable name, with
its log messages captured (FMI 2.0 and 3.0, co-simulation and model exchange).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi2 import (
    FMU2Model,
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy.fmi3 import FMU3Model, FMU3Slave

from uwcosim.fmu.build import archive_name, build_fmus

CS, ME = "CoSimulation", "ModelExchange"


_BUILT: dict[str, Path] = {}  # one build per session, whichever test module asks first


@pytest.fixture(scope="session")
def fmu_dir(project_fmus, tmp_path_factory) -> Path:
    """All FMUs (every model, FMI 3.0 and 2.0) in a session temporary folder that the build
    tests may rebuild into: copies of ``fmus/``'s archives, which ``project_fmus`` built or
    brought up to date (a second build of all of them cost 15-35 s of every test session)."""
    if "dir" not in _BUILT:
        out = tmp_path_factory.mktemp("fmus")
        for path in build_fmus(project_fmus):  # up to date: nothing is compiled
            shutil.copy2(path, out / path.name)
        _BUILT["dir"] = out
    return _BUILT["dir"]


def fmu_path(fmu_dir: Path, model: str, fmi_version: str = "3.0") -> Path:
    return fmu_dir / archive_name(model, fmi_version)


class Instance:
    """One FMU instance, driven by variable name; ``messages`` collects (status, text)."""

    def __init__(self, path: Path, interface: str = CS, name: str | None = None,
                 unzipdir: str | None = None) -> None:
        self.md = read_model_description(str(path))
        self.fmi3 = self.md.fmiVersion.startswith("3")
        self.interface = interface
        self._tmp = None if unzipdir else extract(str(path))
        self.dir = unzipdir or self._tmp
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.messages: list[tuple[int, str]] = []
        cls = {(True, CS): FMU3Slave, (True, ME): FMU3Model,
               (False, CS): FMU2Slave, (False, ME): FMU2Model}[(self.fmi3, interface)]
        self.fmu = cls(guid=self.md.guid, unzipDirectory=self.dir, instanceName=name,
                       modelIdentifier=self.md.coSimulation.modelIdentifier)
        if self.fmi3:
            self.fmu.instantiate(logMessage=self._log3)
        else:
            # no fmpy.logging.addLoggerProxy: it keeps ONE global logger for all instances
            # (a later simulate_fmu would call this instance's freed callback). uwcosim FMUs
            # pass formatted messages with '%' escaped as '%%'.
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(self._log2)
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self._callbacks = cb
            self.fmu.instantiate(callbacks=cb)

    def _log3(self, env, status, category, message) -> None:
        self.messages.append((status, message.decode()))

    def _log2(self, env, instance_name, status, category, message) -> None:
        self.messages.append((status, message.decode().replace("%%", "%")))

    @property
    def log(self) -> str:
        return "\n".join(text for _, text in self.messages)

    def set(self, **values) -> None:
        for name, value in values.items():
            if self.types[name] == "String":
                self.fmu.setString([self.vr[name]], [value])
            elif self.fmi3:
                self.fmu.setFloat64([self.vr[name]], [float(value)])
            else:
                self.fmu.setReal([self.vr[name]], [float(value)])

    def get(self, *names: str) -> list[float]:
        vrs = [self.vr[n] for n in names]
        return self.fmu.getFloat64(vrs) if self.fmi3 else self.fmu.getReal(vrs)

    def init(self, start_time: float = 0.0, **start) -> None:
        """Set start values, then enter and leave initialization mode (ME: to continuous
        time mode)."""
        if not self.fmi3:
            self.fmu.setupExperiment(startTime=start_time)
        self.set(**start)
        if self.fmi3:
            self.fmu.enterInitializationMode(startTime=start_time)
        else:
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        if self.interface == ME:
            if self.fmi3:
                self.fmu.updateDiscreteStates()
            else:
                self.fmu.newDiscreteStates()
            self.fmu.enterContinuousTimeMode()

    def step(self, t: float, h: float) -> None:
        self.fmu.doStep(t, h)

    def free(self) -> None:
        self.fmu.freeInstance()
        if self._tmp:
            shutil.rmtree(self._tmp, ignore_errors=True)
