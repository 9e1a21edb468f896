"""An FMU in a worker process, so that a call that hangs can be given up (``timeout_s``).

A call into an FMU's shared library cannot be interrupted from Python. When a scenario sets
``[fmus.NAME] timeout_s``, the master uses a :class:`ProxyAdapter` instead of an
:class:`~uwcosim.fmi.adapter.FMUAdapter`: same interface, but the FMU is loaded and stepped by a
worker process (``python -m uwcosim.fmi.proxy``) that runs an ordinary ``FMUAdapter``. Requests and
answers are pickled over two pipes; every answer is awaited at most ``timeout_s`` seconds, after
which the worker is killed and :class:`~uwcosim.core.errors.FMUError` says which call did not
answer, e.g. ``FMU 'fault' did not answer doStep within 5 s at t=3``. A worker that crashes
(segmentation fault in the FMU) is reported the same way instead of taking the run down.

The proxy keeps a description-only adapter (model description and variable map; the FMU's
library is not loaded in this process) for names, causalities and the connection graph.
Pipes with ``multiprocessing.connection.Connection`` on file descriptors: POSIX only.

Life cycle: a worker dies with its parent (Linux ``prctl(PR_SET_PDEATHSIG, SIGKILL)``, set by the
worker itself, which also exits at once if the parent is already gone) and ignores SIGINT, SIGTERM
and SIGHUP (the master decides, and closes or kills it). A wait for an answer is polled in slices
of 50 ms, so a stop request (Ctrl-C, SIGTERM: :mod:`uwcosim.core.runguard`) ends it at once instead
of after ``timeout_s``; the worker is then killed.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import weakref
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmpy.model_description import ModelVariable

import numpy as np

from uwcosim.core import fmucall, process, runguard, scratch
from uwcosim.core.errors import FMUError, RunInterrupted, ScenarioError
from uwcosim.core.paths import PACKAGE_DIR
from uwcosim.fmi.adapter import FMUAdapter
from uwcosim.fmi.archive import MAX_UNPACKED_ENV, MIB, max_unpacked_bytes
from uwcosim.fmi.binding import Binding
from uwcosim.fmi.varmap import VariableMap

#: seconds allowed for the worker to start (imports) before the first FMU call
STARTUP_S = 60.0
#: an answer is awaited in slices of this many seconds (a stop request is seen between them)
_SLICE_S = 0.05
_ERRORS = {"FMUError": FMUError, "ScenarioError": ScenarioError}
#: a request's name as a call of :mod:`uwcosim.core.fmucall` (the others: instantiate)
_CALL = {c: fmucall.CALLS.index(c) for c in fmucall.CALLS} | {
    "start": fmucall.CALLS.index("load library")}


class ProxyAdapter:
    """An :class:`FMUAdapter` look-alike whose FMU runs in a worker process."""

    def __init__(self, name: str, path: Path, interface: str = "cs", solver: str = "rk4",
                 substeps: int = 1, rtol: float = 1e-8, timeout_s: float = 10.0,
                 unzip_dir: str | Path | None = None) -> None:
        self.local = FMUAdapter(name, path, interface, solver, substeps, rtol)
        self._max_unpacked_mb = max_unpacked_bytes() / MIB  # the worker checks it again
        self._scratch = None
        if unzip_dir is None:  # ours, not the worker's: a killed worker cannot remove it
            self._scratch = scratch.Scratch(self, "uwcosim_fmu_")
            unzip_dir = self._scratch.path
        self.name, self.path, self.md = name, self.local.path, self.local.md
        self._ci = fmucall.fmu_index(name)
        self.sha256, self.fmi3 = self.local.sha256, self.local.fmi3
        self.interface, self.nx = interface, self.local.nx
        self.messages = self.local.messages
        self.timeout_s = float(timeout_s)
        #: what an in-process adapter offers an algebraic-loop solver or a joint integrator:
        #: not across the pipe (an FMU in a worker is stepped on its own)
        self.provides_derivatives = False
        self.model_exchange = None
        self.time_s = 0.0
        self._args = (name, str(self.local.path), interface, solver, substeps, rtol, None,
                      None if unzip_dir is None else str(unzip_dir))
        self.terminated: tuple[float, str] | None = None
        #: the integrator the worker reports after instantiate (the configured one until then)
        self.solver_used: str | None = solver
        self._map: tuple | None = None
        self._bindings: list[Binding] = []
        self._ids: dict[int, int] = {}
        self._sent: list[int] = []  # bindings the worker knows
        self._fn = None
        self._outs: list[int] = []  # bindings read after each step: sent with the step answer
        self._fresh: dict[int, tuple] = {}
        self._proc: subprocess.Popen | None = None
        self._req = self._resp = None
        self._finalizer = None

    # -- description (local) ----------------------------------------------------------------
    @property
    def variables(self) -> dict:
        return self.local.variables

    @property
    def varmap(self):
        return self.local.varmap

    def variable(self, name: str) -> ModelVariable:
        return self.local.variable(name)

    def use_map(self, entries: dict[str, dict], role: str | None = None, where: str = "",
                prefix: str = "") -> VariableMap:
        vmap = self.local.use_map(entries, role, where, prefix)
        self._map = (entries, role, where, prefix)
        return vmap

    def real_outputs(self) -> list[str]:
        return self.local.real_outputs()

    def outputs(self) -> list[str]:
        return self.local.outputs()

    def check_values(self, values: dict, where: str = "") -> dict:
        return self.local.check_values(values, where)

    def feedthrough(self) -> dict[str, set[str]]:
        return self.local.feedthrough()

    def bind(self, names: list[str] | tuple[str, ...]) -> Binding:
        typed = self.local.bind(names)  # checks the names and types; buffers unused
        b = Binding.plain(names, typed.kinds, typed.types, typed.sizes, typed.wide_pos)
        self._ids[id(b)] = len(self._bindings)
        self._bindings.append(b)
        return b

    # -- the worker -------------------------------------------------------------------------
    def _start(self) -> None:
        req_r, req_w = os.pipe()
        resp_r, resp_w = os.pipe()
        env = dict(os.environ)
        root = str(PACKAGE_DIR.parent)  # the worker imports this very package
        env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
        env[MAX_UNPACKED_ENV] = repr(self._max_unpacked_mb)  # e.g. run.fmu_max_unpacked_mb
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "uwcosim.fmi.proxy", str(req_r), str(resp_w),
                 str(os.getpid())],
                pass_fds=(req_r, resp_w), stdin=subprocess.DEVNULL, env=env)
            process.register(self._proc)
        finally:
            os.close(req_r)
            os.close(resp_w)
        self._req = Connection(req_w, readable=False)
        self._resp = Connection(resp_r, writable=False)
        self._finalizer = weakref.finalize(self, process.reap, self._proc)
        self._call("start", 0.0, ("open", self._args, self._map), limit=STARTUP_S)

    def _call(self, what: str, t: float, request: tuple, limit: float | None = None):
        fmucall.begin(self._ci, _CALL.get(what, 0), t)  # timed by the run-wide watchdog too
        try:
            return self._round_trip(what, t, request, limit)
        finally:
            fmucall.end()

    def _round_trip(self, what: str, t: float, request: tuple, limit: float | None):
        if self._proc is None:
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): worker process not running "
                           f"({what} at t={t:g})")
        try:
            self._req.send(request)
            ready = self._wait(self.timeout_s if limit is None else limit, what, t)
            answer = self._resp.recv() if ready else None
        except (EOFError, OSError, BrokenPipeError):
            rc = self._proc.wait()
            self._stop()
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): worker process died during "
                           f"{what} at t={t:g} (exit status {rc})") from None
        if answer is None:
            self._stop()
            raise FMUError(f"FMU '{self.name}' did not answer {what} within "
                           f"{self.timeout_s if limit is None else limit:g} s at t={t:g} "
                           f"(worker process killed)")
        if answer[0] == "error":
            cls = _ERRORS.get(answer[1], FMUError)
            raise cls(answer[2] if answer[1] in _ERRORS else
                      f"FMU '{self.name}': {what} failed at t={t:g} ({answer[1]}: {answer[2]})")
        return answer[1]

    def _wait(self, limit: float, what: str, t: float) -> bool:
        """Wait up to ``limit`` s for an answer; a stop request kills the worker at once."""
        deadline = time.monotonic() + limit
        while True:
            left = deadline - time.monotonic()
            if self._resp.poll(max(0.0, min(_SLICE_S, left))):
                return True
            if runguard.stop_requested():
                self._stop()
                raise RunInterrupted(f"interrupted during {what} of FMU '{self.name}' at "
                                     f"t={t:g} (worker process killed)")
            if left <= 0:
                return False

    def _stop(self) -> None:
        proc, self._proc = self._proc, None
        if proc is not None:
            process.reap(proc)
        for c in (self._req, self._resp):
            if c is not None:
                c.close()
        self._req = self._resp = None
        if self._finalizer is not None:
            self._finalizer.detach()

    def _sync_bindings(self, t: float) -> None:
        for i in range(len(self._sent), len(self._bindings)):
            self._call("bind", t, ("bind", self._bindings[i].names))
            self._sent.append(i)

    # -- life cycle and hot path --------------------------------------------------------------
    def instantiate(self, parameters: dict, start: dict, t0: float, t_stop: float) -> None:
        if self._proc is None:
            self._start()
        self._sync_bindings(t0)
        self.terminated = None
        self.terminated, self.solver_used = self._call(
            "instantiate", t0, ("instantiate", parameters, start, t0, t_stop))

    def set_inputs(self, b: Binding, t: float) -> None:
        self._fresh.clear()
        if b.n:
            self._sync_bindings(t)
            self._call("set inputs", t, ("set", self._ids[id(b)], b.view.tobytes(), t,
                                         dict(b.text), _wide(b)))

    def get_outputs(self, b: Binding, t: float) -> np.ndarray:
        if b.n:
            i = self._ids[id(b)]
            data = self._fresh.pop(i, None)
            if data is None:  # not sent along with the last step's answer
                self._sync_bindings(t)
                data = self._call("get outputs", t, ("get", i, t))
                if i not in self._outs:
                    self._outs.append(i)
            b.view[:] = np.frombuffer(data[0])
            b.text.update(data[1])
            if data[2]:
                b.wide[:] = np.frombuffer(data[2], dtype=np.int64)
        return b.view

    def do_step(self, t: float, h: float, inputs: Binding,
                input_fn: Callable | None = None) -> float:
        """One round trip: inputs in, doStep, and the outputs read after the last step out;
        returns the time reached (see :attr:`FMUAdapter.terminated`)."""
        self._fresh.clear()
        self._sync_bindings(t)
        fn = None
        if input_fn is not self._fn:  # sent once (pickled): table controls for ME stages
            self._fn = fn = input_fn
        values, reached, self.terminated = self._call(
            "doStep", t, ("step", t, h, self._ids[id(inputs)], inputs.view.tobytes(),
                          fn is not None, fn, tuple(self._outs), dict(inputs.text),
                          _wide(inputs)))
        self._fresh = dict(zip(self._outs, values))
        return reached

    def reset(self) -> None:
        if self._proc is not None:
            self._call("reset", 0.0, ("reset",))

    def close(self) -> None:
        try:
            if self._proc is None:
                return
            if runguard.stop_requested():  # interrupted: no polite terminate
                self._stop()
                return
            try:
                self._call("terminate", 0.0, ("close",))
            except FMUError:
                pass
            self._stop()
        finally:
            if self._scratch is not None:
                self._scratch.cleanup()


def _wide(b: Binding) -> bytes | None:
    """The exact 64-bit values a binding's owner gave (None: take them from ``view``)."""
    return b.wide.tobytes() if b.wide_given and len(b.wide) else None


