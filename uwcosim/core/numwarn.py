"""Numerical warnings of a run (numpy's ``RuntimeWarning`` s): one line each, recorded.

numpy warns on stderr when a computation overflows, divides by zero or meets an invalid value
(``RuntimeWarning: divide by zero encountered in divide`` and the source line under it), e.g.
a particle filter's weights with a zero measurement noise. A run catches them instead
(:class:`NumericalWarnings`, entered by :func:`uwcosim.run.simulate.simulate`): the first of
each kind (message and source line) is one log line, ``numerical warning at FILE:LINE:
MESSAGE``, the rest are counted, and :meth:`NumericalWarnings.entries` goes into
``simulation.json`` and ``summary.json`` as ``warnings`` (``message``, ``where``, ``count``).
Nothing is silenced that a run did not print before; only how it is shown changes.
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

log = logging.getLogger(__name__)


class NumericalWarnings:
    """A context in which ``RuntimeWarning`` s are logged once per kind and counted."""

    def __init__(self) -> None:
        self._counts: dict[tuple[str, str], int] = {}
        self._catch: warnings.catch_warnings | None = None

    def __enter__(self) -> NumericalWarnings:
        self._catch = warnings.catch_warnings()
        self._catch.__enter__()
        warnings.simplefilter("always", RuntimeWarning)  # counted here, not deduplicated
        previous = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None) -> None:
            if not issubclass(category, RuntimeWarning):
                previous(message, category, filename, lineno, file, line)
                return
            key = (str(message), f"{_short(filename)}:{lineno}")
            n = self._counts.get(key, 0)
            self._counts[key] = n + 1
            if n == 0:
                log.warning("numerical warning at %s: %s (counted in summary.json "
                            "'warnings')", key[1], key[0])

        warnings.showwarning = show
        return self

    def __exit__(self, *exc) -> None:
        if self._catch is not None:
            self._catch.__exit__(*exc)
            self._catch = None

    def entries(self) -> list[dict]:
        """``[{"message", "where", "count"}, ...]`` in the order they first came."""
        return [{"message": m, "where": w, "count": n} for (m, w), n in self._counts.items()]


def _short(filename: str) -> str:
    """``uwcosim/...`` for the package's files, else the file name."""
    parts = Path(filename).parts
    if "uwcosim" in parts:
        i = len(parts) - 1 - parts[::-1].index("uwcosim")
        return "/".join(parts[i:])
    return Path(filename).name
