"""The run summary (``summary.json``), computed from the logged outputs.

Per estimator: position and velocity RMSE of the run (seed 000 eq. 56 with ST = 1: the root of
the time average of the squared error, over steps 1..K), per-axis RMSE, ANEES (time average of
the NEES divided by the state dimension; 1 for a consistent filter), the fraction of NIS values
inside their two-sided chi-square 95% band, the time per step (median and 95th percentile) and
the divergence flag. Timing: wall time in each FMU, in the master itself and per estimator.
A plain co-simulation run (no estimators) has an empty ``estimators``; a run an FMU stopped has
status ``terminated`` and ``termination`` ``{fmu, time_s, reason}``.
"""

from __future__ import annotations

import numpy as np

from uwcosim.evaluation.metrics import chi2_ppf, run_rmse
from uwcosim.runlog import read_log


def estimator_metrics(cols: dict, name: str, truth: list[str], states: list[str]) -> dict:
    """Metrics of estimator ``name`` from log columns (rows 1.. are the filtered steps)."""
    X = np.stack([cols[t] for t in truth], axis=1)[1:]
    E = np.stack([cols[f"est.{name}.{s}"] for s in states], axis=1)[1:]
    out = run_rmse(X, E, states)
    nees = cols[f"est.{name}.nees"][1:]
    nees = nees[np.isfinite(nees)]
    nx = len(states)
    out["anees"] = float(np.mean(nees) / nx) if nees.size else float("nan")
    if nees.size:
        lo, hi = chi2_ppf(np.array([0.025, 0.975]), nx)
        out["nees_in_95_band"] = float(np.mean((nees >= lo) & (nees <= hi)))
    nis = cols[f"est.{name}.nis"][1:]
    out["mean_nis"] = float(np.nanmean(nis)) if np.isfinite(nis).any() else float("nan")
    diverged = cols.get(f"est.{name}.diverged")
    out["diverged"] = bool(diverged is not None and diverged.any())
    if out["diverged"]:
        out["diverged_at_s"] = float(cols["time"][np.argmax(diverged)])
    return out


def summarize(master, bank, status: str, error: str, log_path) -> dict:
    summary = {
        "scenario": master.system.name, "seed": master.seed, "status": status, "error": error,
        "steps": master.k, "step_s": master.h, "estimators": {},
        "start_time_s": master.t0, "end_time_s": master.t,
        "timing": {k: round(v, 6) for k, v in master.timing().items()},
    }
    solvers = master.me_solvers()
    summary["fmus"] = {
        n.adapter.name: {"interface": n.adapter.interface, "fmi_version": n.adapter.md.fmiVersion,
                         "solver": solvers.get(n.adapter.name),
                         "period_steps": n.period, "time_s": round(n.time_s, 6)}
        for n in master.nodes}
    stop = master.terminated
    if stop is not None:
        summary["termination"] = {"fmu": stop.fmu, "time_s": stop.time, "reason": stop.reason}
        summary["end_time_s"] = max(master.t, stop.time)
    k = max(master.k, 1)
    summary["timing"]["master_overhead_per_step_s"] = master.master_time_s / k
    summary["timing"]["fmus_per_step_s"] = sum(n.time_s for n in master.nodes) / k
    if bank is None:
        return summary
    try:
        cols, _ = read_log(log_path)
    except Exception:  # noqa: BLE001 - no log written (failure before the first row)
        return summary
    if cols["time"].size < 2:
        return summary
    for tr in bank.tracks:
        m = estimator_metrics(cols, tr.name, list(master.spec.model.truth),
                              list(bank.model.state_names))
        times = np.asarray(tr.step_times)
        m["time_per_step_s"] = float(np.median(times)) if times.size else float("nan")
        m["time_per_step_p95_s"] = float(np.percentile(times, 95)) if times.size else float("nan")
        m["total_time_s"] = float(times.sum())
        if tr.error:
            m["error"] = tr.error
        summary["estimators"][tr.name] = m
    return summary
