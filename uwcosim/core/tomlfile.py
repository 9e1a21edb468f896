"""Read a TOML file of the user (scenario, campaign, variable map) with one-line errors.

:func:`read_toml` is the one place that turns a missing, unreadable, non-UTF-8 or malformed
file into a :class:`~uwcosim.core.errors.ScenarioError` naming the file. A document nested
more than :data:`MAX_DEPTH` levels deep (arrays in arrays, inline tables in inline tables) is
refused in one line: ``tomllib`` is recursive and would otherwise end in a ``RecursionError``,
and so would everything that walks the data afterwards. :func:`toml_inline` writes a value
back as one inline TOML value (for the ``--set`` overrides a run records).
"""

from __future__ import annotations

import datetime
import json
import math
import tomllib
from pathlib import Path
from typing import Any

from uwcosim.core.errors import ScenarioError

#: deepest nesting of arrays and tables accepted in a user's TOML (a scenario needs about 5)
MAX_DEPTH = 64


def nesting_depth(value: Any) -> int:
    """How deep lists and dicts nest in ``value`` (a scalar: 0), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, dict | list):
            deepest = max(deepest, d + 1)
            if d + 1 <= MAX_DEPTH:  # deeper than that is refused anyway: stop counting
                stack.extend((c, d + 1) for c in (v.values() if isinstance(v, dict) else v))
    return deepest


def toml_inline(value: Any) -> str:
    """``value`` (as ``tomllib`` returns it) as one inline TOML value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # JSON's escapes are TOML basic-string escapes
    if isinstance(value, datetime.date | datetime.time):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(toml_inline(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_inline(v)}"
                               for k, v in value.items()) + "}"
    raise TypeError(f"not a TOML value: {type(value).__name__}")



def read_toml(path: str | Path, what: str, where: str | None = None) -> tuple[str, dict]:
    """``(text, data)`` of the TOML file ``path``; ``what`` names it in messages (``"scenario"``)
    and ``where`` is the prefix of the messages (default: the path)."""
    path = Path(path)
    where = str(path) if where is None else where
    if not path.is_file():
        if path.is_dir():
            raise ScenarioError(f"{where}: is a folder; expected a {what} file (.toml)")
        if path.is_symlink() and not path.exists():
            raise ScenarioError(f"{where}: a symbolic link to nothing (or a loop of links); "
                                f"expected a {what} file")
        if path.exists():
            raise ScenarioError(f"{where}: not a regular file (a FIFO, socket or device); "
                                f"expected a {what} file")
        raise ScenarioError(f"{where}: {what} file not found")
    try:
        # utf-8-sig: a byte-order mark (some Windows editors write one) is not TOML
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{where}: not a UTF-8 text file (byte {exc.start}: {exc.reason})"
                            ) from None
    except OSError as exc:
        raise ScenarioError(f"{where}: cannot read the {what} ({exc.strerror or exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: invalid TOML ({exc})") from None
    except RecursionError:
        raise ScenarioError(f"{where}: arrays or tables nested too deeply (at most "
                            f"{MAX_DEPTH} levels)") from None
    if nesting_depth(data) > MAX_DEPTH:
        raise ScenarioError(f"{where}: arrays or tables nested too deeply (at most "
                            f"{MAX_DEPTH} levels)")
    return text, data
