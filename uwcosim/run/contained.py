"""A run of the Python API in a supervised child process (``simulate`` and ``run_scenario`` with
``contained=True``).

An in-process FMU can end the process that calls it (``exit``, ``abort``, a segmentation
fault), and the run-wide watchdog (``run.fmu_timeout_s``) ends the process of a run whose FMU
does not come back: from the command line that process is a supervised child
(:mod:`uwcosim.core.supervise`), from Python it is the caller's own (a notebook's kernel, a
script with other work in memory). :func:`run_contained` runs the run in a forked child as the
command line does: the caller's process only waits; it returns when the run's files are
written, or raises the error the run raised (the same exception, with the child's traceback as
a note), or -- when the child was ended -- an
:class:`~uwcosim.core.errors.FMUError` naming the FMU call it was in, after the run directory
was finished from its files (every row up to the end kept, :mod:`uwcosim.run.aftermath`).

What runs in the child stays there: an observer passed as ``progress`` is called in the child
(what it prints is seen, what it collects is not), a :class:`~uwcosim.master.master.Master`
passed is used by the child and left as it was in the caller. The result comes back through
the run directory's files (the callers read them). Where the platform cannot fork, or with
``UWCOSIM_SUPERVISE=0``, the run is in the caller's process.
"""

from __future__ import annotations

import base64
import pickle
import traceback
from collections.abc import Callable
from functools import partial
from pathlib import Path

from uwcosim.core.errors import FMUError, RunInterrupted, UwcosimError
from uwcosim.core.supervise import Death, announce, enabled, supervised_map
from uwcosim.run.aftermath import finish_death


def run_contained(job: Callable[[], object], out_dir: str | Path) -> None:
    """``job()`` (a run into ``out_dir``) in a supervised child; what it raised, raised here
    (see the module docstring)."""
    out_dir = Path(out_dir)
    if not enabled():
        job()
        return
    answer: object = {}  # the child's answer: {} (done), an error, or the FMUError of a death
    try:
        for _, answer in supervised_map(partial(_in_child, job, out_dir), [None]):
            if isinstance(answer, Death):  # finished while the child's folders still exist
                answer = FMUError(finish_death(answer.out_dir, answer.message(),
                                               answer.error is not None))
    except RunInterrupted as exc:  # the child was stopped by a signal: it may not have said so
        err = RunInterrupted(finish_death(out_dir, str(exc), True, "interrupted"))
        err.exit_code = exc.exit_code
        raise err from None
    if isinstance(answer, FMUError):
        raise answer
    if "error" in answer:
        raise _error(answer)


def _in_child(job: Callable[[], object], out_dir: Path, _item) -> dict:
    """The child's side: where the run directory is (finished by the parent if the child
    dies), then the run; an error it raises goes back to the parent as it is."""
    announce(out_dir)
    try:
        job()
    except Exception as exc:  # noqa: BLE001 - every error of the run is the caller's to see
        return {"error": _pickled(exc), "text": f"{type(exc).__name__}: {exc}",
                "trace": traceback.format_exc()}
    return {}


def _pickled(exc: Exception) -> str | None:
    try:
        return base64.b64encode(pickle.dumps(exc)).decode("ascii")
    except Exception:  # noqa: BLE001 - an exception that cannot be pickled: its text only
        return None


def _error(answer: dict) -> Exception:
    """The child's exception, with its traceback as a note (its text in a
    :class:`UwcosimError` when it could not be passed on as it is)."""
    exc = None
    if answer["error"] is not None:
        try:
            exc = pickle.loads(base64.b64decode(answer["error"]))
        except Exception:  # noqa: BLE001 - e.g. a class the parent cannot import
            exc = None
    if not isinstance(exc, Exception):
        exc = UwcosimError(answer["text"])
    exc.add_note("raised in the run's child process:\n" + answer["trace"].rstrip())
    return exc

