"""Signals, interruption and the run-wide FMU watchdog of a run.

A call into an FMU's shared library cannot be interrupted by a Python signal handler: the
handler only runs when the main thread comes back to Python bytecode, which a hanging FMU never
does. So while a run is going (:func:`run_guard`, entered by :func:`uwcosim.run.simulate.simulate`
in the main thread):

- SIGINT (Ctrl-C), SIGTERM and SIGHUP get a handler that only *records* the signal; the C-level
  part of Python's signal handling writes the signal number to a wake-up pipe
  (:func:`signal.set_wakeup_fd`) from whatever thread the kernel picked, even while the main
  thread is inside an FMU;
- a watcher thread reads that pipe. The main loop sees the request at the next step (a master
  hook raises :class:`~uwcosim.core.errors.RunInterrupted`) and closes the log and writes
  ``summary.json`` itself. If the main thread has not come back within :data:`GRACE_S`
  (stuck in an FMU call), the watcher does the same finalization (the log writer is
  lock-protected), prints the one-line message and ends the process with ``os._exit``
  (exit status 128 + signal: 130, 143, 129). A second Ctrl-C does not abort the finalization;
- the same watcher enforces ``run.fmu_timeout_s``: an FMU call of any FMU (every call into its
  library: instantiate, enter/exit initialization, set, get, doStep, event update, reset,
  terminate, free; the master's record ``busy`` of a step or an algebraic loop, else the
  adapters' record :mod:`uwcosim.core.fmucall`), in this process or in a worker, that lasts
  longer ends the run as ``failed`` with the log kept and exit status 3 (a C call cannot be
  abandoned, so the process ends).

Before the process ends so, the workers are killed and the run's scratch folders (unzipped
FMUs, extracted SSP members: :mod:`uwcosim.core.scratch`) removed.

A signal whose disposition is "ignore" when the guard is entered (``nohup``, campaign pool
workers) stays ignored. Outside the main thread the guard does nothing.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from uwcosim.core import fmucall, process, scratch, supervise
from uwcosim.core.errors import RunInterrupted

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: seconds the main thread has to stop at a step boundary before the watcher finalizes
GRACE_S = 0.5
#: seconds after a signal by which the process is gone, whatever the main thread does
HARD_S = 1.5
_POLL_S = 0.05

_active: RunGuard | None = None


def active() -> RunGuard | None:
    """The guard of the run in progress in this process, if any."""
    return _active


def stop_requested() -> bool:
    """True once a run's stop signal arrived (long waits poll this, e.g. the FMU proxy)."""
    g = _active
    return g is not None and g.signum is not None


