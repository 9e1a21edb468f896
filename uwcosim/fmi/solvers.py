"""Model-exchange stepping: the FMI 2.0 / 3.0 ME state machine between communication points.

:class:`ModelExchange` advances one ME FMU instance from ``t`` to ``t + h`` (a communication
step of the master) and chooses the integrator once, after initialization:

- **Fixed-step RK4** (``solver = "rk4"``, ``substeps`` per step) or scipy's **DOP853**
  (``"adaptive"``) for FMUs without events: no event indicators and no time event after the
  initial event iteration. This is the project's fast path (its TAN FMUs); results are those of
  earlier versions bit for bit. ``completedIntegratorStep`` is called once per step; a step
  event is handled at the end of the step; an FMU that defines a time event later switches to
  the event-aware path.
- **Event-aware** (``cvode``): SUNDIALS CVode (BDF, fmpy's ``fmpy.sundials.CVodeSolver``) with
  root finding on the event indicators, as ``fmpy.simulate_fmu`` integrates ME FMUs: the
  integration stops at each time event (``nextEventTime``) and each state event (a root of an
  event indicator, located to CVode's root tolerance), calls ``completedIntegratorStep``
  (step events), then enters event mode, runs the ``newDiscreteStates`` /
  ``updateDiscreteStates`` iteration until no more is needed and re-initializes CVode at the
  event time (new states, nominals, event indicators). Events between communication points are
  handled inside the step. Relative tolerance ``rtol``; absolute ``rtol * nominal``; largest
  internal step ``(t_stop - t0) / 50`` (fmpy's choice).

Discrete inputs (Integer, Boolean, String, or discrete Real) are set in event mode at the
communication point when they changed (the FMU refuses them in continuous-time mode).
``terminateSimulation`` from an event update or from ``completedIntegratorStep`` stops the
integration at that time and sets :attr:`ModelExchange.terminated` (the adapter's
:attr:`~uwcosim.fmi.adapter.FMUAdapter.terminated` after the call).

The integrator calls the FMU through its :class:`~uwcosim.fmi.instance.Instance` (the C
functions, the component and the status checks), not through the adapter.
"""

from __future__ import annotations

import ctypes
import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from uwcosim.core.errors import FMUError
from uwcosim.core.integrators import rk4
from uwcosim.fmi.binding import Binding
from uwcosim.fmi.instance import Instance

if TYPE_CHECKING:  # loaded on first use (cvode_class)
    from fmpy.sundials import CVodeSolver

#: event iterations allowed before the FMU is declared not converging
MAX_EVENT_ITERATIONS = 1000
#: CVode's internal steps allowed per call (fmpy: 500, enough for its output intervals; a
#: master's communication step may be long). The results do not depend on it.
MAX_CVODE_STEPS = 100_000
#: event times kept in :attr:`ModelExchange.event_times`
MAX_LOGGED_EVENTS = 100_000


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-12 * max(1.0, abs(a), abs(b))


def dop853(deriv: Callable, x0: np.ndarray, t: float, h: float, rtol: float,
           name: str) -> np.ndarray:
    """scipy's adaptive DOP853 from ``t`` to ``t + h`` (no events)."""
    from scipy.integrate import solve_ivp  # lazy: scipy.integrate only for solver "adaptive"

    sol = solve_ivp(deriv, (t, t + h), x0, method="DOP853", rtol=rtol, atol=rtol * 1e-3)
    if not sol.success:
        raise FMUError(f"FMU '{name}': adaptive solver failed at t={t:g} ({sol.message})")
    return sol.y[:, -1]


class NoInput:
    """fmpy's CVodeSolver applies ``input.apply(t)`` in its root function: inputs are ours."""

    @staticmethod
    def apply(t: float, **_) -> None:
        return None


