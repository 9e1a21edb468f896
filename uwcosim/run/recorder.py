"""What a run logs, one row per step: an observer of the master that writes its
:class:`~uwcosim.runlog.RunLogger`.

The columns are a :class:`~uwcosim.runlog.columns.LogLayout` (``time``, the logged signals,
the measurements, each estimator's block; the flags after them). :func:`logged_signals` picks
the signals (``[log] signals`` globs, plus the filters' truth signals when there are
estimators).

Row ``k`` is the bus at step ``k`` (:meth:`LogRecorder.on_step`) joined with the estimates of
step ``k`` (:meth:`LogRecorder.estimates`, which the estimator bank calls when it has filtered
the block the step belongs to): rows are paired by their step index and written in order as
soon as both halves are there. :meth:`LogRecorder.flush` writes what still waits at the end of
a run (with NaN estimates where the bank has none). Columns computed from a row (a
georeferenced run's latitude/longitude) are filled by the ``derive`` function given.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from uwcosim.master.observer import StepView
from uwcosim.runlog import RunLogger
from uwcosim.runlog.columns import LogLayout

#: bus signals that are never logged: the master's noise samples
_UNLOGGED = ("noise.", "sensornoise.")


def logged_signals(names: Iterable[str], patterns: Sequence[str],
                   truth: Sequence[str] = ()) -> list[str]:
    """The bus signals matching ``patterns`` (globs), then the ``truth`` signals not among
    them (the filters' truth is always logged)."""
    out = [n for n in names
           if not n.startswith(_UNLOGGED) and any(fnmatch.fnmatch(n, p) for p in patterns)]
    return out + [t for t in truth if t not in out]


class LogRecorder:
    """Writes row ``k`` of the log from the step's view and the estimates of step ``k``."""

    def __init__(self, layout: LogLayout, logger: RunLogger, signal_slots: Sequence[int],
                 exact_slots: Sequence[int] = (),
                 derive: Callable[[np.ndarray], None] | None = None) -> None:
        """``derive(row)``: fills the columns computed from the rest of a row before it is
        written (a georeferenced run's latitude/longitude, :mod:`uwcosim.run.geocolumns`)."""
        self.layout, self.logger = layout, logger
        self.derive = derive
        self.sig = np.asarray(signal_slots, dtype=np.intp)
        self.exact = list(exact_slots)
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
        row = np.empty(lay.width)
        row[0] = view.t
        row[lay.signal_part] = view.signals(self.sig)
        exact = [view.native.get(s) for s in self.exact]
        if not self._with_estimates:
            self.logger.append(row, np.zeros(0, dtype=bool), exact)
            self._next = k + 1
            return
        meas = view.measurement()
        row[lay.measurement_part] = meas.z
        self._rows[k] = (row, [bool(r) for r in meas.received], exact)
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
        self.logger.append(row, np.zeros(self.n_flags, dtype=bool),
                           [view.native.get(s) for s in self.exact])
