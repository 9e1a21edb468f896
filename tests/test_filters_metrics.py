"""Evaluation metrics: RMSE (seed 000 eq. 56), NEES/NIS with chi-square bounds, timing."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from uwcosim.evaluation.metrics import (
    anees,
    chi2_band,
    mean_over_runs,
    nees,
    nis_consistency,
    position_velocity_indices,
    rmse,
    rmse_combined,
    rmse_per_step,
    run_rmse,
    step_time_stats,
)


def test_state_indices_from_names():
    assert position_velocity_indices(("x", "y", "vx", "vy")) == ([0, 1], [2, 3])
    assert position_velocity_indices(("px", "vx", "py", "vy")) == ([0, 2], [1, 3])


def test_rmse_per_axis_and_combined():
    err = np.array([[3.0, 4.0], [0.0, 0.0], [np.nan, 1.0]])
    np.testing.assert_allclose(rmse(err), [np.sqrt(9 / 2), np.sqrt(17 / 3)], rtol=1e-12)
    # combined: sqrt(mean_k |e_k|^2) over steps without NaN: (25 + 0) / 2
    assert rmse_combined(err) == pytest.approx(np.sqrt(12.5), rel=1e-12)


def test_run_rmse_uses_state_names():
    T = 4
    truth = np.zeros((T, 4))
    est = np.tile([1.0, 0.5, 2.0, 0.1], (T, 1))  # CV order: px, vx, py, vy
    r = run_rmse(truth, est, ("px", "vx", "py", "vy"))
    assert r["rmse_position_m"] == pytest.approx(np.sqrt(5.0), rel=1e-12)
    assert r["rmse_x_m"] == pytest.approx(1.0) and r["rmse_y_m"] == pytest.approx(2.0)
    assert r["rmse_velocity_mps"] == pytest.approx(np.sqrt(0.26), rel=1e-12)
    assert r["rmse_vx_mps"] == pytest.approx(0.5) and r["rmse_vy_mps"] == pytest.approx(0.1)
    assert mean_over_runs([1.0, 2.0, np.nan]) == pytest.approx(1.5)
    e = np.zeros((3, 2, 2))
    e[:, 0, 0] = 2.0
    np.testing.assert_allclose(rmse_per_step(e), np.sqrt(2.0))


def test_nees_batched_and_per_step_nan_for_bad_steps():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((5, 3, 3))
    P = A @ A.transpose(0, 2, 1) + np.eye(3)
    e = rng.standard_normal((5, 3))
    ref = np.einsum("ki,kij,kj->k", e, np.linalg.inv(P), e)
    np.testing.assert_allclose(nees(e, P), ref, rtol=1e-10)
    for k in range(5):  # the estimator bank's per-step call: e @ solve(P, e), bit for bit
        assert nees(e[k:k + 1], P[k:k + 1])[0] == e[k] @ np.linalg.solve(P[k], e[k])
    P[1] = -np.eye(3)  # not a covariance: a negative NEES, which the divergence check flags
    P[2] = 0.0  # singular
    e[3, 0] = np.nan
    out = nees(e, P)
    assert out[1] == pytest.approx(-e[1] @ e[1]) and np.isnan(out[2]) and np.isnan(out[3])
    np.testing.assert_allclose(out[[0, 4]], ref[[0, 4]], rtol=1e-10)


def test_chi2_band_and_anees_coverage():
    lo, hi = chi2_band(4)
    assert (lo, hi) == pytest.approx(tuple(chi2.ppf([0.025, 0.975], 4)))
    lo, hi = chi2_band(4, n=100)
    assert (lo, hi) == pytest.approx(tuple(chi2.ppf([0.025, 0.975], 400) / 100))
    rng = np.random.default_rng(1)
    samples = rng.chisquare(4, size=(400, 100))  # consistent NEES: (T, M)
    res = anees(samples, dof=4)
    assert 0.9 < res["fraction_inside"] <= 1.0
    assert res["normalized"] == pytest.approx(1.0, abs=0.02)
    res = anees(2.0 * samples, dof=4)  # overconfident filter: twice the NEES
    assert res["fraction_inside"] < 0.05


def test_nis_consistency_with_varying_dof():
    rng = np.random.default_rng(2)
    dof = rng.integers(1, 4, 2000).astype(float)
    nis = rng.chisquare(dof)
    nis[::10] = np.nan  # steps without an update
    res = nis_consistency(nis, dof)
    assert res["fraction_inside"] == pytest.approx(0.95, abs=0.02)
    lo, hi = res["total_band_per_dof"]
    assert lo < res["mean_per_dof"] < hi


def test_step_time_stats():
    s = step_time_stats([1.0, 2.0, 3.0, 100.0, np.nan])
    assert s["median_s"] == 2.5 and s["p95_s"] == pytest.approx(85.45)
