"""Load a scenario TOML file, apply ``--set key=value`` overrides and validate the schema.

Relative paths written in a scenario are relative to the scenario file; relative paths given in
``--set`` overrides on the command line are relative to the current folder (see
:func:`absolute_path_overrides`). Every problem becomes one
:class:`~uwcosim.core.errors.ScenarioError` line naming the file, the key and what was expected.
"""

from __future__ import annotations

from dataclasses import replace
from math import inf
from pathlib import Path

from uwcosim.core.errors import ScenarioError
from uwcosim.core.tomlfile import read_toml
from uwcosim.fmi.archive import unpacked_limit
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.overrides import absolute_path_overrides, apply_override, parse_overrides
from uwcosim.scenario.ssp.convert import load_ssp, merge_system
from uwcosim.scenario.validate import first_error, validate_data


def read_scenario(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                  overrides_base: str | Path | None = None) -> tuple[dict, LoadedScenario]:
    """Read a scenario and apply the overrides, without validating: ``(data, loaded)`` with
    ``loaded.spec`` None (an ``.ssp`` alone: validated, ``data`` empty). File, TOML and ``--set``
    syntax errors raise ScenarioError."""
    path = Path(path)
    where = str(path)
    # recorded with absolute paths, so that the run's log says which files it used
    overrides = absolute_path_overrides(
        overrides, Path(overrides_base) if overrides_base is not None else path.resolve().parent,
        where)
    if path.suffix.lower() == ".ssp":
        loaded = load_ssp(path, overrides)  # validated by its reader: spec set
        return {}, loaded
    text, data = read_toml(path, "scenario", where)
    for keys, value in parse_overrides(overrides, where):
        apply_override(data, keys, value, where)
    ssp = None
    if isinstance(data.get("system"), dict) and "ssp" in data["system"]:
        with unpacked_limit(_max_unpacked_mb(data, where)):
            ssp = merge_system(data, path, where)
    return data, LoadedScenario(spec=None, path=path.resolve(), text=text,
                                overrides=tuple(overrides), ssp=ssp)


def _max_unpacked_mb(data: dict, where: str) -> float | None:
    """``run.fmu_max_unpacked_mb`` before the scenario is validated (the SSP is read first),
    checked as the schema checks it."""
    run = data.get("run")
    value = run.get("fmu_max_unpacked_mb") if isinstance(run, dict) else None
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < inf:
        raise ScenarioError(f"{where}: key 'run.fmu_max_unpacked_mb': expected a positive "
                            f"number of MiB (got {value!r})")
    return float(value)


def load_scenario(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                  overrides_base: str | Path | None = None) -> LoadedScenario:
    """Read, override and validate a scenario (a TOML file, or an ``.ssp`` run alone); raise
    ScenarioError with one line on failure: the first problem and how many more there are
    (``uwcosim check`` lists them all, :mod:`uwcosim.scenario.validate`).

    ``overrides_base``: the folder that relative paths in ``overrides`` are relative to (the
    command line passes the current folder); by default they are relative to the scenario file,
    like the paths written in it. Either way they are recorded as absolute paths.
    """
    data, loaded = read_scenario(path, overrides, overrides_base)
    if loaded.spec is not None:  # an .ssp alone: validated by its reader
        return loaded
    spec, problems = validate_data(data, str(Path(path)))
    if problems:
        raise first_error(problems) from None
    return replace(loaded, spec=spec)
