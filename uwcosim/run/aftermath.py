"""The run directory of a run whose process died in an FMU call: finished by its parent.

:mod:`uwcosim.core.supervise` runs ``uwcosim run`` in a child process; when an FMU ends that
process (``exit``, ``abort``, a segmentation fault: see :class:`~uwcosim.core.supervise.Death`),
:func:`finish_dead_run` does what the run would have done on a failure: the log is rewritten
from its journal and tail into a normal ``log.parquet`` (every row up to the crash, as after
``kill -9``: :func:`uwcosim.runlog.recover_log`), ``simulation.json`` says ``failed`` with the
one-line error, and ``summary.json`` is evaluated from those files (metrics of what was
logged). A run that died before its first row has no log: the writer's empty stubs are removed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from uwcosim.core.errors import UwcosimError
from uwcosim.evaluation.summary import evaluate
from uwcosim.runlog import read_log, recover_log
from uwcosim.runlog.parquet import journal_path, unfinished
from uwcosim.runlog.rundir import LOG_FILE, SIMULATION_FILE, SUMMARY_FILE, write_json
from uwcosim.runlog.tail import tail_path


def finish_dead_run(out_dir: str | Path, message: str, status: str = "failed") -> str:
    """Finish the run directory ``out_dir`` of a dead run; returns ``message`` with the log's
    extent (``(log up to t=T kept in PATH)``) when it has rows."""
    out_dir = Path(out_dir)
    log = out_dir / LOG_FILE
    cols, meta = {}, {}
    try:
        if unfinished(log):  # the journal's row groups, then the tail's rows
            recover_log(log)
        if log.is_file():
            cols, meta = read_log(log)
    except (UwcosimError, OSError):  # the journal has no schema yet: nothing was logged
        for stub in (journal_path(log), tail_path(log), log):  # opened by the writer
            stub.unlink(missing_ok=True)
    t = cols.get("time", np.zeros(0))
    if t.size:
        message = f"{message} (log up to t={float(t[-1]):g} kept in {log})"
    else:
        message = f"{message} (no log row was written)"
    record = {"scenario": meta.get("scenario_name", Path(meta.get("scenario_path", "?")).stem),
              "seed": meta.get("seed"), "status": status, "error": message,
              "steps": max(int(t.size) - 1, 0), "step_s": meta.get("step"), "timing": {},
              "estimators": {}, "notes": []}
    try:
        write_json(out_dir / SIMULATION_FILE, record)
        evaluate(out_dir)
    except Exception as exc:  # noqa: BLE001 - a summary whatever the log holds: say why
        record["notes"].append(f"evaluation failed ({type(exc).__name__}: {exc}): no metrics")
        try:
            write_json(out_dir / SUMMARY_FILE, record)
        except OSError:
            pass
    return message


def finish_death(out_dir: str | Path | None, message: str, reported: bool,
                 status: str = "failed") -> str:
    """:func:`finish_dead_run` of the run directory of a process that ended (None: it had none
    yet), unless that process finished it itself and said so (``reported``: its own one-line
    error, e.g. the watchdog's of ``run.fmu_timeout_s``, whose run wrote its log, simulation
    record and summary before it ended): then ``message`` as it is, which names the log."""
    if out_dir is None:
        return message
    if reported and not unfinished(Path(out_dir) / LOG_FILE):
        return message
    return finish_dead_run(out_dir, message, status)