@functools.cache
def cvode_class():
    """fmpy's CVodeSolver with callbacks that report an FMU error (loaded on first use)."""
    # lazy: fmpy.sundials loads the SUNDIALS libraries, needed only on the event-aware path
    from fmpy.sundials import CVodeSolver, sundials_types
    from fmpy.sundials import cvode as cv
    from fmpy.sundials.libraries import sundials_core
    from fmpy.sundials.sundials_context import SUNContext_PushErrHandler
    from fmpy.sundials.sundials_types import SUNContext

    class CVode(CVodeSolver):
        """fmpy's CVode with callbacks that report an FMU error instead of printing it."""

        error: Exception | None = None

        def __init__(self, **kwargs) -> None:
            super().__init__(**kwargs)
            self._tret = sundials_types.sunrealtype(0.0)
            self._tret_ref = ctypes.byref(self._tret)
            self._no_roots = np.zeros(self.nz, dtype=np.int32)
            # only fmpy's handler (it keeps the message for the exception): SUNDIALS' default
            # one would also print it to stderr, and the CLI's errors are one line
            clear = sundials_core.SUNContext_ClearErrHandlers
            clear.argtypes, clear.restype = [SUNContext], ctypes.c_int
            if clear(self.sunctx) == 0:
                SUNContext_PushErrHandler(self.sunctx, self.ehfun_, None)

        def f(self, t, y, ydot, user_data):
            try:
                return super().f(t, y, ydot, user_data)
            except Exception as exc:  # noqa: BLE001 - raised again after CVode returns
                self.error = exc
                return -1

        def g(self, t, y, gout, user_data):
            try:
                return super().g(t, y, gout, user_data)
            except Exception as exc:  # noqa: BLE001
                self.error = exc
                return -1

        def step(self, t, tNext):
            """fmpy's step (the same calls) without its per-call allocations."""
            if not self.discrete:
                self.get_x(self.px, self.nx)
            flag = cv.CVode(self.cvode_mem, tNext, self.x, self._tret_ref, cv.CV_NORMAL)
            if not self.discrete:
                self.set_x(self.px, self.nx)
            if flag == cv.CV_ROOT_RETURN:
                roots = np.zeros(self.nz, dtype=np.int32)
                if cv.CVodeGetRootInfo(self.cvode_mem, np.ctypeslib.as_ctypes(roots)) != 0:
                    raise RuntimeError("CVodeGetRootInfo failed")
                return True, roots, self._tret.value
            if flag < 0:
                raise RuntimeError(f"CVode error (flag {flag}): {self.error_info}")
            return flag > 0, self._no_roots, self._tret.value

    return CVode


def cvode_step(cvode: CVodeSolver, time: float, t_next: float, what: str) -> tuple[bool, float]:
    """One call of fmpy's CVode solver from ``time`` towards ``t_next``: ``(state event,
    time reached)``. A failure is an FMUError naming ``what`` (the FMU, or the FMUs integrated
    together) and why: the FMUError a callback raised, or CVode's own message."""
    try:
        state_event, _, reached = cvode.step(time, t_next)
    except RuntimeError as exc:
        err, cvode.error = cvode.error, None
        if isinstance(err, FMUError):
            raise err from None
        info = cvode.error_info
        why = err or (info[3] if info else exc)
        raise FMUError(f"{what}: CVode failed between t={time:g} and {t_next:g} ({why})") from None
    return bool(state_event), float(reached)


