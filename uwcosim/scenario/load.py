"""Load a scenario TOML file, apply ``--set key=value`` overrides and validate the schema.

Relative paths written in a scenario are relative to the scenario file; relative paths given in
``--set`` overrides on the command line are relative to the current folder (see
:func:`absolute_path_overrides`). Every problem becomes one
:class:`~uwcosim.errors.ScenarioError` line naming the file, the key and what was expected.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from uwcosim.errors import ScenarioError
from uwcosim.scenario.schema import Scenario
from uwcosim.tomlfile import read_toml


@dataclass(frozen=True)
class LoadedScenario:
    """A validated scenario with its source text, the file it came from and its hash."""

    spec: Scenario
    path: Path
    text: str
    overrides: tuple[str, ...]
    #: the SSP of ``[system] ssp`` or of an ``.ssp`` run (:class:`uwcosim.ssp.scenario.SSPArchive`)
    ssp: Any = None

    @property
    def base_dir(self) -> Path:
        return self.path.parent

    def resolve(self, relpath: str) -> Path:
        p = Path(relpath)
        return p if p.is_absolute() else (self.base_dir / p).resolve()

    @property
    def sha256(self) -> str:
        h = hashlib.sha256(self.text.encode())
        for o in self.overrides:
            h.update(b"\0" + o.encode())
        if self.ssp is not None:
            h.update(b"\0ssp:" + self.ssp.sha256.encode())
        return h.hexdigest()


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # bare words are strings: --set estimators.pf.resampling=systematic


def parse_overrides(items: list[str] | tuple[str, ...], where: str) -> list[tuple[list[str], Any]]:
    out = []
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"{where}: --set {item!r}: expected KEY=VALUE")
        out.append((key.strip().split("."), _parse_value(value.strip())))
    return out


def _apply(data: dict, keys: list[str], value: Any, where: str) -> None:
    node = data
    for i, k in enumerate(keys[:-1]):
        nxt = node.get(k)
        if nxt is None:
            nxt = node[k] = {}
        if not isinstance(nxt, dict):
            raise ScenarioError(
                f"{where}: --set {'.'.join(keys)}: {'.'.join(keys[: i + 1])} is not a table"
            )
        node = nxt
    node[keys[-1]] = value


def format_validation_error(exc: ValidationError, where: str,
                            root: type[BaseModel] = Scenario) -> str:
    """The first problem of a pydantic error, one line (and how many more there are)."""
    from uwcosim.scenario.validate import schema_problems

    problems = schema_problems(exc, where, root)
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    return problems[0].message + more


def _is_path_key(keys: list[str]) -> bool:
    """``fmus.NAME.path``, ``fmus.NAME.map`` (a map file) and ``map.file`` hold file paths."""
    return (len(keys) == 3 and keys[0] == "fmus" and keys[2] in ("path", "map")) \
        or keys == ["map", "file"]


def absolute_path_overrides(overrides, base: Path, where: str) -> tuple[str, ...]:
    """``--set`` overrides with relative file paths made absolute against ``base``.

    A path typed on the command line means a file relative to the current folder, not to the
    scenario file; the rewritten override (``key="/abs/path"``) is what the run records.
    """
    out = []
    for item in overrides:
        keys, value = parse_overrides([item], where)[0]
        if _is_path_key(keys) and isinstance(value, str) and not Path(value).is_absolute():
            item = f"{'.'.join(keys)}={json.dumps(str((Path(base) / value).resolve()))}"
        out.append(item)
    return tuple(out)


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
        from uwcosim.ssp.scenario import load_ssp

        loaded = load_ssp(path, overrides)  # validated by its reader: spec set
        return {}, loaded
    text, data = read_toml(path, "scenario", where)
    for keys, value in parse_overrides(overrides, where):
        _apply(data, keys, value, where)
    ssp = None
    if isinstance(data.get("system"), dict) and "ssp" in data["system"]:
        from uwcosim.ssp.scenario import merge_system

        ssp = merge_system(data, path, where)
    return data, LoadedScenario(spec=None, path=path.resolve(), text=text,
                                overrides=tuple(overrides), ssp=ssp)


def load_scenario(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                  overrides_base: str | Path | None = None) -> LoadedScenario:
    """Read, override and validate a scenario (a TOML file, or an ``.ssp`` run alone); raise
    ScenarioError with one line on failure: the first problem and how many more there are
    (``uwcosim check`` lists them all, :mod:`uwcosim.scenario.validate`).

    ``overrides_base``: the folder that relative paths in ``overrides`` are relative to (the
    command line passes the current folder); by default they are relative to the scenario file,
    like the paths written in it. Either way they are recorded as absolute paths.
    """
    from dataclasses import replace

    from uwcosim.scenario.validate import first_error, validate_data

    data, loaded = read_scenario(path, overrides, overrides_base)
    if loaded.spec is not None:  # an .ssp alone: validated by its reader
        return loaded
    spec, problems = validate_data(data, str(Path(path)))
    if problems:
        raise first_error(problems) from None
    return replace(loaded, spec=spec)
