"""Drives a scenario's estimators from the master, as an observer of its steps.

At each step ``t_k -> t_{k+1}`` every estimator predicts over the step's duration (the view's
``dt``: the master's base step, or the gap between a replay's time stamps) with the control held
over the step, then updates with the measurements received at ``t_{k+1}`` (common random
numbers: all estimators see the same :class:`~uwcosim.master.measurement.Measurement`, from the
master's sensor bank, which the log records too), after its lost-measurement policy has
decided what to feed it.

The estimators do not act on the co-simulation, so they need not run inside its step: the bank
records each step's inputs and runs the estimators over a block of ``[run] filter_block``
steps at a time, one estimator after the other. Each then keeps its grid, particles and
tables in the CPU caches for the whole block instead of finding them evicted by the other
estimators, the FMUs and the log at every step: a Table 1 run of five filters takes about a
quarter less time. Every estimator has its own random stream and sees the same inputs in the
same order, so the results do not depend on the block size (``tests/test_filter_blocks.py``).
A block also ends at each density snapshot step (all estimators must be at the same step) and
with each row group of the log (a row group written, also one kept after a kill, has its
estimates). Each filtered step's estimates go to the bank's ``sink`` with the step's index
(the log recorder, :meth:`uwcosim.run.recorder.LogRecorder.estimates`).

At ``k = 0`` (the start time) the bank builds its estimators at the truth plus the initial
error (``[estimation] initial_state`` replaces the truth of the states it names; a replay's
reference, which may be missing there, is its truth), from :class:`EstimatorPlan` s
(:func:`plans`: what ``[estimators]`` and ``[estimation]`` of a scenario say); the truth,
control and measurement layout come from the run layer
(:func:`uwcosim.run.simulate.simulate`), not from the master.

A diverging estimator (:mod:`uwcosim.run.divergence`: non-finite state,
covariance not symmetric positive definite, negative NIS/NEES, position out of bounds) is
flagged and stopped; the others go on. So is one whose code fails: any exception raised in its
``predict`` or ``update`` (a user's filter: its type, message, file and line), or an ``x`` /
``P`` of the wrong shape after a step. Each stop is one warning line (logger
``uwcosim.run.bank``) naming the estimator, the step and the time, and is kept in
``simulation.json`` (``error``, ``stopped_step``); its log columns are NaN from that step on.

The scenario was validated when it was loaded (:mod:`uwcosim.scenario.validate`: sensors,
controls, filter types, policies and settings), so the bank trusts it.
"""

from __future__ import annotations

import logging
import time
from array import array
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

from uwcosim.core.errors import FilterDivergence, ScenarioError
from uwcosim.core.jit import interrupted
from uwcosim.core.plugins import describe_error
from uwcosim.core.rng import stream
from uwcosim.filters import Estimator
from uwcosim.filters.base import build
from uwcosim.filters.policies import POLICIES
from uwcosim.master.observer import StepView
from uwcosim.models.protocol import StateSpaceModel
from uwcosim.run.divergence import DivergenceCheck
from uwcosim.runlog.columns import EstimateBlock
from uwcosim.scenario.schema import EstimationSpec, EstimatorSpec
from uwcosim.scenario.validate import validated_settings

log = logging.getLogger(__name__)

#: where a bank's estimates of step ``k`` go: ``sink(k, values, diverged)``
Sink = Callable[[int, np.ndarray, list[bool]], None]


@dataclass(frozen=True)
class _Step:
    """What the estimators need of one step ``t - dt -> t`` (step ``k``); ``dt`` is the
    step's own duration (:attr:`~uwcosim.master.observer.StepView.dt`: the master's base step,
    or a replay's gap between two time stamps)."""

    k: int
    t: float
    dt: float
    u: np.ndarray  # controls held over the step
    z: np.ndarray
    received: np.ndarray
    truth: np.ndarray


@dataclass(frozen=True)
class EstimatorPlan:
    """How to build one estimator: filter type, settings, lost-measurement policy, the
    measurement components it uses and its initial standard deviations (None: the bank's)."""

    name: str
    type: str
    settings: dict
    policy: str
    use: np.ndarray  # bool [nz]
    initial_std: np.ndarray | None = None


