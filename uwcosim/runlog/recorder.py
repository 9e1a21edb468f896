"""What a run logs, one row per step: a master hook between the run and its :class:`RunLogger`.

Columns: ``time``, the logged signals (``[log] signals`` globs, plus the model's truth signals
when there are estimators), and, with estimators, the measurements ``z.NAME`` (NaN when not
received; flags ``z.NAME.received``) from the master's
:class:`~uwcosim.master.measurement.SensorBank`, and each estimator's mean ``est.E.STATE``,
variance ``est.E.var.STATE``, ``est.E.nis``, ``est.E.nees`` (flag ``est.E.diverged``).
"""

from __future__ import annotations

import fnmatch
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
        self.row = np.empty(self.width)
        self.n_flags = len(logger.bool_columns)

    def __call__(self, master: Master) -> None:
        row = self.row
        row[0] = master.t
        i = 1 + len(self.sig)
        row[1:i] = master.bus[self.sig]
        flags = []
        if self.bank:
            meas = master.measurement()
            row[i:i + meas.z.size] = meas.z
            i += meas.z.size
            flags = [bool(r) for r in meas.received]
            nx = self.model.nx
            for tr in self.bank.tracks:
                if tr.diverged_at is None:
                    row[i:i + nx] = tr.estimator.x
                    row[i + nx:i + 2 * nx] = np.diag(tr.estimator.P)
                    row[i + 2 * nx] = tr.estimator.diagnostics.get("nis", np.nan)
                    row[i + 2 * nx + 1] = tr.nees
                else:
                    row[i:i + 2 * nx + 2] = np.nan
                i += 2 * nx + 2
            flags += [tr.diverged_at is not None for tr in self.bank.tracks]
        self.logger.append(row, np.array(flags, dtype=bool),
                           [master.native.get(s) for s in self.exact])

    def final(self, master: Master, t: float) -> None:
        """The last row of a run an FMU stopped between two communication points: the signals
        at ``t`` (the stopped FMU's outputs at its termination time; the others' at the last
        communication point), no measurements or estimates."""
        row = np.full(self.width, np.nan)
        row[0] = t
        row[1:1 + len(self.sig)] = master.bus[self.sig]
        self.logger.append(row, np.zeros(self.n_flags, dtype=bool),
                           [master.native.get(s) for s in self.exact])
