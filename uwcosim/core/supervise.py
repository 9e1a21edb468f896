"""``uwcosim run``, ``demo`` and the runs of ``campaign --workers 1`` in a child process, so
that nothing an FMU does ends them silently.

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
that steps them. :class:`Child` is that child and its messages (:func:`tell`, read as they
arrive); :func:`supervised_map` runs a sequence of jobs in one (a campaign's runs), yields each
result as it comes and, when the child dies in a job, that job's :class:`Death`, then goes on
with the next job in a new child; :func:`supervised_pool` does the same on several children at
once (``campaign --workers N``), the parent waiting on all their pipes and handing each the
next job's index when it has finished one. The child ends with ``os._exit`` after what the
interpreter's exit would do for a run (workers killed, scratch folders removed, logging and
output flushed), not after its teardown of every module (slow with Numba loaded: most of the
time a stop took).

The child's temporary files (unzipped FMUs, extracted SSP members, its workers' files) go
to a folder of the parent's (``TMPDIR``), removed when the child has ended, however it ended.

Signals: the parent passes SIGINT, SIGTERM and SIGHUP on to every child it runs (unless they
are ignored, e.g. under ``nohup``: the child inherits that) and otherwise ignores them; the
child stops as a run always does (:mod:`uwcosim.core.runguard`). The child has a process group
of its own, so a terminal's Ctrl-C (sent to the foreground group) reaches it once, through the
parent. The child dies with the parent (``kill -9`` of the parent:
:func:`uwcosim.core.process.die_with_parent`). ``UWCOSIM_SUPERVISE=0`` runs in one
process (e.g. under a debugger). POSIX only; elsewhere :func:`supervise` calls the command
directly.
"""

from __future__ import annotations

import collections
import json
import logging
import os
import selectors
import shutil
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TypeVar

from uwcosim.core import fmucall, process, scratch
from uwcosim.core.errors import RunInterrupted, UwcosimError

T = TypeVar("T")

_FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_fd: int | None = None  # the child's end of the pipe
_parent_reports = False  # a child whose parent reports its last error (see parent_reports)


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
    #: the one-line error the child reported before it ended (the run-wide watchdog), or None
    error: str | None = None

    def message(self) -> str:
        """One line: which FMU call ended the process, and how."""
        if self.error:
            return self.error
        if self.call is not None:
            fmu, what, t, _ = self.call
            return (f"FMU '{fmu}' ended the process during {what} at t={t:g} ({self.how}; "
                    f"set [fmus.{fmu}] timeout_s to run it in a worker process)")
        return f"the run's process ended unexpectedly ({self.how})"


def announce(out_dir: str | os.PathLike) -> None:
    """In a supervised child: the run directory (where the parent finishes a dead run)."""
    tell("out", os.fspath(out_dir))


def done(code: int) -> None:
    """In a supervised child: the exit status it chose (the last thing it does)."""
    tell("done", str(int(code)))


def report_error(message: str) -> None:
    """In a supervised child: the one-line error it ends with (before :func:`done`)."""
    tell("error", message)


def parent_reports() -> bool:
    """Whether this process is a child of :func:`supervised_map` or :func:`supervised_pool`,
    whose parent reports the one-line error the child ends with (:func:`report_error`; a
    campaign's line, the Python API's exception), so that the child does not print it too.
    The child of :func:`supervise` (``uwcosim run``) prints its own."""
    return _parent_reports


def tell(key: str, value: str) -> None:
    """In a supervised child: one message ``key value`` to the parent (:meth:`Child.messages`;
    a newline in ``value`` becomes a space); nothing in an unsupervised process."""
    global _fd
    if _fd is None:
        return
    data = f"{key} {value.replace(chr(10), ' ')}\n".encode("utf-8", "surrogateescape")
    try:
        while data:  # a signal may interrupt a long write part way
            data = data[os.write(_fd, data):]
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


def enabled() -> bool:
    """Whether commands run in a supervised child: a platform that forks, and
    ``UWCOSIM_SUPERVISE`` not ``0``."""
    return hasattr(os, "fork") and os.environ.get("UWCOSIM_SUPERVISE", "1") != "0"


def supervise(command: Callable[[], int]) -> int | Death:
    """Run ``command`` in a forked child and return its exit status, or the :class:`Death` of
    a child that did not choose one (see the module docstring)."""
    if not enabled():
        return command()
    child = Child(command)
    try:
        for _ in child.messages():
            pass
    finally:
        child.close()
    return child.result


