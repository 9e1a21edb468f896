"""``uwcosim check``: every problem of a scenario, without running it.

Three levels, each a list of one-line :class:`~uwcosim.scenario.validate.Problem` s naming
the file, the key and what was expected:

1. the scenario's data (:func:`uwcosim.scenario.validate.validate_data`, also run at load
   time): the schema, each ``[estimators.NAME]`` against its filter's settings, the
   cross-references that need no FMU;
2. :func:`check_fmus`: the scenario against the FMUs' model descriptions (variables,
   causalities, types, shapes and integer ranges of connections, start values and
   parameters, algebraic loops; the master's own checks, run in its collecting mode,
   :class:`uwcosim.master.master.Master` ``check_only``; the FMUs' own checks at load, e.g.
   duplicate value references, a missing instantiation token), ``model.truth`` outputs, the
   ``[log] signals`` patterns that match no signal and the ``map.fmu_parameter`` variable;
3. :func:`check_filters`: the map is read, the vehicle's start position checked against it
   (:func:`start_position_problem`), the filters' model built and every estimator constructed
   at the initial state (what the constructors check: measurement names, grid memory, ...).

A replay scenario (``[replay]``) has no FMUs: its second level is :func:`check_replay`, the
recorded file read and checked (columns, units, time stamps) as a run reads it.

:func:`check_scenario` runs all three (exit 0 ok, 2 scenario problems, 3 FMU problems only);
levels that depend on a refused one are skipped.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from uwcosim.core.errors import ScenarioError, UwcosimError
from uwcosim.core.plugins import describe_error
from uwcosim.filters.base import build
from uwcosim.fmi.archive import open_archive, unpacked_limit
from uwcosim.master.master import Master
from uwcosim.models.terrain import Bathymetry
from uwcosim.run.factory import build_model, scenario_map
from uwcosim.run.recorder import pattern_problems
from uwcosim.run.replay import replay_source
from uwcosim.scenario.load import read_scenario
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.system import to_system
from uwcosim.scenario.validate import (
    Problem,
    reference_problems,
    validate_data,
    validated_settings,
)


@dataclass
class CheckReport:
    """What ``uwcosim check`` found."""

    path: Path
    problems: list[Problem] = field(default_factory=list)
    checked: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        codes = {p.exit_code for p in self.problems}
        return 0 if not codes else 2 if codes != {3} else 3


def check_fmus(loaded: LoadedScenario) -> list[Problem]:
    """The scenario against the FMUs' model descriptions (no FMU instantiated)."""
    try:
        master = Master(to_system(loaded), check_only=True)
    except UwcosimError as exc:
        return [Problem.of(exc)]
    try:
        problems = [Problem.of(e) for e in master.problems]
        if not problems and loaded.spec.model is not None:
            for s in loaded.spec.model.truth:
                try:
                    master.slot(s, "model.truth")
                except UwcosimError as exc:
                    problems.append(Problem.of(exc))
        problems += [Problem.of(e) for e in
                     pattern_problems(master, loaded.spec.log.signals, str(loaded.path))]
        problem = map_parameter_problem(loaded, master)
        if problem is not None:
            problems.append(Problem.of(problem))
        return problems
    finally:
        master.close()


def map_parameter_problem(loaded: LoadedScenario, master: Master) -> ScenarioError | None:
    """``map.fmu_parameter`` naming a variable its FMU does not have (a run sets the map file
    there at initialization), named as that key."""
    spec = loaded.spec
    if spec.map is None or spec.map.kind is None or not spec.map.fmu_parameter:
        return None
    fmu, _, par = spec.map.fmu_parameter.partition(".")
    adapter = master.adapters.get(fmu)
    if adapter is None or par in adapter.fmu_variables or par in adapter.variables:
        return None  # another FMU: the scenario's cross-references say so
    return ScenarioError(f"{loaded.path}: key 'map.fmu_parameter': FMU '{fmu}' has no variable "
                         f"{par!r} (expected the String parameter that takes the map file, "
                         f"e.g. 'sounder.mapFile')")