def _take_wide(b: Binding, data: bytes | None) -> None:
    if data is not None:
        b.wide[:] = np.frombuffer(data, dtype=np.int64)
    b.wide_given = data is not None


def _answer(b: Binding, view: np.ndarray) -> tuple:
    return view.tobytes(), dict(b.text), b.wide.tobytes() if len(b.wide) else b""


# -- worker side ------------------------------------------------------------------------------
def _serve(req: Connection, resp: Connection) -> None:
    adapter: FMUAdapter | None = None
    bindings: list[Binding] = []
    fn = None
    while True:
        try:
            msg = req.recv()
        except EOFError:
            break
        op = msg[0]
        try:
            out = None
            if op == "open":
                adapter = FMUAdapter(*msg[1])
                if msg[2] is not None:
                    adapter.use_map(*msg[2])
            elif op == "bind":
                bindings.append(adapter.bind(msg[1]))
            elif op == "instantiate":
                adapter.instantiate(*msg[1:])
                out = (adapter.terminated, adapter.solver_used)
            elif op == "set":
                b = bindings[msg[1]]
                b.view[:] = np.frombuffer(msg[2])
                b.text.update(msg[4])
                _take_wide(b, msg[5])
                adapter.set_inputs(b, msg[3])
            elif op == "get":
                b = bindings[msg[1]]
                out = _answer(b, adapter.get_outputs(b, msg[2]))
            elif op == "step":
                _, t, h, i, values, new_fn, f, outs, text, wide = msg
                if new_fn:
                    fn = f
                b = bindings[i]
                b.view[:] = np.frombuffer(values)
                b.text.update(text)
                _take_wide(b, wide)
                reached = adapter.do_step(t, h, b, fn)
                out = ([_answer(bindings[j], adapter.get_outputs(bindings[j], reached))
                        for j in outs], reached, adapter.terminated)
            elif op == "reset":
                adapter.reset()
            elif op == "close":
                adapter.close() if adapter is not None else None
                resp.send(("ok", None))
                break
            resp.send(("ok", out))
        except Exception as exc:  # noqa: BLE001 - every error goes back to the master
            resp.send(("error", type(exc).__name__, str(exc)))


def main(argv: list[str] | None = None) -> int:
    # Ctrl-C reaches the whole process group: the master decides, and closes or kills us;
    # if the master dies, so do we
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_IGN)
    argv = sys.argv[1:] if argv is None else argv
    process.die_with_parent(int(argv[2]) if len(argv) > 2 else None)
    req = Connection(int(argv[0]), writable=False)
    resp = Connection(int(argv[1]), readable=False)
    try:
        _serve(req, resp)
    except (BrokenPipeError, EOFError):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