class ModelExchange:
    """Steps one model-exchange FMU instance (see the module docstring).

    It calls the FMU through its :class:`~uwcosim.fmi.instance.Instance` and sets the continuous
    inputs with ``set_continuous(binding, t)`` (the adapter's); :attr:`terminated` is set when
    the FMU asks to stop."""

    def __init__(self, instance: Instance, set_continuous: Callable[[Binding, float], None],
                 t0: float, t_stop: float, *, nx: int, nz: int, solver: str = "rk4",
                 substeps: int = 1, rtol: float = 1e-8) -> None:
        self.inst = inst = instance
        self._set_continuous = set_continuous
        fmi3 = inst.fmi3
        p = "fmi3" if fmi3 else "fmi2"
        fn, self._c = inst.function, inst.component
        self.nx, self.nz = nx, nz
        self.substeps, self.rtol = substeps, rtol
        self._x = (ctypes.c_double * self.nx)()
        self._dx = (ctypes.c_double * self.nx)()
        self.xv = np.ctypeslib.as_array(self._x) if self.nx else np.zeros(0)
        self.dxv = np.ctypeslib.as_array(self._dx) if self.nx else np.zeros(0)
        self._set_time = fn(f"{p}SetTime")
        self._set_states = fn(f"{p}SetContinuousStates")
        self._get_states = fn(f"{p}GetContinuousStates")
        self._get_der = fn("fmi3GetContinuousStateDerivatives" if fmi3 else
                           "fmi2GetDerivatives")
        self._get_z = fn(f"{p}GetEventIndicators")
        self._get_nominals = fn(f"{p}GetNominalsOfContinuousStates")
        self._completed = fn(f"{p}CompletedIntegratorStep")
        self._enter_event = fn(f"{p}EnterEventMode")
        flag = ctypes.c_bool if fmi3 else ctypes.c_int
        self._cflags = [flag(), flag()]
        self._cflag_refs = [ctypes.byref(f) for f in self._cflags]
        self._true = True if fmi3 else 1  # noSetFMUStatePriorToCurrentPoint
        self.t0, self.t_stop = t0, t_stop
        self.max_step = (t_stop - t0) / 50.0 if t_stop > t0 else math.inf
        self.next_event: float | None = None
        self.solver_name = "cvode" if self.nz else solver
        self.cvode = None
        self._t = t0
        self._inputs = None
        self._input_fn = None
        #: ``(time, reason)`` once the FMU asked to stop (an event update or
        #: completedIntegratorStep), else None
        self.terminated: tuple[float, str] | None = None
        #: times of the events handled after initialization (the first MAX_LOGGED_EVENTS)
        self.event_times: list[float] = []

    # -- event mode ---------------------------------------------------------------------------
    def _iterate(self, t: float) -> None:
        fmu = self.inst.fmu
        update = fmu.updateDiscreteStates if self.inst.fmi3 else fmu.newDiscreteStates
        for _ in range(MAX_EVENT_ITERATIONS):
            need, terminate, _, _, defined, t_next = self.inst.guard("event update", update, t)
            if terminate:
                self.terminated = (t, self.inst.reason("terminateSimulation (event update)"))
                return
            if not need:
                self.next_event = float(t_next) if defined else None
                return
        raise FMUError(f"FMU '{self.inst.name}' ({self.inst.path.name}): event iteration did not "
                       f"converge at t={t:g} ({MAX_EVENT_ITERATIONS} iterations)")

    # -- the pieces a joint integrator uses (:mod:`uwcosim.fmi.coupled`) -----------------------
    def enter_event_mode(self, t: float) -> None:
        """enterEventMode at ``t`` (the event time is logged)."""
        self.inst.check(self._enter_event(self._c), "enterEventMode", t)
        if len(self.event_times) < MAX_LOGGED_EVENTS:
            self.event_times.append(t)

    def update_pass(self, t: float) -> bool:
        """One pass of the discrete update in event mode: True if the FMU needs another one
        (a request to stop sets :attr:`terminated`; a converged pass, :attr:`next_event`)."""
        fmu = self.inst.fmu
        update = fmu.updateDiscreteStates if self.inst.fmi3 else fmu.newDiscreteStates
        need, terminate, _, _, defined, t_next = self.inst.guard("event update", update, t)
        if terminate:
            self.terminated = (t, self.inst.reason("terminateSimulation (event update)"))
            return False
        if not need:
            self.next_event = float(t_next) if defined else None
        return bool(need)

    def enter_continuous_mode(self, t: float) -> None:
        self.inst.guard("enterContinuousTimeMode", self.inst.fmu.enterContinuousTimeMode, t)
        if self.next_event is not None:
            self.solver_name = "cvode"

    def set_time(self, t: float) -> None:
        """setTime (no input refresh: the joint integrator sets the inputs itself)."""
        self._t = t
        st = self._set_time(self._c, t)
        if st > 1:
            self.inst.check(st, "setTime", t)

    def set_states(self, x: np.ndarray) -> None:
        if self.nx:
            self.xv[:] = x
            self.inst.check(self._set_states(self._c, self._x, self.nx),
                            "setContinuousStates", self._t)

    def derivatives(self) -> np.ndarray:
        if self.nx:
            self.inst.check(self._get_der(self._c, self._dx, self.nx), "getDerivatives",
                            self._t)
        return self.dxv.copy()

    def completed_step(self, t: float) -> tuple[bool, bool]:
        """completedIntegratorStep: ``(enter event mode, terminate)``; a request to stop sets
        :attr:`terminated`."""
        st = self._completed(self._c, self._true, *self._cflag_refs)
        if st > 1:
            self.inst.check(st, "completedIntegratorStep", t)
        if self._cflags[1].value:
            self.terminated = (t, self.inst.reason(
                "terminateSimulation (completedIntegratorStep)"))
            return False, True
        return bool(self._cflags[0].value), False

    def discrete_changes(self, b: Binding) -> list:
        """The discrete input groups of ``b`` whose values changed since last set."""
        if not b.groups:
            return []
        b.to_fmu()
        changed = []
        for g in b.discrete_groups:
            b.raw_to_group(g)
            cur = g.arr.copy() if g.arr is not None else [g.buf[j] for j in range(g.n)]
            same = g.last is not None and (np.array_equal(cur, g.last) if g.arr is not None
                                           else cur == g.last)
            if not same:
                changed.append((g, cur))
        return changed

    def apply_discrete(self, changed: list, t: float) -> None:
        """Set the changed discrete groups (:meth:`discrete_changes`) in event mode."""
        for g, cur in changed:
            if self.inst.fmi3:
                st = g.set(self._c, g.vr, g.nvr, g.buf, g.n)
            else:
                st = g.set(self._c, g.vr, g.nvr, g.buf)
            self.inst.check(st, "set discrete inputs", t)
            g.last = cur

    def initial_event(self, t0: float) -> None:
        """After exitInitializationMode (event mode): iterate, then continuous-time mode."""
        self._iterate(t0)
        if self.terminated is None:
            self.inst.guard("enterContinuousTimeMode", self.inst.fmu.enterContinuousTimeMode, t0)
        if self.next_event is not None:
            self.solver_name = "cvode"

    def _event(self, t: float, before=None) -> None:
        self.inst.check(self._enter_event(self._c), "enterEventMode", t)
        if before is not None:
            before()
        if len(self.event_times) < MAX_LOGGED_EVENTS:
            self.event_times.append(t)
        self._iterate(t)
        if self.terminated is None:
            self.inst.guard("enterContinuousTimeMode", self.inst.fmu.enterContinuousTimeMode, t)
        if self.next_event is not None:
            self.solver_name = "cvode"  # a time event from now on: the event-aware path
        if self.cvode is not None:
            self.cvode.reset(t)

    def set_discrete(self, b: Binding, t: float) -> None:
        """Set the discrete inputs of ``b`` that changed, in event mode (one event)."""
        changed = self.discrete_changes(b)
        if not changed or self.terminated is not None:
            return
        self._event(t, lambda: self.apply_discrete(changed, t))

    # -- stepping -----------------------------------------------------------------------------
    def states(self) -> np.ndarray:
        if self.nx:
            self.inst.check(self._get_states(self._c, self._x, self.nx), "getContinuousStates",
                            self._t)
        return self.xv.copy()

    def step(self, t: float, h: float, inputs: Binding, input_fn: Callable | None) -> float:
        if inputs.groups and inputs.discrete_groups:
            self.set_discrete(inputs, t)
        if self.terminated is not None:
            return self.terminated[0]
        if self.solver_name == "cvode":
            return self._step_events(t, t + h, inputs, input_fn)
        x_end = self._fixed(t, h, inputs, input_fn)
        self._finish(t + h, x_end, inputs, input_fn)
        return self.terminated[0] if self.terminated is not None else t + h

    def _deriv(self, t: float, x: np.ndarray, inputs, input_fn) -> np.ndarray:
        check = self.inst.check
        check(self._set_time(self._c, t), "setTime", t)
        if input_fn is not None:
            input_fn(t, inputs.view)
        self._set_continuous(inputs, t)
        if self.nx:
            self.xv[:] = x
            check(self._set_states(self._c, self._x, self.nx), "setContinuousStates", t)
            check(self._get_der(self._c, self._dx, self.nx), "getDerivatives", t)
        return self.dxv.copy()

    def _fixed(self, t: float, h: float, inputs, input_fn) -> np.ndarray:
        x = self.states()
        if self.solver_name == "adaptive":
            if not self.nx:
                return x
            return dop853(lambda tt, xx: self._deriv(tt, xx, inputs, input_fn), x, t, h,
                          self.rtol, self.inst.name)
        return rk4(lambda tt, xx: self._deriv(tt, xx, inputs, input_fn), x, t, h,
                   self.substeps)

    def _finish(self, t: float, x_end: np.ndarray, inputs, input_fn) -> None:
        inst = self.inst
        inst.check(self._set_time(self._c, t), "setTime", t)
        self._t = t
        if input_fn is not None:
            input_fn(t, inputs.view)
        self._set_continuous(inputs, t)
        if self.nx:
            self.xv[:] = x_end
            inst.check(self._set_states(self._c, self._x, self.nx), "setContinuousStates", t)
        st = self._completed(self._c, self._true, *self._cflag_refs)
        inst.check(st, "completedIntegratorStep", t)
        if self._cflags[1].value:
            self.terminated = (t, inst.reason("terminateSimulation (completedIntegratorStep)"))
            return
        if self._cflags[0].value:
            self._event(t)

    # -- event-aware (CVode) ------------------------------------------------------------------
    # CVode's callbacks (pointer, size): status checked inline, they run per right-hand side
    def _cb_set_time(self, t: float) -> None:
        self._t = t
        st = self._set_time(self._c, t)
        if st > 1:
            self.inst.check(st, "setTime", t)
        if self._input_fn is not None:
            self._input_fn(t, self._inputs.view)
            self._set_continuous(self._inputs, t)

    def get_states_into(self, p: object, n: int) -> None:
        """getContinuousStates into the C array ``p`` (CVode's callbacks: pointer, size)."""
        st = self._get_states(self._c, p, n)
        if st > 1:
            self.inst.check(st, "getContinuousStates", self._t)

    def set_states_from(self, p: object, n: int) -> None:
        st = self._set_states(self._c, p, n)
        if st > 1:
            self.inst.check(st, "setContinuousStates", self._t)

    def get_derivatives_into(self, p: object, n: int) -> None:
        st = self._get_der(self._c, p, n)
        if st > 1:
            self.inst.check(st, "getDerivatives", self._t)

    def get_indicators_into(self, p: object, n: int) -> None:
        st = self._get_z(self._c, p, n)
        if st > 1:
            self.inst.check(st, "getEventIndicators", self._t)

    def get_nominals_into(self, p: object, n: int) -> None:
        self.inst.check(self._get_nominals(self._c, p, n), "getNominalsOfContinuousStates",
                        self._t)

    def _make_cvode(self, t: float):
        return cvode_class()(
            nx=self.nx, nz=self.nz, get_x=self.get_states_into, set_x=self.set_states_from,
            get_dx=self.get_derivatives_into, get_z=self.get_indicators_into,
            get_nominals=self.get_nominals_into,
            set_time=self._cb_set_time, input=NoInput(), startTime=t, maxStep=self.max_step,
            relativeTolerance=self.rtol, maxNumSteps=MAX_CVODE_STEPS)

    def _integrate(self, time: float, t_next: float) -> tuple[bool, float]:
        """CVode from ``time`` to ``t_next`` or the first root: ``(state event, time)``."""
        if not self.nx and not self.nz:  # nothing continuous: jump
            self._cb_set_time(t_next)
            return False, t_next
        if self.cvode is None:
            self.cvode = self._make_cvode(time)
        return cvode_step(self.cvode, time, t_next,
                          f"FMU '{self.inst.name}' ({self.inst.path.name})")

    def _step_events(self, t: float, t_end: float, inputs, input_fn) -> float:
        inst = self.inst
        self._inputs, self._input_fn = inputs, input_fn
        if input_fn is not None:
            self._cb_set_time(t)  # refreshes the continuous inputs
        self._set_continuous(inputs, t)
        time, flag_true, same_time = t, self._true, 0
        while True:
            t_next, time_event = t_end, False
            ne = self.next_event
            if ne is not None and (ne < t_end or _close(ne, t_end)):
                # an event within rounding of the communication point happens there (fmpy too)
                t_next, time_event = t_end if _close(ne, t_end) else max(ne, time), True
            if t_next > time and not _close(t_next, time):
                state_event, time = self._integrate(time, t_next)
            else:
                state_event, time = False, t_next
            if state_event:
                time_event = time_event and _close(time, t_next)
            self._cb_set_time(time)
            st = self._completed(self._c, flag_true, *self._cflag_refs)
            if st > 1:
                inst.check(st, "completedIntegratorStep", time)
            if self._cflags[1].value:
                self.terminated = (time, inst.reason(
                    "terminateSimulation (completedIntegratorStep)"))
                return time
            if state_event or time_event or self._cflags[0].value:
                same_time = same_time + 1 if self.event_times and time == self.event_times[-1] \
                    else 0
                if same_time > MAX_EVENT_ITERATIONS:
                    raise FMUError(f"FMU '{inst.name}' ({inst.path.name}): more than "
                                   f"{MAX_EVENT_ITERATIONS} events at t={time:g} (time events "
                                   f"that do not advance?)")
                self._event(time)
                if self.terminated is not None:
                    return time
            if time >= t_end or _close(time, t_end):
                return t_end
