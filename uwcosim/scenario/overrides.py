"""``--set key=value`` overrides of a scenario: parsing, applying, and their file paths.

A value is TOML (``--set run.duration=600``, ``--set 'sensors.depth.loss={model="bernoulli",
p=0.3}'``); a bare word is a string. A file path typed on the command line is relative to the
current folder, not to the scenario file: :func:`absolute_path_overrides` makes it absolute,
and the rewritten override is what the run records. That holds for a path inside an inline
table too (``--set 'map={kind="file", file="maps/a.nc"}'``, ``--set 'fmus.dvl={path="x.fmu"}'``).

A value must be one whole TOML value: ``--set "$(printf 'run.duration=20\nstep=2')"`` is
refused rather than read as ``20`` with the rest dropped, and values nested more than
:data:`MAX_DEPTH` levels deep are refused in one line (not a ``RecursionError``).
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from uwcosim.core.errors import ScenarioError
from uwcosim.core.tomlfile import MAX_DEPTH, nesting_depth, toml_inline


def _parse_value(text: str, item: str, where: str) -> Any:
    try:
        doc = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        if "\n" in text or "\r" in text:
            raise ScenarioError(f"{where}: --set {item!r}: the value is not one TOML value "
                                f"(it spans lines); give one KEY=VALUE per --set") from None
        return text  # bare words are strings: --set estimators.pf.resampling=systematic
    except RecursionError:
        raise ScenarioError(f"{where}: --set {item!r}: the value is nested too deeply "
                            f"(at most {MAX_DEPTH} levels)") from None
    if set(doc) != {"v"}:
        raise ScenarioError(f"{where}: --set {item!r}: the value is not one TOML value (a new "
                            f"line starts key {next(k for k in doc if k != 'v')!r}); give one "
                            f"KEY=VALUE per --set")
    if nesting_depth(doc["v"]) > MAX_DEPTH:
        raise ScenarioError(f"{where}: --set {item!r}: the value is nested too deeply "
                            f"(at most {MAX_DEPTH} levels)")
    return doc["v"]


def parse_overrides(items: list[str] | tuple[str, ...], where: str) -> list[tuple[list[str], Any]]:
    """``KEY=VALUE`` items as ``(dotted key split, TOML value)`` pairs (a bare word is a
    string)."""
    out = []
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"{where}: --set {item!r}: expected KEY=VALUE")
        out.append((key.strip().split("."), _parse_value(value.strip(), item, where)))
    return out


def apply_override(data: dict, keys: list[str], value: Any, where: str) -> None:
    """Set ``data[k1][k2]...[kn] = value`` (tables created on the way), one line if a key on
    the way is not a table."""
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


def is_path_key(keys: list[str]) -> bool:
    """``fmus.NAME.path``, ``fmus.NAME.map`` (a map file), ``map.file`` and ``system.ssp``
    hold file paths."""
    return (len(keys) == 3 and keys[0] == "fmus" and keys[2] in ("path", "map")) \
        or keys in (["map", "file"], ["system", "ssp"])


def _absolute_paths(keys: list[str], value: Any, base: Path) -> tuple[Any, bool]:
    """``value`` (set at ``keys``) with its relative file paths, at any depth of inline
    tables, made absolute against ``base``; and whether anything changed."""
    if is_path_key(keys) and isinstance(value, str) and not Path(value).is_absolute():
        return str((Path(base) / value).resolve()), True
    if isinstance(value, dict):
        changed = False
        out = {}
        for k, v in value.items():
            out[k], c = _absolute_paths([*keys, k], v, base)
            changed |= c
        return out, changed
    return value, False


def absolute_path_overrides(overrides: Sequence[str], base: Path, where: str) -> tuple[str, ...]:
    """``--set`` overrides with relative file paths made absolute against ``base``.

    A path typed on the command line means a file relative to the current folder, not to the
    scenario file; the rewritten override (``key="/abs/path"``) is what the run records.
    """
    out = []
    for item in overrides:
        keys, value = parse_overrides([item], where)[0]
        value, changed = _absolute_paths(keys, value, base)
        if changed:
            item = f"{'.'.join(keys)}={toml_inline(value)}"
        out.append(item)
    return tuple(out)
