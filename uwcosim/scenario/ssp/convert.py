"""SSP files as scenarios: ``[system] ssp = "vehicle.ssp"`` in a scenario, or an ``.ssp`` alone.

The SSP becomes the same scenario data the TOML loader validates: each FMU component an
``[fmus.NAME]`` entry (the FMU extracted from the archive into a folder owned by the loaded
scenario, removed when it is garbage collected or at exit; its bound parameters as
``parameters`` and, for other variables, ``start``), each connection a ``connections`` entry
(with ``{factor, offset}`` when units or a linear transformation change the value) and the
DefaultExperiment the ``[run]`` start and duration. The scenario's own keys win: it may add
FMUs, connections, parameters, and set ``[run]``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import tomli_w
from pydantic import ValidationError

from uwcosim.core.errors import ScenarioError
from uwcosim.core.scratch import Scratch
from uwcosim.fmi.archive import sha256_file
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.overrides import apply_override, parse_overrides
from uwcosim.scenario.schema import Scenario
from uwcosim.scenario.ssp.read import FlatSystem, read_ssp
from uwcosim.scenario.validate import format_validation_error

log = logging.getLogger(__name__)


class SSPArchive:
    """An SSP read for one scenario: its flat system, its sha256 and the folder of its FMUs."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path).resolve()
        self.sha256 = sha256_file(self.path)
        self._scratch = Scratch(self, "uwcosim-ssp-")
        self.dir = Path(self._scratch.path)
        try:
            self.system: FlatSystem = read_ssp(self.path, self.dir)
        except BaseException:
            self.cleanup()
            raise
        for name in self.system.ignored:
            if name.endswith(")"):  # says why itself
                log.warning("%s: %s: ignored (SSP)", self.path.name, name)
            else:
                log.warning("%s: parameter %s matches no variable: ignored (SSP)",
                            self.path.name, name)
        if self.system.not_validated:
            log.warning("%s: %d element(s) or attribute(s) only SSP 2.0 defines were not "
                        "validated (fmpy has the SSP 1.0 schema only; first: %s)",
                        self.path.name, len(self.system.not_validated),
                        self.system.not_validated[0])

    def cleanup(self) -> None:
        """Remove the extracted FMUs now (otherwise done at garbage collection or exit)."""
        self._scratch.cleanup()


def _connections(system: FlatSystem) -> list[list]:
    out = []
    for c in system.connections:
        entry: list = [c.src, c.dst]
        if (c.factor, c.offset) != (1.0, 0.0):
            entry.append({"factor": c.factor, "offset": c.offset})
        out.append(entry)
    return out


def apply_system(data: dict, system: FlatSystem, where: str, fmu_paths: bool = True,
                 check_run: bool = True) -> None:
    """Merge ``system`` into the scenario data ``data`` (the scenario's own keys win);
    ``check_run``: a ScenarioError when ``[run]`` still lacks its step or duration."""
    if system.description:
        data.setdefault("description", system.description)
    fmus = data.setdefault("fmus", {})
    if isinstance(fmus, dict):
        for c in system.components.values():
            entry = fmus.setdefault(c.name, {})
            if not isinstance(entry, dict):
                continue
            entry.setdefault("path", str(c.fmu) if fmu_paths else c.source)
            if c.interface:
                entry.setdefault("interface", c.interface)
            for key, values in (("parameters", c.parameters), ("start", c.start)):
                own = entry.get(key)
                if values and (own is None or isinstance(own, dict)):
                    entry[key] = {**values, **(own or {})}
    own = data.get("connections", [])
    data["connections"] = _connections(system) + (list(own) if isinstance(own, list) else [])
    run = data.setdefault("run", {})
    if not isinstance(run, dict):
        return
    if system.start_time is not None:
        run.setdefault("start_time", system.start_time)
    if system.stop_time is not None and "duration" not in run:
        run["duration"] = system.stop_time - float(run.get("start_time", 0.0))
    if system.step is not None:
        run.setdefault("step", system.step)
    if check_run and "step" not in run:
        raise ScenarioError(f"{where}: key 'run.step': required: the SSP gives no communication "
                            f"step (SSP 1.0 has none); set it in [run] or with --set run.step=H")
    if check_run and "duration" not in run:
        raise ScenarioError(f"{where}: key 'run.duration': required: the SSP's "
                            f"DefaultExperiment has no stopTime; set it in [run] or with "
                            f"--set run.duration=T")


def merge_system(data: dict, scenario_path: Path, where: str) -> SSPArchive:
    """``[system] ssp = "..."``: read the SSP (relative to the scenario file) into ``data``."""
    ssp = data["system"].get("ssp")
    if not isinstance(ssp, str):
        raise ScenarioError(f"{where}: key 'system.ssp': expected the path of an .ssp file "
                            f"(got {ssp!r})")
    p = Path(ssp)
    p = p if p.is_absolute() else Path(scenario_path).resolve().parent / p
    if not p.is_file():
        raise ScenarioError(f"{where}: key 'system.ssp': file not found: {p}")
    archive = SSPArchive(p)
    apply_system(data, archive.system, where)
    return archive


def equivalent_toml(system: FlatSystem, ssp_name: str, sha256: str) -> str:
    """The scenario an ``.ssp`` alone stands for, as TOML text (FMU paths name the archive
    members); kept in the log metadata as the scenario text."""
    data: dict = {"name": system.name}
    apply_system(data, system, ssp_name, fmu_paths=False, check_run=False)
    return (f"# generated from {ssp_name} (sha256 {sha256}); FMU paths are members of "
            f"the archive\n" + tomli_w.dumps(data))


def load_ssp(path: Path, overrides: list[str] | tuple[str, ...] = ()) -> LoadedScenario:
    """``uwcosim run system.ssp``: the SSP as a plain co-simulation scenario."""
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise ScenarioError(f"{where}: SSP file not found")
    archive = SSPArchive(path)
    text = equivalent_toml(archive.system, path.name, archive.sha256)
    data: dict = {"name": archive.system.name, "run": {}}
    for keys, value in parse_overrides(overrides, where):
        apply_override(data, keys, value, where)
    apply_system(data, archive.system, where)
    try:
        spec = Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(exc, where)) from None
    return LoadedScenario(spec=spec, path=path.resolve(), text=text,
                          overrides=tuple(overrides), ssp=archive)
