"""``uwcosim run`` in a child process, so that nothing an FMU does ends the run silently.

A call into an in-process FMU's library can end the whole process: ``exit(0)``, ``exit(n)``,
``abort()``, a segmentation fault, at library load, at initialization, in ``doStep`` or in a
getter. No Python code runs after that (``exit`` skips Python's ``atexit``, a fatal signal
handler may not call back into Python), so the process that runs the FMUs cannot be the one that
reports it. The command line therefore forks once, before it imports anything heavy
(:func:`supervise`): the child runs the command as before; the parent only waits. The child
says, through a pipe, where its run directory is (:func:`announce`) and, as its very last act,
which exit status it chose (:func:`done`). A child that ends without saying so was ended by
something else: the parent names the FMU call it was in (:mod:`uwcosim.core.fmucall`, in shared
memory) and how it ended, and returns a :class:`Death` for the caller to finish the run
directory (``uwcosim.run.aftermath``). No per-step cost: the FMUs still run in the process
that steps them. The child ends with ``os._exit`` after what the interpreter's exit would do
for a run (workers killed, scratch folders removed, logging and output flushed), not after its
teardown of every module (slow with Numba loaded: most of the time a stop took).

The child's temporary files (unzipped FMUs, extracted SSP members, its workers' files) go
to a folder of the parent's (``TMPDIR``), removed when the child has ended, however it ended.

Signals: the parent passes SIGINT, SIGTERM and SIGHUP on to the child (unless they are ignored,
e.g. under ``nohup``: the child inherits that) and otherwise ignores them; the child stops as a
run always does (:mod:`uwcosim.core.runguard`). The child has a process group of its own, so a
terminal's Ctrl-C (sent to the foreground group) reaches it once, through the parent. The
child dies with the parent (``kill -9`` of the parent:
:func:`uwcosim.core.process.die_with_parent`). ``UWCOSIM_SUPERVISE=0`` runs in one
process (e.g. under a debugger). POSIX only; elsewhere :func:`supervise` calls the command
directly.
"""

from __future__ import annotations

import logging
import os
import shutil
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable
from dataclasses import dataclass

from uwcosim.core import fmucall, process, scratch

_FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_fd: int | None = None  # the child's end of the pipe


@dataclass
class Death:
    """How a supervised child ended without choosing its exit status."""

    #: what ended it, e.g. ``killed by SIGSEGV``, ``the process exited with status 7``
    how: str
    #: the run directory the child announced (None: it ended before it had one)
    out_dir: str | None
    #: ``(fmu, call, t, start)`` of the FMU call it was in, or None
    call: tuple[str, str, float, float] | None
    #: the signal the parent passed on before the child ended, or None
    forwarded: int | None

    def message(self) -> str:
        """One line: which FMU call ended the process, and how."""
        if self.call is not None:
            fmu, what, t, _ = self.call
            return (f"FMU '{fmu}' ended the process during {what} at t={t:g} ({self.how}; "
                    f"set [fmus.{fmu}] timeout_s to run it in a worker process)")
        return f"the run's process ended unexpectedly ({self.how})"


def announce(out_dir: str | os.PathLike) -> None:
    """In a supervised child: the run directory (where the parent finishes a dead run)."""
    _send(f"out {os.fspath(out_dir)}")


def done(code: int) -> None:
    """In a supervised child: the exit status it chose (the last thing it does)."""
    _send(f"done {int(code)}")


def _send(line: str) -> None:
    global _fd
    if _fd is None:
        return
    try:
        os.write(_fd, (line.replace("\n", " ") + "\n").encode("utf-8", "surrogateescape"))
    except OSError:
        _fd = None


def _how(status: int) -> str:
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            name = signal.Signals(sig).name
        except ValueError:
            name = f"signal {sig}"
        return f"killed by {name}"
    return f"the process exited with status {os.waitstatus_to_exitcode(status)}"


def supervise(command: Callable[[], int]) -> int | Death:
    """Run ``command`` in a forked child and return its exit status, or the :class:`Death` of
    a child that did not choose one (see the module docstring)."""
    global _fd
    if not hasattr(os, "fork") or os.environ.get("UWCOSIM_SUPERVISE", "1") == "0":
        return command()
    r, w = os.pipe()
    fmucall.clear()
    parent = os.getpid()
    tmp = tempfile.mkdtemp(prefix="uwcosim_proc_")  # the child's temporary folder
    sys.stdout.flush()
    sys.stderr.flush()
    target: list[int] = []
    forwarded: list[int] = []

    def forward(signum, frame) -> None:
        forwarded.append(signum)
        for pid in target:
            try:
                os.kill(pid, signum)
            except ProcessLookupError:
                pass

    saved = {}  # installed before the fork: a signal in between is passed on, not lost
    for s in _FORWARDED:
        if signal.getsignal(s) is not signal.SIG_IGN:
            saved[s] = signal.signal(s, forward)
    before = len(forwarded)
    pid = os.fork()
    if pid == 0:  # the child: the command, then its exit status to the parent
        for s, old in saved.items():
            signal.signal(s, old)
        for s in forwarded[before:]:  # reached the child before its own handlers were back
            signal.raise_signal(s)
        os.close(r)
        _fd = w
        os.setpgid(0, 0)  # a terminal's Ctrl-C reaches the parent only, which passes it on
        process.die_with_parent(parent)
        tempfile.tempdir = tmp  # its scratch folders and its workers' (TMPDIR) go there
        os.environ["TMPDIR"] = tmp
        try:
            code = command()
        except SystemExit as exc:  # argparse and friends
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException:  # noqa: BLE001 - an internal error: its traceback, as unsupervised
            traceback.print_exc()
            code = 1
        try:  # what the interpreter's exit would do for a run, not its slow teardown
            process.kill_workers()
            scratch.remove_all()
            logging.shutdown()
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            done(code)
            os._exit(code)
    os.close(w)
    target.append(pid)
    for s in list(forwarded):  # arrived during the fork
        os.kill(pid, s)
    data = b""
    try:
        with os.fdopen(r, "rb", buffering=0) as pipe:
            while chunk := pipe.read(4096):
                data += chunk
        _, status = os.waitpid(pid, 0)
    finally:
        for s, old in saved.items():
            signal.signal(s, old)
        shutil.rmtree(tmp, ignore_errors=True)  # what a dead child could not remove
    out_dir = code = None
    for line in data.decode("utf-8", "surrogateescape").splitlines():
        key, _, value = line.partition(" ")
        if key == "out":
            out_dir = value
        elif key == "done":
            code = int(value)
    if code is not None:
        return code
    return Death(_how(status), out_dir, fmucall.current(), forwarded[0] if forwarded else None)
