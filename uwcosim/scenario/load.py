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


def _allowed_keys(model: type[BaseModel] | None) -> str:
    if model is None:
        return ""
    return ", ".join(model.model_fields)


def _submodel(loc: tuple, root: type[BaseModel]) -> type[BaseModel] | None:
    """The pydantic model that owns the key at ``loc`` (for 'expected one of')."""
    model: Any = root
    for part in loc[:-1]:
        if isinstance(part, int) or model is None:
            continue
        field = getattr(model, "model_fields", {}).get(part)
        if field is None:
            continue
        ann = field.annotation
        args = getattr(ann, "__args__", ())
        candidates = [a for a in (ann, *args) if isinstance(a, type) and issubclass(a, BaseModel)]
        model = candidates[0] if candidates else None
    return model


def format_validation_error(
    exc: ValidationError, where: str, root: type[BaseModel] = Scenario
) -> str:
    err = exc.errors()[0]
    loc = tuple(p for p in err["loc"] if not (isinstance(p, str) and p in ("bernoulli",
                                                                           "gilbert_elliott")))
    key = ".".join(str(p) for p in loc) or "(top level)"
    etype = err["type"]
    if etype == "extra_forbidden":
        allowed = _allowed_keys(_submodel(loc, root))
        return f"{where}: key '{key}': unknown key (expected one of: {allowed})"
    if etype == "missing":
        return f"{where}: key '{key}': required key is missing"
    msg = err["msg"]
    if "input" in err and etype not in ("value_error",):
        got = repr(err["input"])
        got = got if len(got) <= 60 else got[:57] + "..."
        return f"{where}: key '{key}': {msg} (got {got})"
    return f"{where}: key '{key}': {msg}"


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


def load_scenario(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                  overrides_base: str | Path | None = None) -> LoadedScenario:
    """Read, override and validate a scenario (a TOML file, or an ``.ssp`` run alone); raise
    ScenarioError with one line on failure.

    ``overrides_base``: the folder that relative paths in ``overrides`` are relative to (the
    command line passes the current folder); by default they are relative to the scenario file,
    like the paths written in it. Either way they are recorded as absolute paths.
    """
    path = Path(path)
    where = str(path)
    # recorded with absolute paths, so that the run's log says which files it used
    overrides = absolute_path_overrides(
        overrides, Path(overrides_base) if overrides_base is not None else path.resolve().parent,
        where)
    if path.suffix.lower() == ".ssp":
        from uwcosim.ssp.scenario import load_ssp

        return load_ssp(path, overrides)
    text, data = read_toml(path, "scenario", where)
    for keys, value in parse_overrides(overrides, where):
        _apply(data, keys, value, where)
    ssp = None
    if isinstance(data.get("system"), dict) and "ssp" in data["system"]:
        from uwcosim.ssp.scenario import merge_system

        ssp = merge_system(data, path, where)
    try:
        spec = Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(exc, where)) from None
    return LoadedScenario(spec=spec, path=path.resolve(), text=text, overrides=tuple(overrides),
                          ssp=ssp)
