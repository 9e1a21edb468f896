"""Accuracy, consistency and timing metrics of estimators: pure numpy functions.

Arrays are time first: a run's errors are ``(T, d)``, covariances ``(T, n, n)``, per-step scalars
``(T,)``; Monte Carlo stacks put the run axis second (``(T, M, d)``, ``(T, M)``). NaN marks a step
without a value (no update, a diverged filter) and is left out.

- RMSE of one run, seed 000 eq. (56) with ``ST = 1``: ``sqrt(mean_k e_k^2)`` per axis, and the
  combined (Euclidean) ``sqrt(mean_k |e_k|^2)`` over the position (or velocity) axes; over ``ST``
  runs eq. (56) averages the runs' RMSEs (:func:`mean_over_runs`). :func:`rmse_per_step` is the
  per-time RMSE over runs (seed 001 eq. 43 for one run, Huang et al. 2018).
- NEES ``e' P^-1 e`` (LU solves; also the estimator bank's per-step NEES) and NIS
  with two-sided chi-square bounds (:func:`chi2_band`): the mean of ``M`` independent
  ``chi2(d)`` values lies in ``chi2.ppf([a/2, 1 - a/2], M d) / M`` with probability
  ``1 - a``. ANEES is the mean NEES over runs (per step) or over runs and time; divided by
  ``n`` it is 1 for a consistent filter.
- Time per step: median and 95th percentile.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import gammaincinv

from uwcosim.models.states import position_velocity_indices


def rmse(err: np.ndarray) -> np.ndarray:
    """Per-component RMSE over time (axis 0), ignoring NaN steps: ``sqrt(mean_k e_k^2)``
    (NaN for a component with no finite step, e.g. a filter that diverged at once)."""
    sq = np.asarray(err, dtype=float) ** 2
    n = np.sum(~np.isnan(sq), axis=0)
    total = np.nansum(sq, axis=0)
    return np.sqrt(np.divide(total, n, out=np.full(np.shape(total), np.nan), where=n > 0))


def rmse_combined(err: np.ndarray) -> float:
    """Euclidean RMSE over time, ``sqrt(mean_k sum_j e_kj^2)``; steps with any NaN left out."""
    err = np.asarray(err, dtype=float)
    err = err.reshape(err.shape[0], -1)
    ok = np.all(np.isfinite(err), axis=1)
    if not ok.any():
        return float("nan")
    return float(np.sqrt(np.mean(np.sum(err[ok] ** 2, axis=1))))


#: per-axis RMSE keys: (label, unit, axis names), the same for every model (``px``/``py`` of a
#: CV model are the ``x``/``y`` axes)
RMSE_KEYS = (("position", "m", ("x", "y")), ("velocity", "mps", ("vx", "vy")))


def run_rmse(x_true: np.ndarray, x_est: np.ndarray,
             state_names: Sequence[str]) -> dict[str, float]:
    """Position and velocity RMSE of one run, combined and per axis (seed 000 eq. 56, ST = 1):
    ``rmse_position_m``, ``rmse_x_m``, ``rmse_y_m``, ``rmse_velocity_mps``, ``rmse_vx_mps``,
    ``rmse_vy_mps`` (the keys of ``summary.json`` and of a campaign's tables)."""
    err = np.asarray(x_est, dtype=float) - np.asarray(x_true, dtype=float)
    out: dict[str, float] = {}
    for (label, unit, axes), idx in zip(RMSE_KEYS, position_velocity_indices(state_names)):
        if not idx:
            continue
        out[f"rmse_{label}_{unit}"] = rmse_combined(err[:, idx])
        for ax, r in zip(axes, rmse(err[:, idx])):
            out[f"rmse_{ax}_{unit}"] = float(r)
    return out


def mean_over_runs(values: ArrayLike) -> float:
    """Seed 000 eq. (56): the average of the runs' RMSEs, ``(1/ST) sum_i RMSE_i``."""
    v = np.asarray(values, dtype=float)
    return float(np.nanmean(v))


def rmse_per_step(err_runs: np.ndarray) -> np.ndarray:
    """Per-step RMSE over runs, ``sqrt(mean_runs |e_k|^2)``, from errors ``(T, M, d)``."""
    e = np.asarray(err_runs, dtype=float)
    return np.sqrt(np.nanmean(np.sum(e**2, axis=2), axis=1))


def nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``e_k' P_k^-1 e_k`` per step from ``(T, n)`` errors and ``(T, n, n)`` covariances.

    Batched LU solves (``numpy.linalg.solve``). A step with a NaN, or whose ``P`` is singular,
    gives NaN; a ``P`` that is not positive definite gives its quadratic form, which may be
    negative (the estimator bank's divergence check flags a negative NEES).
    """
    err = np.asarray(err, dtype=float)
    P = np.asarray(P, dtype=float)
    out = np.full(err.shape[0], np.nan)
    ok = np.all(np.isfinite(err), axis=1) & np.all(np.isfinite(P), axis=(1, 2))
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return out
    e = err[idx]
    try:
        y = np.linalg.solve(P[idx], e[..., None])[..., 0]
    except np.linalg.LinAlgError:  # some step is singular: step by step
        for k in idx:
            try:
                out[k] = err[k] @ np.linalg.solve(P[k], err[k])
            except np.linalg.LinAlgError:
                continue
        return out
    # one step (the estimator bank's call): the dot product, bit for bit ``e @ solve(P, e)``
    out[idx] = e[0] @ y[0] if idx.size == 1 else np.einsum("ki,ki->k", e, y)
    return out


def chi2_ppf(q: ArrayLike, dof: ArrayLike) -> np.ndarray:
    """Quantile of the chi-square distribution, ``2 P^-1(dof/2, q)`` (scipy.special: importing
    scipy.stats costs most of a second at start-up)."""
    return 2.0 * gammaincinv(np.asarray(dof, dtype=float) / 2.0, q)


def chi2_band(dof: ArrayLike, n: int = 1, p: float = 0.95) -> tuple[float, float]:
    """Two-sided ``p`` bounds of the mean of ``n`` independent ``chi2(dof)`` values."""
    a = 0.5 * (1.0 - p)
    lo, hi = chi2_ppf(np.array([a, 1.0 - a]), np.asarray(dof, dtype=float) * n)
    return float(lo / n), float(hi / n)


def anees(nees_runs: np.ndarray, dof: int, p: float = 0.95) -> dict:
    """ANEES of ``M`` Monte Carlo runs from NEES values ``(T, M)``.

    Returns the per-step ANEES (mean over runs), its chi-square band (``M dof`` degrees of
    freedom), the fraction of steps inside it, and the overall mean over runs and time with its
    band (``T M dof`` degrees of freedom: assumes independence over time, so it is a tight
    check) and the normalized ANEES (overall / dof, 1 when consistent).
    """
    v = np.asarray(nees_runs, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    per_step = np.nanmean(v, axis=1)
    m = int(np.max(np.sum(np.isfinite(v), axis=1)))
    lo, hi = chi2_band(dof, m, p)
    inside = (per_step >= lo) & (per_step <= hi)
    count = int(np.sum(np.isfinite(v)))
    overall = float(np.nanmean(v))
    olo, ohi = chi2_band(dof, count, p)
    return {
        "per_step": per_step, "band": (lo, hi), "fraction_inside": float(np.mean(inside)),
        "overall": overall, "overall_band": (olo, ohi), "normalized": overall / dof,
    }


def nis_consistency(nis: np.ndarray, dof: np.ndarray, p: float = 0.95) -> dict:
    """NIS check of one run: the fraction of updates whose NIS lies in its own ``chi2(dof)``
    band, the mean NIS per degree of freedom, and the band of the total
    (``sum NIS ~ chi2(sum dof)``). Steps with NaN (no update) are left out."""
    nis = np.asarray(nis, dtype=float)
    dof = np.asarray(dof, dtype=float)
    ok = np.isfinite(nis) & np.isfinite(dof) & (dof > 0)
    if not ok.any():
        return {"fraction_inside": float("nan"), "mean_per_dof": float("nan"),
                "total_band_per_dof": (float("nan"), float("nan"))}
    a = 0.5 * (1.0 - p)
    lo = chi2_ppf(a, dof[ok])
    hi = chi2_ppf(1.0 - a, dof[ok])
    total = float(dof[ok].sum())
    tlo, thi = chi2_ppf(np.array([a, 1.0 - a]), total) / total
    return {
        "fraction_inside": float(np.mean((nis[ok] >= lo) & (nis[ok] <= hi))),
        "mean_per_dof": float(nis[ok].sum() / total),
        "total_band_per_dof": (float(tlo), float(thi)),
    }


def step_time_stats(times: ArrayLike) -> dict[str, float]:
    """Median, 95th percentile and mean of per-step wall times (seconds)."""
    t = np.asarray(times, dtype=float)
    t = t[np.isfinite(t)]
    if t.size == 0:
        return {"median_s": float("nan"), "p95_s": float("nan"), "mean_s": float("nan")}
    return {"median_s": float(np.median(t)), "p95_s": float(np.percentile(t, 95)),
            "mean_s": float(np.mean(t))}
