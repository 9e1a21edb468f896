"""What a run logs, one row per step: a master hook between the run and its :class:`RunLogger`.

With estimators, a step's row waits until the estimator bank has filtered the block the step
belongs to (:mod:`uwcosim.estimator_bank`); :meth:`LogRecorder.flush` writes what waits at the
end of a run.

Columns: ``time``, the logged signals (``[log] signals`` globs, plus the model's truth signals
when there are estimators), and, with estimators, the measurements ``z.NAME`` (NaN when not
received; flags ``z.NAME.received``) from the master's
:class:`~uwcosim.master.measurement.SensorBank`, and each estimator's mean ``est.E.STATE``,
variance ``est.E.var.STATE``, ``est.E.nis``, ``est.E.nees`` (flag ``est.E.diverged``).
"""

from __future__ import annotations

import fnmatch
from collections import deque
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from uwcosim.runlog.parquet import RunLogger

if TYPE_CHECKING:
    from uwcosim.estimator_bank import EstimatorBank
    from uwcosim.master.master import Master
    from uwcosim.models.casadi_model import CasadiModel
    from uwcosim.models.linear import LinearModel
    from uwcosim.models.tan import TANModel

    Model = CasadiModel | LinearModel | TANModel


def log_columns(master: Master, bank: EstimatorBank | None,
                model: Model | None) -> tuple[list[str], list[int], list[str]]:
    """``(float columns, bus slots of the logged signals, bool columns)`` of a run's log."""
    patterns = master.spec.log.signals
    names = [n for n in master.slots
             if not n.startswith(("noise.", "sensornoise."))
             and any(fnmatch.fnmatch(n, p) for p in patterns)]
    if bank:
        for tname in master.spec.model.truth:
            if tname not in names:
                names.append(tname)
    slots = [master.slots[n] for n in names]
    cols = list(names)
    flags = []
    if bank:
        cols += [f"z.{n}" for n in master.sensors.names]
        flags += [f"z.{n}.received" for n in master.sensors.names]
        for tr in bank.tracks:
            cols += [f"est.{tr.name}.{s}" for s in model.state_names]
            cols += [f"est.{tr.name}.var.{s}" for s in model.state_names]
            cols += [f"est.{tr.name}.nis", f"est.{tr.name}.nees"]
        flags += [f"est.{tr.name}.diverged" for tr in bank.tracks]
    return cols, slots, flags


class LogRecorder:
    """A master hook: writes one log row per step from the bus, the step's
    :class:`~uwcosim.master.measurement.Measurement` and the estimator bank."""

    def __init__(self, master: Master, bank: EstimatorBank | None, logger: RunLogger,
                 signal_slots: np.ndarray, model: Model | None,
                 exact_slots: Sequence[int] = ()) -> None:
        self.bank, self.logger, self.model = bank, logger, model
        self.sig = signal_slots
        self.exact = list(exact_slots)
        self.width = 1 + len(signal_slots)
        if bank:
            self.width += len(master.sensors.names) + len(bank.tracks) * (2 * model.nx + 2)
        self.n_flags = len(logger.bool_columns)
        self._first = True
        self._pending: deque = deque()  # rows waiting for the bank's estimates

    def __call__(self, master: Master) -> None:
        row = np.empty(self.width)
        row[0] = master.t
        i = 1 + len(self.sig)
        row[1:i] = master.bus[self.sig]
        exact = [master.native.get(s) for s in self.exact]
        if not self.bank:
            self.logger.append(row, np.zeros(0, dtype=bool), exact)
            return
        meas = master.measurement()
        row[i:i + meas.z.size] = meas.z
        received = [bool(r) for r in meas.received]
        if self._first:  # the start time: the estimators' initial state, before any step
            self._first = False
            self._append(row, received, exact, self.bank.current())
            return
        self._pending.append((row, received, exact))
        self._drain()

    def _append(self, row, received, exact, estimates) -> None:
        values, diverged = estimates
        row[self.width - values.size:] = values
        self.logger.append(row, np.array(received + diverged, dtype=bool), exact)

    def _drain(self) -> None:
        """Write the rows whose estimates the bank has filtered (it runs in blocks)."""
        outputs = self.bank.outputs
        while self._pending and outputs:
            row, received, exact = self._pending.popleft()
            self._append(row, received, exact, outputs.popleft())

    def flush(self) -> None:
        """Write every row still waiting: with its estimates when the bank has them, else
        with NaN estimates (a run that ended inside a block the bank did not filter)."""
        if not self.bank:
            return
        self._drain()
        n = len(self.bank.tracks) * (2 * self.model.nx + 2)
        while self._pending:
            row, received, exact = self._pending.popleft()
            self._append(row, received, exact,
                         (np.full(n, np.nan), [False] * len(self.bank.tracks)))

    def final(self, master: Master, t: float) -> None:
        """The last row of a run an FMU stopped between two communication points: the signals
        at ``t`` (the stopped FMU's outputs at its termination time; the others' at the last
        communication point), no measurements or estimates."""
        row = np.full(self.width, np.nan)
        row[0] = t
        row[1:1 + len(self.sig)] = master.bus[self.sig]
        self.logger.append(row, np.zeros(self.n_flags, dtype=bool),
                           [master.native.get(s) for s in self.exact])