class _Forwarder:
    """The parent's handlers of SIGINT, SIGTERM and SIGHUP while children run: each signal is
    passed on to every live child and remembered. Installed by the first live :class:`Child`,
    the previous handlers put back when the last one ends."""

    def __init__(self) -> None:
        self.pids: set[int] = set()
        self.signals: list[int] = []  # every signal passed on, in order
        self._users = 0
        self._saved: dict = {}

    def __call__(self, signum, frame) -> None:
        self.signals.append(signum)
        for pid in list(self.pids):
            try:
                os.kill(pid, signum)
            except ProcessLookupError:
                pass

    def acquire(self) -> None:
        if self._users == 0:
            for s in _FORWARDED:
                if signal.getsignal(s) is not signal.SIG_IGN:
                    self._saved[s] = signal.signal(s, self)
        self._users += 1

    def release(self) -> None:
        self._users -= 1
        if self._users == 0:
            self.restore()

    def restore(self) -> None:
        """Put the handlers back (in a new child: its own are the parent's old ones)."""
        for s, old in self._saved.items():
            signal.signal(s, old)
        self._saved = {}


_forwarder = _Forwarder()


class Child:
    """``command`` in a forked child (see the module docstring): :meth:`messages` yields what
    it says (:func:`tell`) as it arrives (or :meth:`read`, one read of the pipe, for a parent
    that waits on several children: :meth:`fileno`); then :attr:`result` is its exit status or
    its :class:`Death`. :meth:`close` ends it (if it still runs) and removes its temporary
    folder. ``reports``: the parent reports the one-line error the child ends with
    (:func:`parent_reports` in the child)."""

    def __init__(self, command: Callable[[], int], reports: bool = False) -> None:
        self.result: int | Death | None = None
        self.out_dir: str | None = None
        self.error: str | None = None
        self._code: int | None = None
        self._pid: int | None = None
        self._data = b""
        self._r, w = os.pipe()
        self._page = fmucall.fresh()  # the record of the child's FMU calls (its own page)
        parent = os.getpid()
        self.tmp = tempfile.mkdtemp(prefix="uwcosim_proc_")  # the child's temporary folder
        sys.stdout.flush()
        sys.stderr.flush()
        # installed before the fork: a signal in between is passed on, not lost
        _forwarder.acquire()
        self._acquired = True
        self._before = len(_forwarder.signals)
        pid = os.fork()
        if pid == 0:  # the child: the command, then its exit status to the parent
            self._child(command, w, parent, _forwarder.signals[self._before:], reports)
        os.close(w)
        self._pid = pid
        _forwarder.pids.add(pid)
        for s in _forwarder.signals[self._before:]:  # arrived during the fork
            os.kill(pid, s)

    def _child(self, command: Callable[[], int], w: int, parent: int, early: list[int],
               reports: bool):
        global _fd, _parent_reports
        _parent_reports = reports
        _forwarder.restore()
        _forwarder.pids.clear()
        for s in early:  # reached the child before its own handlers were back
            signal.raise_signal(s)
        os.close(self._r)
        _fd = w
        os.setpgid(0, 0)  # a terminal's Ctrl-C reaches the parent only, which passes it on
        process.die_with_parent(parent)
        tempfile.tempdir = self.tmp  # its scratch folders and its workers' (TMPDIR) go there
        os.environ["TMPDIR"] = self.tmp
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

    def fileno(self) -> int:
        """The parent's end of the child's pipe (to wait on with :mod:`selectors`)."""
        return self._r

    def read(self) -> list[tuple[str, str]] | None:
        """One read of the pipe (blocks until the child says something or ends): the
        ``(key, value)`` messages it completed; None when the child has ended (then
        :attr:`result` is set). An ``item`` message (the start of a job) clears the run
        directory and the error of the job before, in the order the child said them (the next
        job's ``out`` may come in the same read)."""
        chunk = os.read(self._r, 65536)
        if not chunk:
            self._reap()
            return None
        self._data += chunk
        *lines, self._data = self._data.split(b"\n")
        out = []
        for line in lines:
            key, _, value = line.decode("utf-8", "surrogateescape").partition(" ")
            if key == "out":
                self.out_dir = value
            elif key == "done":
                self._code = int(value)
            elif key == "error":
                self.error = value
            else:
                if key == "item":
                    self.out_dir = self.error = None
                out.append((key, value))
        return out

    def messages(self) -> Iterator[tuple[str, str]]:
        """``(key, value)`` of each :func:`tell` of the child, as it arrives; when the child
        has ended, :attr:`result` is set."""
        while (batch := self.read()) is not None:
            yield from batch

    def _reap(self) -> None:
        os.close(self._r)
        self._r = -1
        _, status = os.waitpid(self._pid, 0)
        _forwarder.pids.discard(self._pid)
        self._pid = None
        forwarded = _forwarder.signals[self._before:]
        self._release()
        if self._code is not None:
            self.result = self._code
        else:
            self.result = Death(_how(status), self.out_dir, self._page.current(),
                                forwarded[0] if forwarded else None, self.error)

    def _release(self) -> None:
        if self._acquired:
            self._acquired = False
            _forwarder.release()

    def close(self) -> None:
        """End the child if it still runs (SIGKILL), then remove its temporary folder."""
        if self._r >= 0:
            os.close(self._r)
            self._r = -1
        if self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            os.waitpid(self._pid, 0)
            _forwarder.pids.discard(self._pid)
            self._pid = None
        self._release()
        shutil.rmtree(self.tmp, ignore_errors=True)  # what a dead child could not remove


