"""Drives a scenario's estimators from the master, as a per-step hook.

At each communication step ``t_k -> t_{k+1}`` every estimator predicts with the control held
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
A block also ends at each density snapshot time (all estimators must be at the same step) and
with each row group of the log (a row group written, also one kept after a kill, has its
estimates). The log recorder writes the block's rows when the bank has filtered them.

A diverging estimator (:mod:`uwcosim.divergence`: non-finite state,
covariance not symmetric positive definite, negative NIS/NEES, position out of bounds) is
flagged and stopped; the others go on.

The scenario was validated when it was loaded (:mod:`uwcosim.scenario.validate`: sensors,
controls, filter types, policies and settings), so the bank trusts it.
"""

from __future__ import annotations

import time
from array import array
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from uwcosim.errors import FilterDivergence, ScenarioError
from uwcosim.filters import Estimator
from uwcosim.filters.grid.jit import interrupted
from uwcosim.master.sources import stream

if TYPE_CHECKING:
    from uwcosim.master.master import Master
    from uwcosim.models.casadi_model import CasadiModel
    from uwcosim.models.linear import LinearModel
    from uwcosim.models.tan import TANModel


@dataclass(frozen=True)
class _Step:
    """What the estimators need of one communication step ``t - h -> t``."""

    t: float
    h: float
    u: np.ndarray  # controls held over the step
    z: np.ndarray
    received: np.ndarray
    truth: np.ndarray


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
    step_times: array = field(default_factory=lambda: array("d"))  # 8 bytes per step


