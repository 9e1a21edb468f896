"""``--set key=value`` overrides of a scenario: parsing, applying, and their file paths.

A value is TOML (``--set run.duration=600``, ``--set 'sensors.depth.loss={model="bernoulli",
p=0.3}'``); a bare word is a string. A file path typed on the command line is relative to the
current folder, not to the scenario file: :func:`absolute_path_overrides` makes it absolute,
and the rewritten override is what the run records.
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from uwcosim.core.errors import ScenarioError


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # bare words are strings: --set estimators.pf.resampling=systematic


def parse_overrides(items: list[str] | tuple[str, ...], where: str) -> list[tuple[list[str], Any]]:
    """``KEY=VALUE`` items as ``(dotted key split, TOML value)`` pairs (a bare word is a
    string)."""
    out = []
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"{where}: --set {item!r}: expected KEY=VALUE")
        out.append((key.strip().split("."), _parse_value(value.strip())))
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
    """``fmus.NAME.path``, ``fmus.NAME.map`` (a map file) and ``map.file`` hold file paths."""
    return (len(keys) == 3 and keys[0] == "fmus" and keys[2] in ("path", "map")) \
        or keys == ["map", "file"]


def absolute_path_overrides(overrides: Sequence[str], base: Path, where: str) -> tuple[str, ...]:
    """``--set`` overrides with relative file paths made absolute against ``base``.

    A path typed on the command line means a file relative to the current folder, not to the
    scenario file; the rewritten override (``key="/abs/path"``) is what the run records.
    """
    out = []
    for item in overrides:
        keys, value = parse_overrides([item], where)[0]
        if is_path_key(keys) and isinstance(value, str) and not Path(value).is_absolute():
            item = f"{'.'.join(keys)}={json.dumps(str((Path(base) / value).resolve()))}"
        out.append(item)
    return tuple(out)
