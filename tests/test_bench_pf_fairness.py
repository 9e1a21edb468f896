"""The particle-filter comparison of ``benchmarks/bench_filters.py`` is fair: our PF, Stone
Soup's and `particles`' start from the same cloud (drawn from ``N(x0, P0)``) and get the same
process noise ``Q``, measurement
likelihood (``R`` and the terrain function) and resampling rule (``PF_SETTINGS``). Checked on
what each filter really does (one step of each from the same cloud), not only on what it was
handed. The libraries are benchmark-only (``pip install -e .[bench]``): their tests skip when
one is missing."""

from __future__ import annotations

import datetime
import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
N = 20000  # particles for the sampled covariances: relative error about sqrt(2/N) = 1 %
TOL = 5.0 * np.sqrt(2.0 / N)  # of a whitened covariance's entries (5 standard errors)


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(BENCH))
    try:
        yield importlib.import_module("bench_filters")
    finally:
        sys.path.remove(str(BENCH))


@pytest.fixture(scope="module")
def problem(bench):
    """The benchmark's model, its first trajectory's prior mean and a cloud over it."""
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry

    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7))
    truth, zs, x0 = bench.simulate(model, 5)
    rng = np.random.default_rng(3)
    cloud = truth[0][:, None] + np.diag([20.0, 20.0, 0.05, 0.05]) @ rng.standard_normal((4, 500))
    return model, x0, zs, cloud


def assert_cov(samples: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> None:
    """``samples`` (nx, n) have ``mean`` and ``cov``: whitened by ``chol(cov)``, their mean is
    0 and their covariance the identity, within 5 standard errors."""
    L = np.linalg.cholesky(cov)
    W = np.linalg.solve(L, samples - mean[:, None])
    n = W.shape[1]
    np.testing.assert_allclose(W.mean(axis=1), 0.0, atol=5.0 / np.sqrt(n))
    np.testing.assert_allclose(np.cov(W), np.eye(cov.shape[0]), atol=5.0 * np.sqrt(2.0 / n))


def ours_weights(bench, model, x0, cloud, z):
    """Our PF's weights after one update of ``cloud`` (equal prior weights, no resampling)."""
    est = bench.ours_filter("pf", model, x0, {"n_particles": cloud.shape[1],
                                              "ess_threshold": 0.0})
    est.particles = cloud.copy()
    est.update(z)
    return est.weights


def softmax(ll: np.ndarray) -> np.ndarray:
    w = np.exp(ll - ll.max())
    return w / w.sum()


def test_ours_gets_the_shared_settings_prior_and_noise(bench, problem):
    model, x0, _, _ = problem
    est = bench.ours_filter("pf", model, x0, {"n_particles": N, **bench.PF_SETTINGS})
    s = est.settings
    assert (s.ess_threshold, s.resampling, s.roughening) == (0.5, "systematic", 0.0)
    assert bench.PF_SETTINGS == {"ess_threshold": 0.5, "resampling": "systematic",
                                 "roughening": 0.0}
    assert s.student_t_nu is None  # the Gaussian likelihood, as the libraries'
    cloud = bench.initial_cloud(x0, N)
    assert_cov(cloud, x0, np.diag(bench.STD0**2))  # the prior N(x0, P0)
    np.testing.assert_array_equal(est.particles, cloud)
    np.testing.assert_allclose(est.x, cloud.mean(axis=1), rtol=1e-12)  # the estimate's too
    u = bench.controls(0)
    x = est.x.copy()
    est.particles = np.repeat(x[:, None], N, axis=1)
    est.predict(u, 1.0)
    assert_cov(est.particles, model.f(x, u, 1.0), model.Q(x, u, 1.0))  # + N(0, Q) per step


def test_stonesoup_gets_the_same_prior_noise_likelihood_and_resampling(bench, problem):
    pytest.importorskip("stonesoup")
    from stonesoup.resampler.particle import ESSResampler, SystematicResampler
    from stonesoup.types.array import StateVector, StateVectors
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import ParticleState

    model, x0, zs, cloud = problem
    trans, meas = bench.stonesoup_models(model, bench.Terrain(model, "model"))
    state, predictor, updater = bench.stonesoup_pf(trans, meas, x0, N)
    assert isinstance(updater.resampler, ESSResampler)
    assert updater.resampler.threshold == 0.5 * N
    assert type(updater.resampler.resampler) is SystematicResampler
    assert updater.regulariser is None and updater.constraint_func is None  # no roughening
    np.testing.assert_array_equal(np.asarray(state.state_vector, dtype=float),
                                  bench.initial_cloud(x0, N))  # the shared cloud

    u = bench.controls(0)
    x = np.asarray(cloud[:, 0])
    same = ParticleState(StateVectors(np.repeat(x[:, None], N, axis=1)),
                         log_weight=np.full(N, -np.log(N)), timestamp=bench.T0)
    pred = predictor.predict(same, timestamp=bench.T0 + datetime.timedelta(seconds=1),
                             u=tuple(u))
    assert_cov(np.asarray(pred.state_vector, dtype=float), model.f(x, u, 1.0),
               model.Q(x, u, 1.0))

    det = Detection(StateVector(zs[0]), timestamp=bench.T0, measurement_model=meas)
    ll = meas.logpdf(det, ParticleState(StateVectors(cloud), timestamp=bench.T0))
    np.testing.assert_allclose(softmax(np.asarray(ll, dtype=float)),
                               ours_weights(bench, model, x0, cloud, zs[0]),
                               rtol=1e-9, atol=1e-15)


def test_particles_gets_the_same_prior_noise_likelihood_and_resampling(bench, problem):
    pytest.importorskip("particles")
    model, x0, zs, cloud = problem
    alg = bench.particles_smc(model, x0, bench.Terrain(model, "model"), zs, N)
    assert alg.ESSrmin == 0.5 and alg.resampling == "systematic"
    ssm = alg.fk.ssm
    # X_0: the shared cloud moved by the first step, f(cloud_i) + N(0, Q)
    u0 = bench.controls(0)
    cloud = bench.initial_cloud(x0, N)
    X0 = ssm.PX0().rvs(size=N).T
    moved = np.stack([model.f(c, u0, 1.0) for c in cloud.T[:5]], axis=1)
    np.testing.assert_allclose(ssm.PX0().loc[:5].T, moved, rtol=1e-12)
    assert_cov(X0 - np.stack([model.f(c, u0, 1.0) for c in cloud.T], axis=1) + x0[:, None],
               x0, model.Q(x0, u0, 1.0))
    u = bench.controls(1)
    x = np.asarray(cloud[:, 0])
    moved = ssm.PX(1, np.repeat(x[None, :], N, axis=0)).rvs(size=N).T
    assert_cov(moved, model.f(x, u, 1.0), model.Q(x, u, 1.0))
    ll = ssm.PY(0, None, cloud.T).logpdf(zs[0])
    np.testing.assert_allclose(softmax(np.asarray(ll, dtype=float)),
                               ours_weights(bench, model, x0, cloud, zs[0]),
                               rtol=1e-9, atol=1e-15)
