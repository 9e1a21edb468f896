"""Read a TOML file of the user (scenario, campaign, variable map) with one-line errors.

:func:`read_toml` is the one place that turns a missing, unreadable, non-UTF-8 or malformed
file into a :class:`~uwcosim.core.errors.ScenarioError` naming the file.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from uwcosim.core.errors import ScenarioError


def read_toml(path: str | Path, what: str, where: str | None = None) -> tuple[str, dict]:
    """``(text, data)`` of the TOML file ``path``; ``what`` names it in messages (``"scenario"``)
    and ``where`` is the prefix of the messages (default: the path)."""
    path = Path(path)
    where = str(path) if where is None else where
    if not path.is_file():
        raise ScenarioError(f"{where}: {what} file not found")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{where}: not a UTF-8 text file (byte {exc.start}: {exc.reason})"
                            ) from None
    except OSError as exc:
        raise ScenarioError(f"{where}: cannot read the {what} ({exc.strerror or exc})") from None
    try:
        return text, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: invalid TOML ({exc})") from None
