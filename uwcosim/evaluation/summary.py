"""The evaluate stage: ``summary.json`` of a run, from the files of its run directory alone.

:func:`evaluate` reads ``log.parquet`` (or its journal after ``kill -9``) with its ``uwcosim``
metadata, and ``simulation.json`` (written by the simulate stage,
:func:`uwcosim.run.simulate.simulate`: status, error, termination, wall times, the estimators'
time per step and divergence reasons, notes). No scenario is loaded and no FMU is touched.

Per estimator: position and velocity RMSE of the run (seed 000 eq. 56 with ST = 1: the root of
the time average of the squared error, over steps 1..K), per-axis RMSE
(:func:`~uwcosim.evaluation.metrics.run_rmse`), ANEES (time average of the NEES divided by the
state dimension; 1 for a consistent filter), the fraction of NEES values inside their two-sided
chi-square 95% band, the mean NIS, the divergence flag, the lost-track flag
(:func:`~uwcosim.evaluation.trackloss.track_loss`: ``track_lost``, ``track_lost_at_s``; a
diverged filter has lost the track), and from ``simulation.json`` the time
per step (median, 95th percentile) and total. A plain co-simulation run (no estimators) has an
empty ``estimators``; a run an FMU stopped has status ``terminated`` and ``termination``
``{fmu, time_s, reason}``. A replay's reference may have values at some steps only (sparse
fixes): the metrics are then over the steps that have one, each estimator's
``reference_steps`` counts them and a note says so; a replay's ``simulation.json`` (and so its
summary) has ``replay``: the file, its rows and time stamps.

A run with ``[evaluation] bound`` (its log has ``bound.STATE`` columns) has ``bound``: the
posterior Cramér-Rao bound's ``position_m`` (root mean square over steps 1..K of the bound on
the position error norm, :mod:`uwcosim.evaluation.pcrb`), its truth runs, seed and recursion
forms; and each estimator ``rmse_position_to_bound``, its position RMSE over that bound.

Older runs: a log without the names of states, truth signals and estimators in its metadata has
them recovered from the column names and ``[model] truth`` of the logged scenario text; a run
directory without ``simulation.json`` takes status and timing from its ``summary.json`` (written
by older versions), or, without either (a run killed hard), has status ``unknown`` and no timing.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from uwcosim.core.errors import UwcosimError
from uwcosim.evaluation.metrics import chi2_ppf, run_rmse
from uwcosim.evaluation.pcrb import position_bound, time_average
from uwcosim.evaluation.trackloss import track_loss
from uwcosim.models.states import position_velocity_indices
from uwcosim.runlog import columns, read_log
from uwcosim.runlog.parquet import unfinished
from uwcosim.runlog.rundir import SIMULATION_FILE, read_json, write_json
from uwcosim.scenario.overrides import apply_override, parse_overrides

#: keys of a summary that come from the simulation (not from the log's metrics)
_ESTIMATOR_RUN_KEYS = ("time_per_step_s", "time_per_step_p95_s", "total_time_s", "error")


def estimator_metrics(cols: dict, name: str, truth: list[str], states: list[str]) -> dict:
    """Metrics of estimator ``name`` from log columns (rows 1.. are the filtered steps)."""
    X = np.stack([cols[t] for t in truth], axis=1)[1:]
    E = np.stack([cols[columns.estimate(name, s)] for s in states], axis=1)[1:]
    out = run_rmse(X, E, states)
    nees = cols[columns.nees(name)][1:]
    nees = nees[np.isfinite(nees)]
    nx = len(states)
    out["anees"] = float(np.mean(nees) / nx) if nees.size else float("nan")
    if nees.size:
        lo, hi = chi2_ppf(np.array([0.025, 0.975]), nx)
        out["nees_in_95_band"] = float(np.mean((nees >= lo) & (nees <= hi)))
    nis = cols[columns.nis(name)][1:]
    out["mean_nis"] = float(np.nanmean(nis)) if np.isfinite(nis).any() else float("nan")
    diverged = cols.get(columns.diverged(name))
    out["diverged"] = bool(diverged is not None and diverged.any())
    if out["diverged"]:
        out["diverged_at_s"] = float(cols["time"][np.argmax(diverged)])
    pos = position_velocity_indices(states)[0]
    if len(pos) == 2 and all(columns.variance(name, states[i]) in cols for i in pos):
        V = np.stack([cols[columns.variance(name, states[i])] for i in pos], axis=1)[1:]
        ref = np.all(np.isfinite(X[:, pos]), axis=1)  # steps with a position reference
        out.update(track_loss(cols["time"][1:][ref], (E[:, pos] - X[:, pos])[ref], V[ref]))
        out["track_lost"] = out["track_lost"] or out["diverged"]
    return out


def bound_metrics(cols: dict, meta: dict) -> dict | None:
    """``summary.json``'s ``bound`` from a log's ``bound.STATE`` columns (None without)."""
    states = columns.bound_states_in(cols)
    if not states:
        return None
    pos = position_velocity_indices(states)[0]
    std = np.stack([cols[columns.bound(s)] for s in states], axis=1)
    out = {**(meta.get("bound") or {})}
    out["position_m"] = time_average(position_bound(std, pos)) if pos else float("nan")
    return out


def _model_truth_from_text(meta: dict) -> list[str]:
    """``[model] truth`` of the logged scenario text with the logged overrides applied."""
    try:
        data = tomllib.loads(meta.get("scenario_text", ""))
        for keys, value in parse_overrides(meta.get("overrides", []), "log"):
            apply_override(data, keys, value, "log")
    except (tomllib.TOMLDecodeError, UwcosimError):
        return []
    truth = (data.get("model") or {}).get("truth") or []
    return [str(t) for t in truth]


def log_names(cols: dict, meta: dict) -> tuple[list[str], list[str], list[str], list[str]]:
    """``(estimators, states, truth signals, notes)`` of a log: from its metadata, or for an
    older log from the column names (``est.NAME.var.STATE``) and the logged scenario text. The
    truth is empty when some of its signals are not in the log (a note says which)."""
    names = columns.estimators_in(cols)
    states = columns.states_in(cols, names[0]) if names else []
    if "estimators" in meta:
        names = list(meta["estimators"])
    states = list(meta.get("states", states))
    truth = list(meta.get("truth", [])) or (_model_truth_from_text(meta) if names else [])
    notes = []
    if names and "truth" not in meta:
        notes.append("names of states and truth signals recovered from an older log's columns "
                     "and scenario text")
    missing = [c for c in truth if c not in cols]
    if missing:
        notes.append(f"truth signals not in the log: {', '.join(missing)}")
        truth = []
    return names, states, truth, notes


def _reference_notes(cols: dict, truth: list[str], states: list[str], meta: dict,
                     estimators: dict) -> list[str]:
    """When the truth has steps without a value (a replay's reference: sparse fixes, or none):
    each estimator's ``reference_steps`` (steps 1.. with a position reference) and a note
    saying over which steps the metrics are. Nothing for a full truth (every simulation)."""
    X = np.stack([cols[c] for c in truth], axis=1)[1:]
    have = np.isfinite(X)
    if have.all():
        return []
    pos = position_velocity_indices(states)[0]
    with_pos = int(np.all(have[:, pos], axis=1).sum()) if pos else int(have.all(axis=1).sum())
    for m in estimators.values():
        m["reference_steps"] = with_pos
    n = X.shape[0]
    src = f"the replay's reference ({meta['replay']['file']})" if "replay" in meta \
        else "the truth"
    if not have.any():
        return [f"{src} has no value at any step: no accuracy metrics (RMSE, NEES are NaN)"]
    lacking = [s for s, c in zip(states, have.T) if not c.any()]
    tail = f"; no reference for {', '.join(lacking)} (their RMSE is NaN)" if lacking else ""
    return [f"{src} has a position at {with_pos} of the {n} filtered steps: RMSE and NEES "
            f"are over the steps that have a reference (NEES: those with every state){tail}"]


def _without_metrics(summary: dict) -> dict:
    """What an older ``summary.json`` says about the simulation (its metrics are recomputed)."""
    out = dict(summary)
    out["estimators"] = {n: {k: v for k, v in m.items() if k in _ESTIMATOR_RUN_KEYS}
                         for n, m in (summary.get("estimators") or {}).items()}
    return out


def evaluate(run_dir: str | Path, out: str | Path | None = None, write: bool = True) -> dict:
    """The summary of the run in ``run_dir`` from its files alone; written to
    ``summary.json`` in ``out`` (default: the run directory) unless ``write`` is false.

    Raises :class:`~uwcosim.core.errors.UwcosimError` when ``run_dir`` holds neither a log nor a
    ``simulation.json``."""
    run_dir = Path(run_dir)
    log_path = run_dir / "log.parquet"
    sim = read_json(run_dir / SIMULATION_FILE)
    notes: list[str] = []
    if sim is None:
        old = read_json(run_dir / "summary.json")
        if old is not None:
            sim = _without_metrics(old)
    has_log = log_path.is_file() or unfinished(log_path)
    if sim is None and not has_log:
        raise UwcosimError(f"{run_dir}: not a run directory (no log.parquet, no "
                           f"{SIMULATION_FILE})")
    cols, meta = {}, {}
    if has_log:
        try:
            cols, meta = read_log(log_path)
        except UwcosimError:
            if sim is None:
                raise
    t = cols.get("time", np.zeros(0))
    if sim is None:
        step = float(meta.get("step", np.diff(t[:2])[0] if t.size > 1 else float("nan")))
        sim = {"scenario": meta.get("scenario_name",
                                    Path(meta.get("scenario_path", "?")).stem),
               "seed": meta.get("seed"), "status": "unknown", "error": "",
               "steps": max(int(t.size) - 1, 0), "step_s": step, "timing": {},
               "estimators": {}}
        notes.append(f"no {SIMULATION_FILE} or summary.json (a run killed hard?): status and "
                     f"timing unknown, metrics recomputed from the log")
    summary = dict(sim)
    run_info = summary.pop("estimators", None) or {}
    summary["estimators"] = {}
    names, states, truth, name_notes = log_names(cols, meta)
    notes += name_notes if names else []
    if t.size >= 2 and truth and states:
        for name in names:
            m = estimator_metrics(cols, name, truth, states)
            m.update(run_info.get(name, {}))
            summary["estimators"][name] = m
        notes += _reference_notes(cols, truth, states, meta, summary["estimators"])
    bound = bound_metrics(cols, meta)
    if bound is not None:
        summary["bound"] = bound
        for m in summary["estimators"].values():
            if "rmse_position_m" in m:
                m["rmse_position_to_bound"] = m["rmse_position_m"] / bound["position_m"]
    if notes:
        summary["notes"] = list(dict.fromkeys([*summary.get("notes", []), *notes]))
    if write:
        out = Path(out) if out is not None else run_dir
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / "summary.json", summary)
    return summary