class EstimatorBank:
    """All estimators of a run, fed from the master's bus."""

    def __init__(self, master: Master, model: CasadiModel | LinearModel | TANModel, where: str,
                 map_extent: tuple[float, float, float, float] | None = None, block: int = 1,
                 sync_times: Sequence[float] = (), row_group: int = 0) -> None:
        from uwcosim.divergence import DivergenceCheck, default_bound
        from uwcosim.evaluation.metrics import position_velocity_indices
        from uwcosim.filters.policies import POLICIES
        from uwcosim.filters.settings import build
        from uwcosim.scenario.validate import validated_settings

        spec = master.spec
        self.model = model
        self.where = where
        self.block = max(int(block), 1)
        self._sync = sorted(float(t) for t in sync_times)
        self._row_group = int(row_group)  # the log's rows per row group: blocks end with them
        self._steps = 0
        self._pending: list[_Step] = []
        self.busy = False  # inside flush (the signal watcher must not filter then)
        #: per filtered step, in order: the log values of every estimator and its flags
        self.outputs: deque[tuple[np.ndarray, list[bool]]] = deque()
        mspec = spec.model
        self.truth_slots = np.array([master._slot(s, "model.truth") for s in mspec.truth])
        self.control_slots = np.array([master.slots[f"controls.{c}"] for c in mspec.controls],
                                      dtype=np.intp)
        sensor_of = master.sensors.sensor_of  # the model's sensors (System.measured)
        x_true0 = master.bus[self.truth_slots]
        est_common = spec.estimation
        bound = est_common.position_bound if est_common is not None else None
        if bound is None and map_extent is not None:
            bound = default_bound(map_extent)
        pos = position_velocity_indices(model.state_names)[0]
        self.check = DivergenceCheck(tuple(pos), tuple(bound) if bound is not None else None)
        init_rng = stream(master.seed, "initial-error")
        std0 = np.asarray(est_common.initial_std if est_common else np.ones(model.nx), float)
        err0 = init_rng.standard_normal(model.nx) * std0
        if est_common is not None and est_common.initial_error == "zero":
            err0[:] = 0.0
        self.tracks: list[Track] = []
        for ename, es in spec.estimators.items():
            std = np.asarray(es.initial_std, float) if es.initial_std else std0
            try:
                est = build(es.type, model, x_true0 + err0, np.diag(std**2),
                            validated_settings(es), rng=stream(master.seed, f"estimator:{ename}"))
            except (TypeError, ValueError) as exc:  # what needs the model (names, memory)
                raise ScenarioError(f"{where}: key 'estimators.{ename}': {exc}") from None
            except MemoryError:
                raise ScenarioError(f"{where}: key 'estimators.{ename}': not enough memory "
                                    f"for these settings") from None
            est.t = master.t0
            policy = POLICIES.get(es.policy)(model.nz)
            use_sensors = es.sensors if es.sensors is not None else list(mspec.sensors)
            use = np.array([s in use_sensors for s in sensor_of], dtype=bool)
            self.tracks.append(Track(ename, est, policy, use))

    # ------------------------------------------------------------------------------------------
    # the steps of a block: recorded with the co-simulation, filtered estimator by estimator

    def __call__(self, master: Master) -> None:
        """Record this step's inputs (controls held over it, measurements, truth); filter the
        block when it is full or the step reaches a sync time (the density snapshots)."""
        meas = master.measurement()
        self._pending.append(_Step(master.t, master.h, master.bus[self.control_slots],
                                   meas.z.copy(), meas.received.copy(),
                                   master.bus[self.truth_slots]))
        self._steps += 1
        # the log's row k is step k (row 0: the start): a row group ends after row k when
        # (k + 1) is a multiple of its size; the block ends with it, so that every row group
        # written (and kept after a kill) has its estimates
        sync = self._row_group > 0 and (self._steps + 1) % self._row_group == 0
        while self._sync and master.t + 1e-9 >= self._sync[0]:
            self._sync.pop(0)
            sync = True
        if sync or len(self._pending) >= self.block:
            self.flush()

    def flush(self) -> None:
        """Run every estimator through the recorded steps (one estimator after the other: each
        keeps its data in cache for the whole block), then check them step by step as one
        batch (:meth:`uwcosim.divergence.DivergenceCheck.assess`) and queue each step's outputs in
        :attr:`outputs`."""
        steps, self._pending = self._pending, []
        if not steps:
            return
        self.busy = True
        try:
            self._filter(steps)
        finally:
            self.busy = False

    def _filter(self, steps: list[_Step]) -> None:
        k, n = len(steps), self.model.nx
        active = [tr for tr in self.tracks if tr.diverged_at is None]
        X = np.full((len(active), k, n), np.nan)
        Ps = np.full((len(active), k, n, n), np.nan)
        nis = np.full((len(active), k), np.nan)
        done = np.zeros(len(active), dtype=np.intp)  # steps each estimator completed
        failed: dict[int, str] = {}  # estimator -> FilterDivergence at step done[a]
        base = [len(tr.step_times) for tr in active]
        for a, tr in enumerate(active):
            est = tr.estimator
            for j, st in enumerate(steps):
                t0 = time.perf_counter()
                try:
                    est.predict(st.u, st.h)
                    est.t = st.t
                    z_in, mask = tr.policy(st.t, st.z, st.received & tr.use)
                    mask = np.asarray(mask, dtype=bool) & tr.use
                    est.update(z_in if mask.any() else None, mask)
                except FilterDivergence as exc:
                    tr.step_times.append(time.perf_counter() - t0)
                    failed[a] = str(exc)
                    break
                except SystemError as exc:  # Ctrl-C while a compiled (Numba) kernel returned
                    if interrupted(exc):
                        raise KeyboardInterrupt from None
                    raise
                tr.step_times.append(time.perf_counter() - t0)
                X[a, j] = est.x
                Ps[a, j] = est.P
                nis[a, j] = est.diagnostics.get("nis", np.nan)
                done[a] = j + 1
        for j, st in enumerate(steps):
            live = []
            for a, tr in enumerate(active):
                if tr.diverged_at is not None:
                    continue
                if done[a] > j:
                    live.append(a)
                elif a in failed:  # raised at this step
                    tr.diverged_at, tr.error, tr.nees = st.t, failed.pop(a), float("nan")
            if live:
                whys, nees = self.check.assess(X[live, j], Ps[live, j],
                                               st.truth - X[live, j], nis[live, j])
                for a, why, v in zip(live, whys, nees.tolist(), strict=True):
                    tr = active[a]
                    tr.nees = v
                    if why:  # diverged here: the steps it went on with are not its results
                        tr.diverged_at, tr.error, tr.nees = st.t, why, float("nan")
                        del tr.step_times[base[a] + j + 1:]
            self.outputs.append(self._row(active, X[:, j], Ps[:, j], nis[:, j]))

    def _row(self, active: list[Track], X, Ps, nis) -> tuple[np.ndarray, list[bool]]:
        """One step's log values of every estimator ``[x, diag P, NIS, NEES]`` (NaN once
        diverged) and its diverged flags."""
        n = self.model.nx
        vals = np.full((len(self.tracks), 2 * n + 2), np.nan)
        where = {id(tr): a for a, tr in enumerate(active)}
        for i, tr in enumerate(self.tracks):
            a = where.get(id(tr))
            if a is not None and tr.diverged_at is None:
                vals[i, :n] = X[a]
                vals[i, n:2 * n] = np.diagonal(Ps[a])
                vals[i, 2 * n] = nis[a]
                vals[i, 2 * n + 1] = tr.nees
        return vals.ravel(), [tr.diverged_at is not None for tr in self.tracks]

    def current(self) -> tuple[np.ndarray, list[bool]]:
        """The log values of the estimators' current state (the row at the start time)."""
        live = [tr for tr in self.tracks if tr.diverged_at is None]
        X = np.array([tr.estimator.x for tr in live], dtype=float)
        Ps = np.array([tr.estimator.P for tr in live], dtype=float)
        nis = np.array([tr.estimator.diagnostics.get("nis", np.nan) for tr in live])
        return self._row(live, X, Ps, nis)
