"""What a run logs, one row per step: an observer of the master that writes its
:class:`~uwcosim.runlog.RunLogger`.

The columns are a :class:`~uwcosim.runlog.columns.LogLayout` (``time``, the logged signals,
the measurements, each estimator's block; the flags after them). :func:`logged_signals` picks
the signals' columns (``[log] signals`` patterns, plus the filters' truth signals when there are
estimators; an array signal has one column per element). A pattern is a glob (``*``, ``?``)
in which brackets are literal (``sig.y[1]`` names one element), or a signal's exact name
(``sig.y`` logs every element of an array). :func:`unmatched_patterns` finds the patterns that
match nothing (with the names nearest to each, for the one-line error).

Row ``k`` is the bus at step ``k`` (:meth:`LogRecorder.on_step`) joined with the estimates of
step ``k`` (:meth:`LogRecorder.estimates`, which the estimator bank calls when it has filtered
the block the step belongs to): rows are paired by their step index and written in order as
soon as both halves are there; a row waiting for its estimates is staged in the logger's tail
file (:meth:`~uwcosim.runlog.RunLogger.stage`: kept if the process dies).
:meth:`LogRecorder.flush` writes what still waits at the end of a run (with NaN estimates where
the bank has none). Columns computed from a row (a
georeferenced run's latitude/longitude) are filled by the ``derive`` function given.
"""

from __future__ import annotations

import difflib
import fnmatch
from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.vartypes import describe
from uwcosim.master.master import Master
from uwcosim.master.observer import StepView
from uwcosim.runlog import RunLogger
from uwcosim.runlog.columns import LogLayout, signal_columns

#: bus signals that are never logged: the master's noise samples
_UNLOGGED = ("noise.", "sensornoise.")


def _glob(pattern: str) -> str:
    """``pattern`` with its brackets literal (element indices, not character classes)."""
    return "".join("[[]" if c == "[" else "[]]" if c == "]" else c for c in pattern)


def _matches(name: str, pattern: str) -> bool:
    return name == pattern or fnmatch.fnmatchcase(name, _glob(pattern))


def _columns(names: Iterable[str], shapes: Mapping[str, tuple[int, ...]]):
    for n in names:
        if not n.startswith(_UNLOGGED):
            yield n, signal_columns(n, tuple(shapes.get(n, ())))


def logged_signals(names: Iterable[str], patterns: Sequence[str],
                   truth: Sequence[str] = (),
                   shapes: Mapping[str, tuple[int, ...]] | None = None) -> list[str]:
    """The columns of the bus signals ``names`` (array signals: ``shapes``) matching
    ``patterns``, then the ``truth`` signals not among them (the filters' truth is always
    logged)."""
    out = []
    for n, cols in _columns(names, shapes or {}):
        if any(_matches(n, p) for p in patterns):
            out += cols
        elif len(cols) > 1:
            out += [c for c in cols if any(_matches(c, p) for p in patterns)]
    return out + [t for t in truth if t not in out]


def unmatched_patterns(names: Iterable[str], patterns: Sequence[str],
                       shapes: Mapping[str, tuple[int, ...]] | None = None,
                       candidates: Iterable[str] = ()) -> list[tuple[str, list[str]]]:
    """``(pattern, nearest names)`` of every pattern that matches no signal (``"*"`` aside:
    it means "whatever there is"); the near names come from the signals' columns and
    ``candidates`` (other variables that could be logged by name)."""
    table = list(_columns(names, shapes or {}))
    out = []
    for p in patterns:
        if p == "*" or any(_matches(n, p) or any(_matches(c, p) for c in cols)
                           for n, cols in table):
            continue
        pool = sorted({c for _, cols in table for c in cols} | {n for n, _ in table}
                      | set(candidates))
        out.append((p, difflib.get_close_matches(p, pool, n=3, cutoff=0.5)))
    return out


def pattern_problems(master: Master, patterns: Sequence[str], where: str) -> list[ScenarioError]:
    """One :class:`ScenarioError` per ``[log] signals`` pattern that matches no signal of
    ``master`` (a :class:`~uwcosim.master.master.Master`), naming the nearest names or why a
    variable it names exactly is not logged."""
    variables = {f"{n}.{v}": var for n, ad in master.adapters.items()
                 for v, var in ad.variables.items()}
    out = []
    for p, near in unmatched_patterns(master.slots, patterns, master.shapes, variables):
        if p.partition(".")[0] in master.unopened:
            continue  # that FMU's problem is reported already
        head = f"{where}: key 'log.signals': pattern {p!r} matches no signal"
        var = variables.get(p)
        if var is not None:
            out.append(ScenarioError(f"{head}: {p!r} has causality {var.causality!r} and type "
                                     f"{describe(var)} (logged are outputs, sources, and by "
                                     f"name locals, states and parameters)"))
        else:
            out.append(ScenarioError(f"{head}" + (f" (nearest: {', '.join(near)})" if near
                                                  else " (and no signal has a similar name)")))
    return out