def supervised_map(func: Callable[[T], object], items: Sequence[T]
                   ) -> Iterator[tuple[int, object]]:
    """``func(item)`` for each of ``items`` in order, in a supervised child process: yields
    ``(i, result)`` as each is done (the result passes through the pipe as JSON). When the
    child ends during item ``i`` without its result (an FMU ended the process; the run-wide
    watchdog ended it: :attr:`Death.error`), ``(i, Death)`` is yielded, while the child's
    temporary folder (a run directory in it, :attr:`Death.out_dir`) still exists, and a new
    child goes on with item ``i + 1``. Interrupted (a signal passed on to the child, which
    stops as a run does): :class:`~uwcosim.core.errors.RunInterrupted` with the exit status
    128 + signal (its message the child's one-line error, if it reported one); the item in
    progress is not yielded. ``UWCOSIM_SUPERVISE=0``: in this process."""
    if not enabled():
        for i, item in enumerate(items):
            yield i, func(item)
        return
    start = 0
    while start < len(items):
        child = Child(partial(_map_child, func, items, start), reports=True)
        current = None
        try:
            for key, value in child.messages():
                if key == "item":
                    current = int(value)
                elif key == "result":
                    yield current, json.loads(value)
                    start, current = current + 1, None
            result = child.result
            code = _interrupt_status(result)
            if code is not None:
                raise _interrupted(code, child.error)
            if current is None:  # between items: only an internal error ends it so
                if start < len(items):
                    how = result.message() if isinstance(result, Death) else \
                        f"exit status {result}"
                    raise UwcosimError(f"the supervised process ended before item {start} "
                                       f"({how})")
                return
            yield current, _death(result, child)
            start = current + 1
        finally:
            child.close()


def _interrupt_status(result: int | Death) -> int | None:
    """128 + signal for a child that a passed-on signal stopped (or ended), else None."""
    if isinstance(result, Death):
        return None if result.forwarded is None else 128 + result.forwarded
    return result if result >= 128 else None


def _interrupted(code: int, error: str | None = None) -> RunInterrupted:
    """The interrupt of a child stopped with status ``code``: its own one-line error, if it
    reported one (the run stopped in an FMU call by the watcher), else the signal."""
    err = RunInterrupted(error or f"interrupted by signal {code - 128}")
    err.exit_code = code
    return err


def _death(result: int | Death, child: Child) -> Death:
    """The :class:`Death` of a child that ended in an item: as it is, or for a status the
    child chose itself (e.g. the watchdog's 3)."""
    if isinstance(result, Death):
        return result
    return Death(f"the process exited with status {result}", child.out_dir, None, None,
                 child.error)


def _stop_status(exc: BaseException) -> int:
    """A child's exit status when a signal stopped it (KeyboardInterrupt, RunInterrupted)."""
    signum = getattr(exc, "signum", None)
    return 128 + signum if signum else int(getattr(exc, "exit_code", 130))


def _map_child(func: Callable, items: Sequence, start: int) -> int:
    for i in range(start, len(items)):
        tell("item", str(i))
        try:
            result = func(items[i])
        except (KeyboardInterrupt, RunInterrupted) as exc:
            return _stop_status(exc)
        tell("result", json.dumps(result))
    return 0


