"""The posterior Cramér-Rao bound (uwcosim.evaluation.pcrb, uwcosim.run.bound): equal to the
Kalman filter's covariance for linear-Gaussian systems, below every filter's error, and with
lost measurements as realised."""

from __future__ import annotations

import json

import numpy as np
import pytest

from uwcosim.core.errors import UwcosimError
from uwcosim.evaluation.pcrb import GENERAL_FORM, Recursion, measurement_information, pcrb
from uwcosim.run.bound import record_truth, scenario_bound, truth_model, truth_seeds
from uwcosim.run.factory import scenario_map
from uwcosim.run.simulate import simulate
from uwcosim.runlog import columns, read_log


def _kf_covariances(P0, F, Q, H, R, masks):
    """The Kalman filter's covariance (Joseph form), skipping the lost rows."""
    P = P0.copy()
    out = [P]
    n = P.shape[0]
    for Fk, Qk, m in zip(F, Q, masks):
        P = Fk @ P @ Fk.T + Qk
        if m.any():
            Hm, Rm = H[m], R[np.ix_(m, m)]
            S = Hm @ P @ Hm.T + Rm
            K = P @ Hm.T @ np.linalg.inv(S)
            IKH = np.eye(n) - K @ Hm
            P = IKH @ P @ IKH.T + K @ Rm @ K.T
        out.append(P)
    return np.array(out)


def _linear_system(rng, K=200, n=4, nz=3):
    A = np.eye(n) + 0.1 * rng.standard_normal((n, n))
    L = rng.standard_normal((n, 2))
    F = np.repeat(A[None], K, axis=0)
    Q = np.repeat((0.01 * L @ L.T)[None], K, axis=0)  # rank 2: singular process noise
    H = rng.standard_normal((nz, n))
    B = rng.standard_normal((nz, nz))
    R = B @ B.T + 0.5 * np.eye(nz)  # a full (not diagonal) R
    masks = rng.random((K, nz)) > 0.3
    return A, F, Q, H, R, masks


def test_linear_gaussian_bound_is_the_kalman_covariance():
    """Linear-Gaussian, singular Q, full R, intermittent rows: PCRB = KF covariance to 1e-9."""
    rng = np.random.default_rng(3)
    _, F, Q, H, R, masks = _linear_system(rng)
    P0 = np.diag([4.0, 1.0, 2.0, 0.5])
    N = 3  # three identical runs: the expectations are the values themselves
    info = np.array([measurement_information(np.repeat(H[None], N, 0), R,
                                             np.repeat(m[None], N, 0)) for m in masks])
    b = pcrb(P0, np.repeat(F[:, None], N, 1), np.repeat(Q[:, None], N, 1), info)
    kf = _kf_covariances(P0, F, Q, H, R, masks)
    assert set(b.forms) == {"covariance"}
    assert np.max(np.abs(b.P - kf)) <= 1e-9 * np.max(np.abs(kf))


def test_general_form_equals_the_covariance_form_for_nonsingular_q():
    rng = np.random.default_rng(5)
    _, F, Q, H, R, masks = _linear_system(rng, K=100)
    Q = Q + 0.02 * np.eye(4)
    P0 = np.eye(4)
    a, g = Recursion(P0), Recursion(P0, form=GENERAL_FORM)
    for k in range(len(F)):
        info = measurement_information(H[None], R, masks[k][None])
        Pa, Pg = a.step(F[k][None], Q[k][None], info), g.step(F[k][None], Q[k][None], info)
        assert np.max(np.abs(Pa - Pg)) <= 1e-9 * np.max(np.abs(Pa))
    assert set(g.forms) == {GENERAL_FORM}


def test_general_form_refuses_a_singular_q():
    rng = np.random.default_rng(7)
    _, F, Q, H, R, masks = _linear_system(rng, K=2)
    F2 = np.stack([F[0], 1.01 * F[0]])  # F differs between two runs: the general form
    with pytest.raises(UwcosimError, match="singular"):
        Recursion(np.eye(4)).step(F2, np.stack([Q[0], Q[0]]), np.zeros((4, 4)))


def test_lost_rows_have_no_information():
    H = np.array([[[1.0, 2.0], [3.0, 4.0]], [[1.0, 2.0], [3.0, 4.0]]])
    R = np.diag([1.0, 4.0])
    got = measurement_information(H, R, np.array([[True, False], [False, False]]))
    assert np.allclose(got, 0.5 * np.outer([1.0, 2.0], [1.0, 2.0]))


def test_truth_seeds_are_the_campaign_seeds():
    from uwcosim.campaign.spec import run_seed

    assert truth_seeds(2021, 5) == [run_seed(2021, i) for i in range(5)]


def _bound_scenario(tan, name, extra=()):
    return tan(["run.duration=100", "evaluation.bound={runs=2}", *extra], name=name)


def test_without_terrain_the_bound_is_the_ekf_covariance(tan, tmp_path):
    """Dead reckoning (DVL only, linear in the state): the log's bound.STATE^2 equals the
    EKF's variances to 1e-9; summary.json has bound.position_m and each RMSE/bound."""
    loaded = _bound_scenario(tan, "tan_dead_reckoning.toml",
                             ['estimators={ekf={type="ekf"}, ukf={type="ukf"}}'])
    simulate(loaded, tmp_path / "run")
    cols, meta = read_log(tmp_path / "run" / "log.parquet")
    for s in ("x", "y", "vx", "vy"):
        b2, var = cols[columns.bound(s)] ** 2, cols[columns.variance("ekf", s)]
        assert np.max(np.abs(b2 - var)) <= 1e-9 * np.max(var), s
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["bound"]["runs"] == 2 and summary["bound"]["position_m"] > 0
    m = summary["estimators"]["ekf"]
    assert m["rmse_position_to_bound"] == pytest.approx(
        m["rmse_position_m"] / summary["bound"]["position_m"])
    assert meta["bound"]["forms"] == {"covariance": 100}


