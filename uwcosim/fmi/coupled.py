"""Model-exchange FMUs connected to each other, integrated as one system (strong coupling).

:class:`CoupledModelExchange` advances several ME FMU instances together from ``t`` to
``t + h``: one integrator over the states of all of them (their states side by side, each
FMU's at its offset), so that the values they exchange follow the states at every stage of the
integrator instead of being held over the communication step. What they exchange is the
caller's: ``exchange(t, event)`` is called whenever the states (and the time) of all members
have been set, and sets every member's inputs from the others' outputs at those states (in
continuous-time mode the continuous inputs; with ``event`` true, in event mode, the discrete
ones too, returning whether a discrete input changed). The master provides it
(:class:`uwcosim.master.loops.Exchange`, which also solves an algebraic loop between members).

The integrator is chosen as for one FMU (:mod:`uwcosim.fmi.solvers`): **CVode** (fmpy's, BDF,
root finding on the event indicators of all members) if a member has event indicators or time
events or asks for ``cvode``; otherwise fixed-step **RK4** over all states (``substeps``, the
largest of the members'), or **DOP853** if a member asks for ``adaptive``. Relative tolerance:
the smallest of the members'.

Events of any member are handled by one joint event loop: every member enters event mode, the
discrete update passes of all members alternate with ``exchange(t, True)`` until no member needs
another pass and no discrete input changed, then every member enters continuous-time mode and
CVode restarts. A member's time event, state event (a root of any indicator) or step event
(``completedIntegratorStep``, called for every member after each integrator step) triggers it;
so does a discrete input changed by the caller at a communication point. A member's request to
stop ends the step at that time (:attr:`CoupledModelExchange.terminated`; each member's
:attr:`~uwcosim.fmi.solvers.ModelExchange.terminated` holds its own).
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable

import numpy as np

from uwcosim.core.errors import FMUError
from uwcosim.core.integrators import rk4
from uwcosim.fmi.binding import Binding
from uwcosim.fmi.solvers import (
    MAX_CVODE_STEPS,
    MAX_EVENT_ITERATIONS,
    ModelExchange,
    NoInput,
    cvode_class,
    cvode_step,
    dop853,
)

#: an exchange: ``exchange(t, event)`` sets the members' inputs at the states set; with
#: ``event`` (event mode) the discrete ones too, and returns True if one of those changed
ExchangeFn = Callable[[float, bool], bool]


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-12 * max(1.0, abs(a), abs(b))


def _at(p, offset: int):
    """The C array ``p`` from element ``offset`` on (CVode's vectors are split by member)."""
    return p if offset == 0 else ctypes.byref(p.contents, 8 * offset)


class CoupledModelExchange:
    """Several model-exchange FMUs stepped as one system (see the module docstring)."""

    def __init__(self, names: list[str], members: list[ModelExchange], inputs: list[Binding],
                 exchange: ExchangeFn, t0: float, t_stop: float, *, solvers: list[str],
                 substeps: list[int], rtols: list[float]) -> None:
        self.names = list(names)
        self.members = list(members)
        self.inputs = list(inputs)
        self.exchange = exchange
        self.nx = [m.nx for m in members]
        self.nz = [m.nz for m in members]
        self.x_off = [int(v) for v in np.cumsum([0, *self.nx])[:-1]]
        self.z_off = [int(v) for v in np.cumsum([0, *self.nz])[:-1]]
        self.nx_total, self.nz_total = sum(self.nx), sum(self.nz)
        self._with_x = [(m, o, n) for m, o, n in zip(members, self.x_off, self.nx) if n]
        self._with_z = [(m, o, n) for m, o, n in zip(members, self.z_off, self.nz) if n]
        #: members with discrete inputs (set in event mode when they change)
        self._discrete = [(m, b) for m, b in zip(members, inputs) if b.discrete_groups]
        self.substeps = max(substeps)
        self.rtol = min(rtols)
        events = any(m.solver_name == "cvode" for m in members) or "cvode" in solvers
        self.solver_name = "cvode" if events else (
            "adaptive" if "adaptive" in solvers else "rk4")
        self.max_step = (t_stop - t0) / 50.0 if t_stop > t0 else math.inf
        self.cvode = None
        self._t = t0
        self._timed = False  # CVode set the time before the states: an evaluation
        #: ``(time, reason, member index)`` once a member asked to stop, else None
        self.terminated: tuple[float, str, int] | None = None

    # -- all members at once ------------------------------------------------------------------
    def _set_time(self, t: float) -> None:
        self._t = t
        for m in self.members:
            m.set_time(t)

    def _states(self) -> np.ndarray:
        return np.concatenate([m.states() for m in self.members]) if self.nx_total else \
            np.zeros(0)

    def _set_states(self, x: np.ndarray) -> None:
        for m, o, n in self._with_x:
            m.set_states(x[o:o + n])

    def _derivatives(self) -> np.ndarray:
        return np.concatenate([m.derivatives() for m, _, _ in self._with_x]) \
            if self.nx_total else np.zeros(0)

    def _deriv(self, t: float, x: np.ndarray) -> np.ndarray:
        self._set_time(t)
        self._set_states(x)
        self.exchange(t, False)
        return self._derivatives()

    def _stopped(self, index: int) -> bool:
        m = self.members[index]
        if m.terminated is None:
            return False
        self.terminated = (m.terminated[0], m.terminated[1], index)
        return True

    def _completed(self, t: float) -> bool:
        """completedIntegratorStep of every member: True if one asks for an event."""
        event = False
        for i, m in enumerate(self.members):
            enter, stop = m.completed_step(t)
            if stop and self._stopped(i):
                return False
            event = event or enter
        return event

    # -- the joint event loop -------------------------------------------------------------------
    def _event(self, t: float) -> None:
        for m in self.members:
            m.enter_event_mode(t)
        need = True
        for _ in range(MAX_EVENT_ITERATIONS):
            changed = self.exchange(t, True)
            if not need and not changed:
                break
            need = False
            for i, m in enumerate(self.members):
                need = m.update_pass(t) or need
                if self._stopped(i):
                    return
        else:
            raise FMUError(f"FMUs {', '.join(self.names)} (integrated together): the event "
                           f"iteration did not converge at t={t:g} ({MAX_EVENT_ITERATIONS} "
                           f"iterations)")
        for m in self.members:
            m.enter_continuous_mode(t)
        if any(m.next_event is not None for m in self.members):
            self.solver_name = "cvode"  # a time event from now on: the event-aware path
        if self.cvode is not None:
            self.cvode.reset(t)

    # -- stepping -------------------------------------------------------------------------------
    def step(self, t: float, h: float) -> float:
        """Advance every member from ``t`` to ``t + h``; the time reached (earlier only when a
        member asked to stop: :attr:`terminated`). The members' inputs from outside are in
        their bindings (held over the step); ``exchange`` sets them with the others'."""
        if self.terminated is not None:
            return self.terminated[0]
        if t != self._t:  # else the members are at t since the end of the last step
            self._set_time(t)
        self.exchange(t, False)
        if any(m.discrete_changes(b) for m, b in self._discrete):
            self._event(t)  # a discrete input from outside changed: one joint event
            if self.terminated is not None:
                return self.terminated[0]
        if self.solver_name == "cvode":
            return self._step_events(t, t + h)
        x = self._states()
        if self.nx_total:
            if self.solver_name == "adaptive":
                x = dop853(self._deriv, x, t, h, self.rtol, ", ".join(self.names))
            else:
                x = rk4(self._deriv, x, t, h, self.substeps)
        t_end = t + h
        self._set_time(t_end)
        self._set_states(x)
        self.exchange(t_end, False)
        if self._completed(t_end):
            self._event(t_end)
        return self.terminated[0] if self.terminated is not None else t_end

    # -- event-aware (CVode) ------------------------------------------------------------------
    def _cb_set_time(self, t: float) -> None:
        self._set_time(t)
        self._timed = True

    def _cb_get_x(self, p, n) -> None:
        for m, o, k in self._with_x:
            m.get_states_into(_at(p, o), k)

    def _cb_set_x(self, p, n) -> None:
        for m, o, k in self._with_x:
            m.set_states_from(_at(p, o), k)
        if self._timed:  # an evaluation (else the states CVode reached: exchanged at that time)
            self._timed = False
            self.exchange(self._t, False)

    def _cb_get_dx(self, p, n) -> None:
        for m, o, k in self._with_x:
            m.get_derivatives_into(_at(p, o), k)

    def _cb_get_z(self, p, n) -> None:
        for m, o, k in self._with_z:
            m.get_indicators_into(_at(p, o), k)

    def _cb_get_nominals(self, p, n) -> None:
        for m, o, k in self._with_x:
            m.get_nominals_into(_at(p, o), k)

    def _integrate(self, time: float, t_next: float) -> tuple[bool, float]:
        if not self.nx_total and not self.nz_total:  # nothing continuous: jump
            return False, t_next
        if self.cvode is None:
            self.cvode = cvode_class()(
                nx=self.nx_total, nz=self.nz_total, get_x=self._cb_get_x, set_x=self._cb_set_x,
                get_dx=self._cb_get_dx, get_z=self._cb_get_z,
                get_nominals=self._cb_get_nominals, set_time=self._cb_set_time,
                input=NoInput(), startTime=time, maxStep=self.max_step,
                relativeTolerance=self.rtol, maxNumSteps=MAX_CVODE_STEPS)
        return cvode_step(self.cvode, time, t_next,
                          f"FMUs {', '.join(self.names)} (integrated together)")

    def _step_events(self, t: float, t_end: float) -> float:
        time, same_time, last_event = t, 0, None
        while True:
            t_next, time_event = t_end, False
            due = [m.next_event for m in self.members if m.next_event is not None]
            ne = min(due) if due else None
            if ne is not None and (ne < t_end or _close(ne, t_end)):
                # an event within rounding of the communication point happens there
                t_next, time_event = t_end if _close(ne, t_end) else max(ne, time), True
            if t_next > time and not _close(t_next, time):
                state_event, time = self._integrate(time, t_next)
            else:
                state_event, time = False, t_next
            # CVode set the states it reached (no exchange yet): the time and the exchange
            self._set_time(time)
            self.exchange(time, False)
            if state_event:
                time_event = time_event and _close(time, t_next)
            step_event = self._completed(time)
            if self.terminated is not None:
                return self.terminated[0]
            if state_event or time_event or step_event:
                same_time = same_time + 1 if time == last_event else 0
                if same_time > MAX_EVENT_ITERATIONS:
                    raise FMUError(f"FMUs {', '.join(self.names)} (integrated together): more "
                                   f"than {MAX_EVENT_ITERATIONS} events at t={time:g} (time "
                                   f"events that do not advance?)")
                last_event = time
                self._event(time)
                if self.terminated is not None:
                    return self.terminated[0]
            if time >= t_end or _close(time, t_end):
                return t_end