@dataclass
class _Lane:
    """One child of :func:`supervised_pool`: the parent's end of its task pipe and the item
    it was given (None: idle), whether it said it started that item."""

    child: Child
    tasks: int
    item: int | None = None
    started: bool = False


def supervised_pool(func: Callable[[T], object], items: Sequence[T], workers: int
                    ) -> Iterator[tuple[int, object]]:
    """``func(item)`` for each of ``items`` on ``workers`` supervised children at once, each
    given the next item (its index through a pipe) when it has finished one: yields ``(i,
    result)`` in the order they finish. A child that ends during item ``i`` without its
    result yields ``(i, Death)``, while its temporary folder still exists, and a new child takes
    its place. Each child records its FMU calls on a page of its own
    (:func:`uwcosim.core.fmucall.fresh`), so a death names the call of the child that died.
    Interrupted (a signal passed on to every child): no item is given any more and, when every
    child has stopped, :class:`~uwcosim.core.errors.RunInterrupted` with the exit status 128 +
    signal; the items in progress are not yielded. ``workers <= 1`` is
    :func:`supervised_map`; ``UWCOSIM_SUPERVISE=0`` runs in this process."""
    if workers <= 1 or not enabled():
        yield from supervised_map(func, items)
        return
    queue = collections.deque(range(len(items)))
    lanes: dict[int, _Lane] = {}
    sel = selectors.DefaultSelector()
    signals_before = len(_forwarder.signals)
    interrupted: int | None = None

    def stopping() -> bool:
        return interrupted is not None or len(_forwarder.signals) > signals_before

    def give(lane: _Lane) -> None:
        """The lane's next item, or ``stop`` (a child that died meanwhile: its end is read)."""
        lane.item = queue.popleft() if queue and not stopping() else None
        lane.started = False
        try:
            os.write(lane.tasks, b"stop\n" if lane.item is None else b"%d\n" % lane.item)
        except OSError:
            pass

    def start() -> None:
        r, w = os.pipe()
        child = Child(partial(_lane_child, func, items, r, w), reports=True)
        os.close(r)
        lane = _Lane(child, w)
        lanes[child.fileno()] = lane
        sel.register(child.fileno(), selectors.EVENT_READ, lane)
        give(lane)

    try:
        for _ in range(min(workers, len(items))):
            start()
        while lanes:
            for key, _ in sel.select():
                lane: _Lane = key.data
                fd = key.fd
                batch = lane.child.read()
                if batch is not None:
                    for k, v in batch:
                        if k == "item":
                            lane.started = True
                        elif k == "result":
                            i = lane.item
                            give(lane)
                            yield i, json.loads(v)
                    continue
                sel.unregister(fd)
                del lanes[fd]
                result = lane.child.result
                code = _interrupt_status(result)
                try:
                    if code is not None:
                        interrupted = interrupted or code
                        continue
                    if lane.item is None and result == 0:  # told to stop
                        continue
                    if lane.item is None or not lane.started:  # only an internal error
                        how = result.message() if isinstance(result, Death) else \
                            f"exit status {result}"
                        raise UwcosimError(f"a supervised worker process ended between "
                                           f"items ({how})")
                    yield lane.item, _death(result, lane.child)
                finally:
                    lane.child.close()
                    os.close(lane.tasks)
                if queue and not stopping():
                    start()
        if interrupted is None and stopping():
            interrupted = 128 + _forwarder.signals[signals_before]
        if interrupted is not None:
            raise _interrupted(interrupted)
    finally:
        for lane in lanes.values():
            lane.child.close()
            os.close(lane.tasks)
        sel.close()


def _lane_child(func: Callable, items: Sequence, tasks: int, parents_end: int) -> int:
    """A child of :func:`supervised_pool`: the items whose indices the parent writes to the
    pipe ``tasks``, one per line, until ``stop``."""
    os.close(parents_end)
    with os.fdopen(tasks, "rb") as pipe:
        try:  # interrupted in an item or waiting for one
            while (line := pipe.readline().strip()) not in (b"", b"stop"):
                i = int(line)
                tell("item", str(i))
                result = func(items[i])
                tell("result", json.dumps(result))
        except (KeyboardInterrupt, RunInterrupted) as exc:
            return _stop_status(exc)
    return 0