def plans(estimators: dict[str, EstimatorSpec], model_sensors: Sequence[str],
          sensor_of: Sequence[str]) -> list[EstimatorPlan]:
    """The plans of a validated scenario's ``[estimators]``; ``sensor_of``: the sensor of each
    component of the measurement vector, ``model_sensors``: the filters' model's sensors."""
    out = []
    for name, es in estimators.items():
        use_sensors = es.sensors if es.sensors is not None else list(model_sensors)
        use = np.array([s in use_sensors for s in sensor_of], dtype=bool)
        std = np.asarray(es.initial_std, float) if es.initial_std else None
        out.append(EstimatorPlan(name, es.type, validated_settings(es), es.policy, use, std))
    return out


@dataclass
class Track:
    """One estimator and what the bank keeps about it."""

    name: str
    estimator: Estimator
    policy: object
    use: np.ndarray  # bool [nz]: components of sensors this estimator uses
    nees: float = float("nan")
    diverged_at: float | None = None
    error: str = ""
    #: the step at which it was stopped (None: it was not)
    stopped_step: int | None = None
    #: its filter type (for the stop's message)
    type: str = ""
    step_times: array = field(default_factory=lambda: array("d"))  # 8 bytes per step


class EstimatorBank:
    """All estimators of a run: an observer of the master's steps (:meth:`on_step`)."""

    def __init__(self, model: StateSpaceModel, plans: Sequence[EstimatorPlan], *,
                 truth_slots: Sequence[int], control_slots: Sequence[int], seed: int,
                 where: str, check: DivergenceCheck,
                 estimation: EstimationSpec | None = None, block: int = 1,
                 sync_steps: Collection[int] = (), row_group: int = 0,
                 sink: Sink | None = None) -> None:
        self.model = model
        self.plans = list(plans)
        self.where = where
        self.seed = int(seed)
        self.check = check
        self.estimation = estimation
        self.block = max(int(block), 1)
        self.sync_steps = frozenset(int(k) for k in sync_steps)
        self._row_group = int(row_group)  # the log's rows per row group: blocks end with them
        self.sink = sink
        self.truth_slots = np.asarray(truth_slots, dtype=np.intp)
        self.control_slots = np.asarray(control_slots, dtype=np.intp)
        self._pending: list[_Step] = []
        self.busy = False  # inside flush (the signal watcher must not filter then)
        self._layout = EstimateBlock.of(model.nx)
        #: the estimators, in the order of the plans (built at k = 0)
        self.tracks: list[Track] = []

    # ------------------------------------------------------------------------------------------
    # the start: the estimators at the truth plus the initial error

    def _start(self, t0: float, x_true0: np.ndarray) -> None:
        model, est_common = self.model, self.estimation
        init_rng = stream(self.seed, "initial-error")
        std0 = np.asarray(est_common.initial_std if est_common else np.ones(model.nx), float)
        err0 = init_rng.standard_normal(model.nx) * std0
        if est_common is not None and est_common.initial_error == "zero":
            err0[:] = 0.0
        x_true0 = self._initial_mean(t0, x_true0)
        self.tracks = []
        for plan in self.plans:
            std = plan.initial_std if plan.initial_std is not None else std0
            key = f"{self.where}: key 'estimators.{plan.name}'"
            with np.errstate(over="ignore"):  # a std above 1.3e154: refused in one line
                var = std**2
            if not np.all(np.isfinite(var)):
                name = f"estimators.{plan.name}.initial_std" if plan.initial_std is not None \
                    else "estimation.initial_std"
                raise ScenarioError(f"{self.where}: key '{name}': {std[~np.isfinite(var)][0]:g} "
                                    f"squared is not a finite variance (float64 holds "
                                    f"standard deviations up to about 1.3e154)")
            try:
                est = build(plan.type, model, x_true0 + err0, np.diag(var), plan.settings,
                            rng=stream(self.seed, f"estimator:{plan.name}"))
            except (TypeError, ValueError) as exc:  # what needs the model (names, memory)
                raise ScenarioError(f"{key}: {exc}") from None
            except MemoryError:
                raise ScenarioError(f"{key}: not enough memory for these settings") from None
            except ScenarioError:
                raise
            except Exception as exc:  # noqa: BLE001 - a user's constructor: one line
                raise ScenarioError(f"{key}: constructing {plan.type!r} failed: "
                                    f"{describe_error(exc)}") from None
            why = shape_problem(est, model.nx)
            if why:
                raise ScenarioError(f"{key}: {plan.type!r} at the start: {why}")
            est.t = t0
            policy = POLICIES.get(plan.policy)(model.nz)
            self.tracks.append(Track(plan.name, est, policy, plan.use, type=plan.type))

    def _initial_mean(self, t0: float, x_true0: np.ndarray) -> np.ndarray:
        """The truth at the start time, with ``[estimation] initial_state`` for the states it
        names; every state needs a value (a replay's reference may have none there)."""
        x0 = np.array(x_true0, dtype=float)
        names = list(self.model.state_names)
        given = (self.estimation.initial_state or {}) if self.estimation is not None else {}
        for s, v in given.items():
            if s not in names:
                raise ScenarioError(f"{self.where}: key 'estimation.initial_state.{s}': not a "
                                    f"state of the filters' model ({', '.join(names)})")
            x0[names.index(s)] = v
        missing = [names[i] for i in np.flatnonzero(~np.isfinite(x0))]
        if missing:
            raise ScenarioError(f"{self.where}: key 'estimation.initial_state': no truth or "
                                f"reference at t={t0:g} for {', '.join(missing)}: the "
                                f"estimators start there; give them, e.g. initial_state = "
                                f"{{{', '.join(f'{m} = 0.0' for m in missing)}}}")
        return x0

    def live(self) -> list[tuple[str, Estimator]]:
        """``(name, estimator)`` of every estimator that has not diverged."""
        return [(tr.name, tr.estimator) for tr in self.tracks if tr.diverged_at is None]

    # ------------------------------------------------------------------------------------------
    # the steps of a block: recorded with the co-simulation, filtered estimator by estimator

    def on_step(self, k: int, view: StepView) -> None:
        """At ``k = 0`` build the estimators and give their initial state; after that record
        step ``k``'s inputs (controls held over it, measurements, truth) and filter the block
        when it is full, at a sync step or at the end of a row group of the log."""
        if k == 0:
            self._start(view.t, view.signals(self.truth_slots))
            self._emit(0, *self.current())
            return
        meas = view.measurement()
        self._pending.append(_Step(k, view.t, view.dt, view.signals(self.control_slots),
                                   meas.z.copy(), meas.received.copy(),
                                   view.signals(self.truth_slots)))
        # the log's row k is step k (row 0: the start): a row group ends after row k when
        # (k + 1) is a multiple of its size; the block ends with it, so that every row group
        # written (and kept after a kill) has its estimates
        sync = (self._row_group > 0 and (k + 1) % self._row_group == 0) or k in self.sync_steps
        if sync or len(self._pending) >= self.block:
            self.flush()

    def _emit(self, k: int, values: np.ndarray, diverged: list[bool]) -> None:
        if self.sink is not None:
            self.sink(k, values, diverged)

    def flush(self) -> None:
        """Run every estimator through the recorded steps (one estimator after the other: each
        keeps its data in cache for the whole block), then check them step by step as one
        batch (:meth:`uwcosim.run.divergence.DivergenceCheck.assess`) and hand each step's
        estimates to the sink."""
        steps, self._pending = self._pending, []
        if not steps:
            return
        self.busy = True
        try:
            self._filter(steps)
        finally:
            self.busy = False

    def discard(self) -> None:
        """Forget the recorded steps not filtered yet (a run that failed: their rows are
        written with NaN estimates)."""
        self._pending = []

    def _filter(self, steps: list[_Step]) -> None:
        k, n = len(steps), self.model.nx
        active = [tr for tr in self.tracks if tr.diverged_at is None]
        X = np.full((len(active), k, n), np.nan)
        Ps = np.full((len(active), k, n, n), np.nan)
        nis = np.full((len(active), k), np.nan)
        done = np.zeros(len(active), dtype=np.intp)  # steps each estimator completed
        failed: dict[int, str] = {}  # estimator -> FilterDivergence at step done[a]
        base = [len(tr.step_times) for tr in active]
        xshape, pshape = (n,), (n, n)
        for a, tr in enumerate(active):
            est = tr.estimator
            # ours: one call per step (the compiled Kalman filters fuse predict and update);
            # the policy does not depend on the estimator, so it may come first
            whole = isinstance(est, Estimator)
            for j, st in enumerate(steps):
                t0 = time.perf_counter()
                try:
                    if whole:
                        z_in, mask = tr.policy(st.t, st.z, st.received & tr.use)
                        mask = np.asarray(mask, dtype=bool) & tr.use
                        est.step(st.u, st.dt, z_in if mask.any() else None, mask, st.t)
                    else:
                        est.predict(st.u, st.dt)
                        est.t = st.t
                        z_in, mask = tr.policy(st.t, st.z, st.received & tr.use)
                        mask = np.asarray(mask, dtype=bool) & tr.use
                        est.update(z_in if mask.any() else None, mask)
                    try:
                        shaped = est.x.shape == xshape and est.P.shape == pshape
                    except AttributeError:  # not arrays: the slow check below words it
                        shaped = False
                    if not shaped and shape_problem(est, n):
                        raise _BadShape(shape_problem(est, n))
                except FilterDivergence as exc:
                    tr.step_times.append(time.perf_counter() - t0)
                    failed[a] = str(exc)
                    break
                except SystemError as exc:  # Ctrl-C while a compiled (Numba) kernel returned
                    if interrupted(exc):
                        raise KeyboardInterrupt from None
                    raise
                except _BadShape as exc:
                    tr.step_times.append(time.perf_counter() - t0)
                    failed[a] = str(exc)
                    break
                except Exception as exc:  # noqa: BLE001 - the estimator's code failed: stop it
                    tr.step_times.append(time.perf_counter() - t0)
                    failed[a] = describe_error(exc)
                    break
                tr.step_times.append(time.perf_counter() - t0)
                X[a, j] = est.x
                Ps[a, j] = est.P
                nis[a, j] = _nis(est)
                done[a] = j + 1
        for j, st in enumerate(steps):
            live = []
            for a, tr in enumerate(active):
                if tr.diverged_at is not None:
                    continue
                if done[a] > j:
                    live.append(a)
                elif a in failed:  # raised at this step
                    self._stop(tr, st, failed.pop(a))
            if live:
                whys, nees = self.check.assess(X[live, j], Ps[live, j],
                                               st.truth - X[live, j], nis[live, j])
                for a, why, v in zip(live, whys, nees.tolist(), strict=True):
                    tr = active[a]
                    tr.nees = v
                    if why:  # diverged here: the steps it went on with are not its results
                        self._stop(tr, st, why)
                        del tr.step_times[base[a] + j + 1:]
            self._emit(st.k, *self._row(active, X[:, j], Ps[:, j], nis[:, j]))

    @staticmethod
    def _stop(tr: Track, st: _Step, why: str) -> None:
        """Stop and flag ``tr`` at step ``st`` for ``why``, in one warning line."""
        tr.diverged_at, tr.error, tr.nees, tr.stopped_step = st.t, why, float("nan"), st.k
        log.warning("estimator %r (%s) stopped at step %d (t=%g s): %s; the other estimators "
                    "and the log go on", tr.name, tr.type, st.k, st.t, why)

    def _row(self, active: list[Track], X, Ps, nis) -> tuple[np.ndarray, list[bool]]:
        """One step's log values of every estimator (its :class:`EstimateBlock`: ``x``,
        ``diag P``, NIS, NEES; NaN once diverged) and its diverged flags."""
        blk = self._layout
        vals = np.full((len(self.tracks), blk.width), np.nan)
        where = {id(tr): a for a, tr in enumerate(active)}
        for i, tr in enumerate(self.tracks):
            a = where.get(id(tr))
            if a is not None and tr.diverged_at is None:
                vals[i, blk.mean] = X[a]
                vals[i, blk.var] = np.diagonal(Ps[a])
                vals[i, blk.nis] = nis[a]
                vals[i, blk.nees] = tr.nees
        return vals.ravel(), [tr.diverged_at is not None for tr in self.tracks]

    def current(self) -> tuple[np.ndarray, list[bool]]:
        """The log values of the estimators' current state (the row at the start time)."""
        live = [tr for tr in self.tracks if tr.diverged_at is None]
        X = np.array([tr.estimator.x for tr in live], dtype=float)
        Ps = np.array([tr.estimator.P for tr in live], dtype=float)
        nis = np.array([_nis(tr.estimator) for tr in live])
        return self._row(live, X, Ps, nis)


class _BadShape(Exception):
    """An estimator's ``x`` or ``P`` has the wrong shape after a step."""


def _nis(est: Estimator) -> float:
    """The NIS of the estimator's last step (NaN when it has none or no ``diagnostics``)."""
    diagnostics = getattr(est, "diagnostics", None)
    return diagnostics.get("nis", np.nan) if diagnostics is not None else np.nan


def shape_problem(est: Estimator, nx: int) -> str:
    """What is wrong with the shapes of ``est.x`` (``(nx,)``) and ``est.P`` (``(nx, nx)``),
    or an empty string."""
    out = []
    for attr, want in (("x", (nx,)), ("P", (nx, nx))):
        try:
            got = np.shape(getattr(est, attr))
        except AttributeError:
            out.append(f"it has no {attr}")
            continue
        except ValueError:  # a ragged sequence
            got = "ragged"
        if got != want:
            out.append(f"{attr} has shape {got}, expected {want}")
    return "; ".join(out)
