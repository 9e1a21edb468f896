"""The PCRB of a scenario: truth runs through the master, then the recursion over them.

:func:`scenario_bound` (behind ``uwcosim bound`` and ``[evaluation] bound = { runs = N }``)
runs the scenario's truth side ``N`` times through the master (its FMUs, its map, the master's
seeded streams; no estimator) with the seeds :func:`truth_seeds` -- the seeds a campaign of
the same seed gives its runs, so that the bound of a campaign's variant is over that campaign's
own truth runs -- and records each run's true states, controls and which measurement components
were received at each step. The recursion (:mod:`uwcosim.evaluation.pcrb`) then takes, step by
step, the Jacobians ``F`` and covariances ``Q`` at each run's true state and ``E[H' R^-1 H]``
over the components each run received, from the *truth's* model: the scenario's filters'
model with the truth's noise (``model.q_psd`` dropped, so the process-noise PSDs are the
``[noise]`` sources the FMUs get, and ``R`` from the sensors' ``sigma``), the terrain gradient
entering through ``H``. The prior is ``[estimation] initial_std`` (the estimators' initial error
distribution): ``J(0) = diag(initial_std)^-2``.

The bound of every step is in :class:`ScenarioBound`: per state the root of the diagonal of
``J(k)^-1`` (the log's ``bound.STATE`` columns) and the position bound
``sqrt(trace of the position block)``; :meth:`ScenarioBound.position_m` is its root mean square
over steps 1..K, comparable with a run's position RMSE (``summary.json`` ``bound.position_m``).
Truth runs that end early (an FMU terminated) shorten the bound to the shortest run.

Lost measurements. By default the expectation ``E[H' R^-1 H]`` is over the truth runs with the
components each run actually received (its loss pattern as realised): the PCRB of the losses
as random, known to the estimator. ``per_run`` (``uwcosim bound --per-run``) instead runs the
recursion on each truth run alone (its own states and loss pattern) and averages the
covariances ``J_i(k)^-1`` over the runs: the bound conditioned on each run's loss pattern, which
is larger (Jensen: the mean of inverses is at least the inverse of the mean) and for a
linear-Gaussian system is exactly the covariance of the Kalman filter that skips the lost
updates, averaged over the runs. For a nonlinear model the per-run recursion is the
information filter along one trajectory, not a bound: use it for linear models.
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from uwcosim.core.errors import ScenarioError
from uwcosim.evaluation.pcrb import (
    Recursion,
    measurement_information,
    position_bound,
    time_average,
)
from uwcosim.master.master import Master
from uwcosim.master.observer import StepView
from uwcosim.models.states import position_velocity_indices
from uwcosim.run.factory import build_model, scenario_map
from uwcosim.runlog import columns
from uwcosim.runlog.rundir import MAP_FILE, write_json
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.system import to_system

__all__ = ["BOUND_FILE", "BOUND_SUMMARY_FILE", "ScenarioBound", "TruthRuns", "bound_runs",
           "scenario_bound", "truth_model", "truth_seeds", "write_bound"]

BOUND_FILE = "bound.parquet"
BOUND_SUMMARY_FILE = "bound.json"


def truth_seeds(seed: int, runs: int) -> list[int]:
    """The seeds of the ``runs`` truth runs: run ``i`` gets a SeedSequence of ``(seed, i)`` as
    a 32-bit integer, the seed a campaign with ``seed`` gives its run ``i``."""
    return [int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, i]).generate_state(1)[0])
            for i in range(runs)]


def bound_runs(loaded: LoadedScenario) -> int | None:
    """``[evaluation] bound.runs`` of a scenario (None: no bound)."""
    ev = loaded.spec.evaluation
    return ev.bound.runs if ev is not None and ev.bound is not None else None


@dataclass
class TruthRuns:
    """``N`` truth runs of ``K`` steps: times ``t`` ``(K + 1,)``, steps ``dt`` ``(K,)``, true
    states ``X`` ``(N, K + 1, n)``, controls ``U`` ``(N, K, nu)`` held over each step and the
    received measurement components ``received`` ``(N, K, nz)`` (in the model's order)."""

    seeds: list[int]
    t: np.ndarray
    dt: np.ndarray
    X: np.ndarray
    U: np.ndarray
    received: np.ndarray


class _TruthRecorder:
    """An observer of the master: the true state, controls and received flags of each step."""

    def __init__(self, truth: np.ndarray, controls: np.ndarray, components: np.ndarray) -> None:
        self.truth, self.controls, self.components = truth, controls, components
        self.t: list[float] = []
        self.dt: list[float] = []
        self.X: list[np.ndarray] = []
        self.U: list[np.ndarray] = []
        self.received: list[np.ndarray] = []

    def on_step(self, k: int, view: StepView) -> None:
        self.t.append(view.t)
        self.X.append(view.signals(self.truth).copy())
        if k == 0:
            return
        self.dt.append(view.dt)
        self.U.append(view.signals(self.controls).copy())  # held over the step, as the bank
        self.received.append(np.asarray(view.measurement().received)[self.components])


def truth_model(loaded: LoadedScenario, bathymetry):
    """The scenario's filters' model with the truth's noise: ``model.q_psd`` dropped, so its
    process noise is the ``[noise]`` sources' PSDs and ``R`` the sensors' ``sigma``."""
    spec = loaded.spec
    if spec.model.q_psd is None:
        return build_model(loaded, bathymetry)
    model = spec.model.model_copy(update={"q_psd": None})
    return build_model(dataclasses.replace(loaded, spec=spec.model_copy(update={"model": model})),
                       bathymetry)


def record_truth(loaded: LoadedScenario, seeds: Sequence[int], measurement_names: Sequence[str],
                 overrides: dict[str, dict], progress: Callable[[int], None] | None = None
                 ) -> TruthRuns:
    """The truth runs of ``seeds`` through one master (reset between runs)."""
    spec = loaded.spec
    master = Master(to_system(loaded), seed=seeds[0])
    try:
        truth = np.array([master.slot(s, "model.truth") for s in spec.model.truth], np.intp)
        controls = np.array([master.slots[f"controls.{c}"] for c in spec.model.controls],
                            np.intp)
        names = list(master.sensors.names)
        missing = [n for n in measurement_names if n not in names]
        if missing:
            raise ScenarioError(f"{loaded.path}: bound: the model's measurements "
                                f"{', '.join(missing)} are no sensor output")
        components = np.array([names.index(n) for n in measurement_names], np.intp)
        recs = []
        for i, seed in enumerate(seeds):
            master.reset(seed)
            rec = _TruthRecorder(truth, controls, components)
            master.observers.append(rec)
            master.initialize(overrides)
            master.run_until(master.t0 + master.n_steps * master.h)
            recs.append(rec)
            if progress is not None:
                progress(i + 1)
    finally:
        master.close()
    K = min(len(r.dt) for r in recs)  # a run an FMU stopped early shortens them all
    return TruthRuns(list(seeds), np.array(recs[0].t[:K + 1]), np.array(recs[0].dt[:K]),
                     np.stack([np.array(r.X[:K + 1]) for r in recs]),
                     np.stack([np.array(r.U[:K]).reshape(K, len(controls)) for r in recs]),
                     np.stack([np.array(r.received[:K], dtype=bool).reshape(K, -1)
                               for r in recs]))


@dataclass(frozen=True)
class ScenarioBound:
    """The PCRB of a scenario: ``std`` ``(K + 1, n)`` the bound on each state's RMSE per
    step (step 0: the prior), ``position`` ``(K + 1,)`` on the position error norm's."""

    t: np.ndarray
    states: tuple[str, ...]
    std: np.ndarray
    position: np.ndarray
    runs: int
    seed: int
    forms: dict[str, int]

    def position_m(self) -> float:
        """Root mean square of the position bound over steps 1..K (comparable with RMSE)."""
        return time_average(self.position)

    def summary(self) -> dict:
        """``summary.json``'s ``bound``: ``position_m``, the truth runs and their seed, the
        number of steps in each form of the recursion."""
        return {"position_m": self.position_m(), "runs": self.runs, "seed": self.seed,
                "steps": int(self.t.size - 1), "forms": dict(self.forms)}


def compute_bound(model, runs: TruthRuns, P0: np.ndarray, seed: int,
                  states: Sequence[str], per_run: bool = False) -> ScenarioBound:
    """The recursion over recorded truth runs with ``model``'s F, Q, H and R (``per_run``: on
    each run alone, the covariances averaged; module docstring)."""
    if per_run:
        parts = [compute_bound(model, TruthRuns([s], runs.t, runs.dt, runs.X[i:i + 1],
                                                runs.U[i:i + 1], runs.received[i:i + 1]),
                               P0, seed, states) for i, s in enumerate(runs.seeds)]
        var = np.mean([b.std**2 for b in parts], axis=0)  # mean over runs of diag J_i^-1
        std = np.sqrt(var)
        pos = position_velocity_indices(states)[0]
        forms = {"per-run " + f: sum(b.forms.get(f, 0) for b in parts) // len(parts)
                 for f in parts[0].forms}
        return ScenarioBound(runs.t, tuple(states), std,
                             position_bound(std, pos) if pos else np.full(len(std), np.nan),
                             len(parts), int(seed), forms)
    N, K1, n = runs.X.shape
    rec = Recursion(P0)
    P = np.empty((K1, n, n))
    P[0] = rec.P
    R = np.asarray(model.R, dtype=float)
    F = np.empty((N, n, n))
    Q = np.empty((N, n, n))
    H = np.empty((N, R.shape[0], n))
    for k in range(K1 - 1):
        dt = float(runs.dt[k])
        for i in range(N):
            x, u = runs.X[i, k], runs.U[i, k]
            F[i] = model.F(x, u, dt)  # at the true state before the step
            Q[i] = model.Q(x, u, dt)
            H[i] = model.H(runs.X[i, k + 1])  # at the true state after it
        P[k + 1] = rec.step(F, Q, measurement_information(H, R, runs.received[:, k]))
    std = np.sqrt(np.maximum(np.diagonal(P, axis1=1, axis2=2), 0.0))
    pos = position_velocity_indices(states)[0]
    position = position_bound(std, pos) if pos else np.full(K1, np.nan)
    forms = {f: rec.forms.count(f) for f in sorted(set(rec.forms))}
    return ScenarioBound(runs.t, tuple(states), std, position, N, int(seed), forms)


def scenario_bound(loaded: LoadedScenario, runs: int, seed: int | None = None,
                   work_dir: str | Path | None = None,
                   progress: Callable[[int], None] | None = None,
                   per_run: bool = False) -> ScenarioBound:
    """The PCRB of ``loaded`` over ``runs`` truth runs (seeds :func:`truth_seeds` of ``seed``,
    default the scenario's ``run.seed``). ``work_dir``: where the map file for the FMUs is
    written (default: a temporary folder); ``per_run``: the bound given each run's loss
    pattern (module docstring)."""
    spec = loaded.spec
    where = str(loaded.path)
    if spec.replay is not None:
        raise ScenarioError(f"{where}: bound: a replay scenario has no truth runs to compute "
                            f"the bound over")
    if spec.model is None:
        raise ScenarioError(f"{where}: bound: needs [model] (the truth's states and sensors)")
    if spec.estimation is None:
        raise ScenarioError(f"{where}: bound: needs [estimation] initial_std (the prior)")
    if runs < 1:
        raise ScenarioError(f"{where}: bound: runs must be at least 1 (got {runs})")
    seed = spec.run.seed if seed is None else int(seed)
    bathy = scenario_map(loaded)
    model = truth_model(loaded, bathy)
    std0 = np.asarray(spec.estimation.initial_std, dtype=float)
    if std0.shape != (model.nx,):
        raise ScenarioError(f"{where}: key 'estimation.initial_std': expected {model.nx} "
                            f"values (one per state), got {std0.size}")
    with tempfile.TemporaryDirectory(prefix="uwcosim-bound-") as tmp:
        folder = Path(work_dir) if work_dir is not None else Path(tmp)
        overrides: dict[str, dict] = {}
        if bathy is not None and spec.map.fmu_parameter:
            fmu, _, par = spec.map.fmu_parameter.partition(".")
            if fmu in spec.fmus:
                path = folder / MAP_FILE
                if not path.is_file():
                    bathy.write_coefficients(path)
                overrides[fmu] = {par: str(path)}
        truth = record_truth(loaded, truth_seeds(seed, runs), model.measurement_names,
                             overrides, progress)
    return compute_bound(model, truth, np.diag(std0**2), seed, model.state_names, per_run)


def write_bound(bound: ScenarioBound, out_dir: str | Path) -> Path:
    """``bound.parquet`` (``time``, ``bound.STATE`` per state, ``bound.position``) and
    ``bound.json`` (:meth:`ScenarioBound.summary`) in ``out_dir`` (created)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = {columns.TIME: bound.t}
    for j, s in enumerate(bound.states):
        data[columns.bound(s)] = bound.std[:, j]
    data[columns.bound_position()] = bound.position
    table = pa.table(data).replace_schema_metadata(
        {"uwcosim": json.dumps({"bound": bound.summary(), "states": list(bound.states)})})
    pq.write_table(table, out / BOUND_FILE)
    write_json(out / BOUND_SUMMARY_FILE, bound.summary())
    return out