class Interrupt(KeyboardInterrupt):
    """SIGTERM or SIGHUP outside a run, raised like Ctrl-C's KeyboardInterrupt."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_interrupt(signum, frame) -> None:
    raise Interrupt(signum)


def install_cli_handlers() -> None:
    """SIGTERM and SIGHUP raise :class:`Interrupt` (a KeyboardInterrupt) in the main thread,
    as SIGINT does: the command line treats all three alike (exit status 128 + signal)."""
    for s in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, _raise_interrupt)


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


class RunGuard:
    """What the watcher knows about the run: the master (for the FMU call in progress), the
    emergency finalizer, and who finalizes (the main thread or the watcher, never both)."""

    def __init__(self, fmu_timeout_s: float | None = None) -> None:
        self.fmu_timeout_s = fmu_timeout_s
        self.signum: int | None = None
        self.t_signal = 0.0
        self.master = None
        self.finalize: Callable[[str, str, int], None] | None = None
        self._lock = threading.Lock()
        self._owner: int | None = None
        self.finished = threading.Event()  # the main thread wrote the summary
        self._quit = threading.Event()
        self._thread: threading.Thread | None = None
        self._rfd = self._wfd = -1
        self._saved: dict = {}
        self._saved_fd = -1

    # -- main thread side -------------------------------------------------------------------
    def check(self) -> None:
        """Raise :class:`RunInterrupted` once a stop signal arrived."""
        if self.signum is not None:
            raise RunInterrupted(f"interrupted by {signal_name(self.signum)}")

    def on_step(self, k: int, view: object) -> None:
        """As an observer of the master (the last one): :meth:`check` after every step."""
        self.check()

    def exit_code(self) -> int:
        return 128 + self.signum if self.signum is not None else 130

    def claim(self) -> bool:
        """Take the right to finalize (True), or learn that the watcher took it (False)."""
        with self._lock:
            if self._owner is None:
                self._owner = threading.get_ident()
            return self._owner == threading.get_ident()

    def wait_for_exit(self) -> None:
        """The watcher finalizes and ends the process: wait for it."""
        while True:
            time.sleep(1.0)

    # -- signals ------------------------------------------------------------------------------
    def _handler(self, signum, frame) -> None:  # runs in the main thread, later: no raise
        self.notify(signum)

    def notify(self, signum: int) -> None:
        if self.signum is None:
            self.signum = int(signum)
            self.t_signal = time.monotonic()

    def install(self) -> bool:
        if threading.current_thread() is not threading.main_thread():
            return False
        self._rfd, self._wfd = os.pipe()
        os.set_blocking(self._wfd, False)
        for s in SIGNALS:
            old = signal.getsignal(s)
            if old is signal.SIG_IGN:
                continue
            self._saved[s] = signal.SIG_DFL if old is None else old  # None: set from C
            signal.signal(s, self._handler)
        self._saved_fd = signal.set_wakeup_fd(self._wfd, warn_on_full_buffer=False)
        self._thread = threading.Thread(target=self._watch, name="uwcosim-runguard",
                                        daemon=True)
        self._thread.start()
        return True

    def uninstall(self) -> None:
        self._quit.set()
        if self._thread is not None:
            try:  # wake the watcher's select at once (0 is no signal number)
                os.write(self._wfd, b"\0")
            except OSError:
                pass  # the pipe is full: the watcher is awake anyway
            self._thread.join()
        signal.set_wakeup_fd(self._saved_fd)
        for s, old in self._saved.items():
            signal.signal(s, old)
        for fd in (self._rfd, self._wfd):
            if fd >= 0:
                os.close(fd)
        self._rfd = self._wfd = -1

    # -- the watcher thread -------------------------------------------------------------------
    def _watch(self) -> None:
        while not self._quit.is_set():
            ready, _, _ = select.select([self._rfd], [], [], _POLL_S)
            if ready:
                try:
                    data = os.read(self._rfd, 64)
                except OSError:
                    data = b""
                for b in data:
                    if b in SIGNALS:
                        self.notify(b)
            if self._quit.is_set():
                return
            now = time.monotonic()
            if self.signum is not None:
                name = signal_name(self.signum)
                if not self.finished.is_set() and now - self.t_signal > GRACE_S:
                    self._emergency("interrupted", f"interrupted by {name}", self.exit_code())
                elif now - self.t_signal > HARD_S:
                    self._exit(f"interrupted by {name} (the run did not end in {HARD_S:g} s)",
                               self.exit_code())
                continue
            busy = getattr(self.master, "busy", None) or fmucall.current()
            if self.fmu_timeout_s and busy is not None and now - busy[3] > self.fmu_timeout_s:
                fmu, what, t, _ = busy
                self._emergency("failed", f"FMU '{fmu}' did not return from {what} within "
                                f"{self.fmu_timeout_s:g} s at t={t:g} (run.fmu_timeout_s)", 3)

    def _emergency(self, status: str, message: str, code: int) -> None:
        if not self.claim():  # the main thread is finalizing: give it until HARD_S
            if self.finished.wait(max(0.0, HARD_S - GRACE_S)):
                time.sleep(0.2)  # it is returning to the command line
            self._exit(message, code)
        try:
            if self.finalize is not None:
                message = self.finalize(status, message, code) or message
        except Exception as exc:  # noqa: BLE001 - the process ends anyway: say why
            message = f"{message} (finalizing failed: {type(exc).__name__}: {exc})"
        self._exit(message, code)

    @staticmethod
    def _exit(message: str, code: int) -> None:
        process.kill_workers()
        scratch.remove_all()  # os._exit runs no atexit handler or finalizer
        try:
            if not supervise.parent_reports():  # else the parent's line or exception says it
                print(f"uwcosim: error: {message}", file=sys.stderr, flush=True)
        finally:  # the run chose its exit status (a supervised child), and said why
            supervise.report_error(message)
            supervise.done(code)
            os._exit(code)


@contextmanager
def run_guard(fmu_timeout_s: float | None = None) -> Iterator[RunGuard]:
    """The guard of one run (nested runs share the outer one's). Yields the :class:`RunGuard`;
    outside the main thread it is inert (signals behave as Python's defaults)."""
    global _active
    if _active is not None:
        outer_timeout = _active.fmu_timeout_s
        if fmu_timeout_s is not None:
            _active.fmu_timeout_s = fmu_timeout_s
        try:
            yield _active
        finally:
            _active.fmu_timeout_s = outer_timeout
        return
    guard = RunGuard(fmu_timeout_s)
    installed = guard.install()
    if installed:
        _active = guard
    try:
        yield guard
    finally:
        if installed:
            _active = None
            guard.uninstall()