def test_no_bound_columns_without_the_key(tan, tmp_path):
    loaded = tan(["run.duration=5", 'estimators={ekf={type="ekf"}}'])
    simulate(loaded, tmp_path / "run")
    cols, meta = read_log(tmp_path / "run" / "log.parquet")
    assert not columns.bound_states_in(cols) and "bound" not in meta
    assert "bound" not in json.loads((tmp_path / "run" / "summary.json").read_text())


def test_no_filter_beats_the_bound_beyond_its_monte_carlo_error(tan, tmp_path):
    """Terrain, 300 s, 8 runs: each filter's mean squared position error over the runs and
    steps is at least the bound's (within 3 standard errors of its Monte Carlo mean)."""
    runs = 8
    loaded = tan(["run.duration=300", 'estimators={ekf={type="ekf"}, ukf={type="ukf"}, '
                  'pf={type="pf", n_particles=500}, point_mass={type="point_mass"}}'])
    b = scenario_bound(loaded, runs, seed=11)
    b2 = float(np.mean(b.position[1:] ** 2))
    mse = {}
    for i, seed in enumerate(truth_seeds(11, runs)):
        out = simulate(loaded, tmp_path / f"r{i}", seed=seed, evaluate=False)
        cols, _ = read_log(out / "log.parquet")
        for e in ("ekf", "ukf", "pf", "point_mass"):
            err2 = sum((cols[columns.estimate(e, s)] - cols[f"vehicle.{s}"]) ** 2
                       for s in ("x", "y"))
            mse.setdefault(e, []).append(float(np.mean(err2[1:])))
    for e, m in mse.items():
        m = np.array(m)
        assert m.mean() + 3 * m.std(ddof=1) / np.sqrt(runs) >= b2, (e, m.mean(), b2)


def test_lost_measurements_bound_as_realised(tan, tmp_path):
    """Seed 001's losses: the truth runs' received flags are the run's; the bound given the
    run's loss pattern is the covariance of the KF that skips lost updates (to 1e-9); the
    pooled bound is below it, and losses raise the bound."""
    loaded = tan(["run.duration=100", "sensors.gps.loss.p=0.3"], name="lost_measurements.toml")
    out = simulate(loaded, tmp_path / "run", seed=truth_seeds(4, 1)[0])
    cols, _ = read_log(out / "log.parquet")
    model = truth_model(loaded, scenario_map(loaded))
    truth = record_truth(loaded, truth_seeds(4, 1), model.measurement_names, {})
    for j, name in enumerate(model.measurement_names):
        assert np.array_equal(truth.received[0, :, j], cols[columns.received(name)][1:])
    assert 0 < truth.received.mean() < 1
    given = scenario_bound(loaded, 1, seed=4, per_run=True)
    for j, s in enumerate(model.state_names):
        var = cols[columns.variance("kf_skip", s)]
        assert np.max(np.abs(given.std[:, j] ** 2 - var)) <= 1e-9 * np.max(var), s
    pooled = scenario_bound(loaded, 6, seed=4)
    per_run = scenario_bound(loaded, 6, seed=4, per_run=True)
    lossless = scenario_bound(tan(["run.duration=100", "sensors.gps.loss.p=0.0"],
                                  name="lost_measurements.toml"), 6, seed=4)
    assert np.all(pooled.std <= per_run.std * (1 + 1e-12))
    assert np.all(lossless.std[1:] < pooled.std[1:])


def test_campaign_evaluation_bound(project_fmus, tmp_path):
    """``[evaluation] bound`` in a campaign spec: each variant's bound over the campaign's own
    runs (its seeds), in ``bound/VARIANT`` and in report.md beside each estimator."""
    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.driver import run_campaign
    from uwcosim.run.bound import BOUND_SUMMARY_FILE
    from uwcosim.scenario import load_scenario

    scen = (project_fmus.parent / "scenarios" / "lost_measurements.toml").as_posix()
    spec = tmp_path / "c.toml"
    spec.write_text(f'name = "c"\nseed = 5\nruns = 3\n[evaluation]\nbound = {{}}\n'
                    f'[[variants]]\nname = "a0.3"\nscenario = "{scen}"\n'
                    f'set = ["run.duration=50", "sensors.gps.loss.p=0.3"]\n')
    campaign = load_campaign(spec)
    run_campaign(campaign, tmp_path / "out", workers=1, figures=False)
    got = json.loads((tmp_path / "out" / "bound" / "a0.3" / BOUND_SUMMARY_FILE).read_text())
    assert got["runs"] == 3 and got["seed"] == 5
    loaded = load_scenario(scen, ["run.duration=50", "sensors.gps.loss.p=0.3"])
    assert got["position_m"] == scenario_bound(loaded, 3, seed=5).position_m()
    report = (tmp_path / "out" / "report.md").read_text()
    assert "## The posterior Cramér-Rao bound" in report and "| a0.3 |" in report
    assert report.count("| a0.3 | ") >= 4 + 4  # the results table and the bound's rows



def test_the_bound_takes_the_truths_noise_not_the_filters(tan):
    """A mistuned ``model.q_psd`` changes the filters' model, not the bound's."""
    loaded = tan(["run.duration=20", "model.q_psd=[1.0, 1.0, 1.0, 1.0]"])
    model = truth_model(loaded, None)
    assert np.array_equal(model.q_psd, [0.05, 0.05, 1e-5, 1e-5])
    same = scenario_bound(tan(["run.duration=20"]), 2, seed=3)
    assert np.array_equal(scenario_bound(loaded, 2, seed=3).std, same.std)