class LogRecorder:
    """Writes row ``k`` of the log from the step's view and the estimates of step ``k``."""

    def __init__(self, layout: LogLayout, logger: RunLogger, signal_slots: Sequence[int],
                 exact_slots: Sequence[int] = (),
                 exact: Mapping[int, tuple[int, bool]] | None = None,
                 kinds: Sequence[str] = (),
                 derive: Callable[[np.ndarray], None] | None = None,
                 bound: np.ndarray | None = None) -> None:
        """``exact_slots``: the bus slots of the logger's exact columns (String, Int64,
        UInt64), in its order; ``exact``: the side bus position and signedness of the 64-bit
        ones (the others: the text of a String, or the bus value of a narrower integer);
        ``kinds``: "string" or "int" per exact slot. ``derive(row)``: fills the columns
        computed from the rest of a row before it is written (a georeferenced run's
        latitude/longitude, :mod:`uwcosim.run.geocolumns`). ``bound``: ``(K + 1, n)``, the
        ``bound.STATE`` columns of each step (:mod:`uwcosim.run.bound`; NaN past its end)."""
        self.layout, self.logger = layout, logger
        self.derive = derive
        self.bound = bound
        self.sig = np.asarray(signal_slots, dtype=np.intp)
        exact = exact or {}
        kinds = list(kinds) or ["string"] * len(exact_slots)
        #: per exact column: ("x", side bus position, unsigned) | ("s", slot) | ("i", slot)
        self.exact = [("x", *exact[s]) if s in exact else
                      ("s", s) if k == "string" else ("i", s)
                      for s, k in zip(exact_slots, kinds)]
        self.n_flags = len(layout.flags)
        self._with_estimates = bool(layout.measurements or layout.estimators)
        #: step -> (row, flags of the measurements, exact values) waiting for its estimates
        self._rows: dict[int, tuple[np.ndarray, list[bool], list]] = {}
        #: step -> (estimate values, diverged flags) waiting for its row
        self._estimates: dict[int, tuple[np.ndarray, list[bool]]] = {}
        self._next = 0  # the step of the next row to write

    def on_step(self, k: int, view: StepView) -> None:
        """Record row ``k``: time, signals and (with estimators) the step's measurement."""
        lay = self.layout
        row = np.full(lay.width, np.nan)  # NaN where it waits for its estimates
        row[0] = view.t
        row[lay.signal_part] = view.signals(self.sig)
        exact = self._exact(view)
        if not self._with_estimates:
            self.logger.append(row, np.zeros(0, dtype=bool), exact)
            self._next = k + 1
            return
        meas = view.measurement()
        row[lay.measurement_part] = meas.z
        received = [bool(r) for r in meas.received]
        # kept if the process dies before its estimates
        self.logger.stage(k, row, received, exact)
        self._rows[k] = (row, received, exact)
        self._drain()

    def estimates(self, k: int, values: np.ndarray, diverged: list[bool]) -> None:
        """The estimates of step ``k``: every estimator's block, and its diverged flags."""
        self._estimates[k] = (values, diverged)
        self._drain()

    def _write(self, k: int, estimates: tuple[np.ndarray, list[bool]]) -> None:
        row, received, exact = self._rows.pop(k)
        values, diverged = estimates
        row[self.layout.estimates] = values
        if self.derive is not None:
            self.derive(row)
        if self.bound is not None:
            row[self.layout.bound_part] = self.bound[k] if k < len(self.bound) else np.nan
        self.logger.append(row, np.array(received + diverged, dtype=bool), exact)
        self._next = k + 1

    def _drain(self) -> None:
        """Write, in step order, every row whose estimates have come."""
        while self._next in self._rows and self._next in self._estimates:
            self._write(self._next, self._estimates.pop(self._next))

    def flush(self) -> None:
        """Write every row still waiting: with its estimates when the bank gave them, else
        with NaN estimates (a run that ended inside a block the bank did not filter)."""
        self._drain()
        lay = self.layout
        missing = (np.full(lay.estimates.stop - lay.estimates.start, np.nan),
                   [False] * len(lay.estimators))
        for k in sorted(self._rows):
            self._write(k, self._estimates.pop(k, missing))

    def final(self, view: StepView, t: float) -> None:
        """The last row of a run an FMU stopped between two communication points: the signals
        at ``t`` (the stopped FMU's outputs at its termination time; the others' at the last
        communication point), no measurements or estimates."""
        lay = self.layout
        row = np.full(lay.width, np.nan)
        row[0] = t
        row[lay.signal_part] = view.signals(self.sig)
        self.logger.append(row, np.zeros(self.n_flags, dtype=bool), self._exact(view))

    def _exact(self, view: StepView) -> list:
        """The values of the exact columns (Python int / str) at the view's step."""
        out = []
        for e in self.exact:
            if e[0] == "x":
                x = view.xbus[e[1]]
                out.append(int(x.view(np.uint64)) if e[2] else int(x))
            elif e[0] == "s":
                out.append(view.text.get(e[1]))
            else:
                out.append(int(view.bus[e[1]]))
        return out