def start_position_problem(loaded: LoadedScenario, bathy: Bathymetry | None) -> Problem | None:
    """The vehicle's start position outside the map: the start values (the scenario's, else
    the FMU's) of what drives the ``x`` and ``y`` inputs of the map's FMU; the run would fail
    at its first step."""
    spec = loaded.spec
    if bathy is None or spec.map is None or not spec.map.fmu_parameter:
        return None
    fmu = spec.map.fmu_parameter.partition(".")[0]
    drivers = {dst: src for src, dst in spec.connections}
    position, source = [], None
    for axis in ("x", "y"):
        src = drivers.get(f"{fmu}.{axis}")
        name, _, var = (src or "").partition(".")
        f = spec.fmus.get(name)
        if f is None or f.map is not None:  # not an FMU, or a variable map's role
            return None
        value = f.start.get(var)
        if value is None:
            try:
                with unpacked_limit(spec.run.fmu_max_unpacked_mb):
                    md = open_archive(loaded.resolve(f.path))
            except UwcosimError:
                return None
            value = next((v.start for v in md.modelVariables if v.name == var), None)
        try:
            position.append(float(value))
        except (TypeError, ValueError):
            return None
        source = name
    x, y = position
    if bool(bathy.inside(np.asarray(x), np.asarray(y))):
        return None
    xmin, xmax, ymin, ymax = bathy.extent
    return Problem(f"{loaded.path}: key 'fmus.{source}.start': the vehicle starts at (x, y) = "
                   f"({x:g}, {y:g}) m, outside the map (x in [{xmin:g}, {xmax:g}], y in "
                   f"[{ymin:g}, {ymax:g}]): FMU '{fmu}' would fail at the start time", 3)


def check_replay(loaded: LoadedScenario) -> list[Problem]:
    """A replay's file against its ``[replay]`` mapping (read as :func:`uwcosim.run.simulate.
    simulate` reads it: columns, types, units, time stamps)."""
    try:
        model = build_model(loaded, scenario_map(loaded))
        replay_source(loaded, None, tuple(model.measurement_names))
    except UwcosimError as exc:
        return [Problem.of(exc)]
    return []


def check_filters(loaded: LoadedScenario) -> list[Problem]:
    """Read the map, build the filters' model and construct every estimator at ``x = 0``."""
    spec, where = loaded.spec, str(loaded.path)
    try:
        bathy = scenario_map(loaded)
        if not spec.estimators:
            problem = start_position_problem(loaded, bathy)
            return [] if problem is None else [problem]
        model = build_model(loaded, bathy)
    except UwcosimError as exc:
        return [Problem.of(exc)]
    problem = start_position_problem(loaded, bathy)
    out = [] if problem is None else [problem]
    for name, es in spec.estimators.items():
        std = es.initial_std or (spec.estimation.initial_std if spec.estimation else None)
        P0 = np.diag(np.asarray(std if std else np.ones(model.nx), float) ** 2)
        try:
            if P0.shape != (model.nx, model.nx):
                raise ValueError(f"initial_std has {len(std)} values for {model.nx} states")
            build(es.type, model, np.zeros(model.nx), P0, validated_settings(es),
                  rng=np.random.default_rng(0))
        except (UwcosimError, ValueError, TypeError, MemoryError) as exc:
            out.append(Problem(f"{where}: key 'estimators.{name}': {exc}"))
        except Exception as exc:  # noqa: BLE001 - a user's filter or model: its error, one line
            out.append(Problem(f"{where}: key 'estimators.{name}': constructing {es.type!r} "
                               f"failed: {describe_error(exc)}"))
    return out


def check_scenario(path: str | Path, overrides: Sequence[str] = (),
                   overrides_base: str | Path | None = None) -> CheckReport:
    """Every problem of a scenario: schema, references, FMUs, map and filters (nothing runs)."""
    report = CheckReport(Path(path))
    try:
        data, loaded = read_scenario(path, overrides, overrides_base)
    except UwcosimError as exc:
        report.problems.append(Problem.of(exc))
        return report
    if loaded.spec is not None:  # an .ssp alone: validated by its reader
        spec, report.problems = loaded.spec, reference_problems(loaded.spec, str(path))
    else:
        spec, report.problems = validate_data(data, str(Path(path)))
    report.checked.append("schema")
    if spec is None:
        return report
    loaded = replace(loaded, spec=spec)
    if spec.replay is not None:
        if not report.problems:
            report.problems += check_replay(loaded)
            report.checked.append("replay file")
    else:
        report.problems += check_fmus(loaded)
        report.checked.append("FMUs")
    if not report.problems:
        report.problems += check_filters(loaded)
        report.checked.append("map and filters")
    report.problems = list(dict.fromkeys(report.problems))  # the master repeats run.duration
    return report
