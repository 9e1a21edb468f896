"""Particle filter: resampling schemes, registry, randomness, convergence to the KF."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.filters import particle, sigma_point, variational  # noqa: F401  (register)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.kalman import KalmanFilter
from uwcosim.filters.particle import RESAMPLERS, ParticleFilter
from uwcosim.models.linear import constant_velocity_model

SCHEMES = ["systematic", "stratified", "residual", "multinomial"]
X0 = np.array([0.0, 1.0, 0.0, -0.5])
P0 = np.diag([4.0, 0.25, 4.0, 0.25])


def cv():
    return constant_velocity_model(
        q_psd=[0.02, 0.01, 0.02, 0.01], R=np.diag([2.0, 2.0, 0.1]),
        measurement_names=("gps.px_m", "gps.py_m", "dvl.vx_m"),
    )


@pytest.mark.parametrize("scheme", SCHEMES)
def test_resampling_preserves_expected_counts(scheme):
    rng = np.random.default_rng(7)
    w = rng.random(8) ** 3
    w /= w.sum()
    trials = 20000
    counts = np.empty((trials, w.size))
    res = RESAMPLERS.get(scheme)
    for i in range(trials):
        idx = res(w, rng)
        assert idx.size == w.size and idx.min() >= 0 and idx.max() < w.size
        counts[i] = np.bincount(idx, minlength=w.size)
    # unbiased: E[N_i] = N w_i; five standard errors of the 20000-trial mean (+ a floor for
    # the schemes whose counts are nearly deterministic)
    se = counts.std(axis=0) / np.sqrt(trials)
    np.testing.assert_array_less(np.abs(counts.mean(axis=0) - w.size * w), 5 * se + 1e-3)


@pytest.mark.parametrize("scheme", ["systematic", "residual"])
def test_low_variance_schemes_give_floor_or_ceiling_counts(scheme):
    rng = np.random.default_rng(3)
    w = rng.random(50)
    w /= w.sum()
    for _ in range(200):
        c = np.bincount(RESAMPLERS.get(scheme)(w, rng), minlength=50)
        lower = np.floor(50 * w)
        assert np.all(c >= lower)
        if scheme == "systematic":
            assert np.all(c <= np.ceil(50 * w))


def test_registry_lists_valid_names_on_a_typo():
    with pytest.raises(ScenarioError, match="multinomial, residual, stratified, systematic"):
        RESAMPLERS.get("sytematic")
    with pytest.raises(ScenarioError, match="s.toml.*sytematic.*systematic"):
        ESTIMATORS.get("pf").from_settings(cv(), X0, P0, {"resampling": "sytematic"},
                                           where="s.toml")


def test_seed_and_rng_make_runs_reproducible():
    model = cv()
    z = np.array([0.5, -0.2, 1.1])

    def run(**kw):
        pf = ParticleFilter(model, X0, P0, n_particles=200, **kw)
        for _ in range(5):
            pf.predict(None, 1.0)
            pf.update(z)
        return pf.x

    np.testing.assert_array_equal(run(seed=4), run(seed=4))
    np.testing.assert_array_equal(run(rng=np.random.default_rng(4)), run(seed=4))
    assert not np.array_equal(run(seed=4), run(seed=5))
    # seed wins over rng
    np.testing.assert_array_equal(run(seed=4, rng=np.random.default_rng(9)), run(seed=4))


def simulate(model, steps, seed):
    rng = np.random.default_rng(seed)
    x = X0 + np.linalg.cholesky(P0) @ rng.standard_normal(4)
    zs = []
    for _ in range(steps):
        x = model.f(x, None, 1.0) + np.linalg.cholesky(model.Q(x, None, 1.0)) @ \
            rng.standard_normal(4)
        zs.append(model.h(x) + np.sqrt(np.diag(model.R)) * rng.standard_normal(model.nz))
    return np.array(zs)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_pf_converges_to_kf_on_linear_gaussian_model(scheme):
    model = cv()
    zs = simulate(model, 10, seed=1)
    kf = KalmanFilter(model, X0, P0)
    pfs = {n: ParticleFilter(model, X0, P0, n_particles=n, resampling=scheme, seed=10)
           for n in (1000, 64000)}
    err = {n: [] for n in pfs}
    cov = {n: [] for n in pfs}
    for k in range(zs.shape[0]):
        for est in (kf, *pfs.values()):
            est.predict(None, 1.0)
            est.update(zs[k])
        sd = np.sqrt(np.diag(kf.P))
        for n, pf in pfs.items():
            err[n].append(np.max(np.abs(pf.x - kf.x) / sd))
            cov[n].append(np.linalg.norm(pf.P - kf.P) / np.linalg.norm(kf.P))
    # Monte Carlo error of the weighted mean ~ 1/sqrt(N_eff) posterior standard deviations and
    # of the covariance ~ sqrt(2/N_eff). The DVL update is sharp here (ESS down to ~15% of N)
    # and resampling correlates the error over steps (variance inflated a few times): the
    # max over 4 states x 10 steps measures ~11/sqrt(N) (0.04 at N = 64000, scattering up to
    # 0.11 over seeds and schemes) and the covariance error ~0.05; tolerances 0.2 and 0.15
    assert max(err[64000]) < 0.2
    assert max(cov[64000]) < 0.15
    # and it converges: 64 times the particles, errors down by ~8 (at least by 3)
    assert np.mean(err[64000]) < np.mean(err[1000]) / 3
    assert np.mean(cov[64000]) < np.mean(cov[1000]) / 3


def test_roughening_and_resampling_diagnostics():
    model = cv()
    zs = simulate(model, 20, seed=2)
    pf = ParticleFilter(model, X0, P0, n_particles=500, roughening=0.2, ess_threshold=1.0,
                        seed=1)
    for z in zs:
        pf.predict(None, 1.0)
        pf.update(z)
        assert pf.diagnostics["resampled"] == 1.0
        assert 1.0 <= pf.diagnostics["ess"] <= 500.0
        assert pf.diagnostics["nis_dof"] == 3.0
    np.testing.assert_allclose(pf.weights.sum(), 1.0)
    assert np.all(np.isfinite(pf.x)) and np.all(np.linalg.eigvalsh(pf.P) > 0)


def test_bad_settings_are_rejected():
    for settings, word in (({"n_particles": 1}, "n_particles"),
                           ({"ess_threshold": 2.0}, "ess_threshold"),
                           ({"roughening": -1.0}, "roughening")):
        with pytest.raises(ScenarioError, match=word):
            ESTIMATORS.get("pf").from_settings(cv(), X0, P0, settings, where="s.toml")


def test_standard_normals_are_standard_normal_and_reproducible():
    from scipy.special import ndtr

    from uwcosim.filters.particle import standard_normals

    x = standard_normals(np.random.default_rng(11), (250001,)).ravel()  # odd size
    assert x.shape == (250001,)
    np.testing.assert_array_equal(x, standard_normals(np.random.default_rng(11), (250001,)))
    n = x.size
    assert abs(x.mean()) < 5 / np.sqrt(n)
    assert abs(x.var() - 1.0) < 5 * np.sqrt(2 / n)
    assert abs(np.mean(x**4) - 3.0) < 5 * np.sqrt(96 / n)
    # Kolmogorov-Smirnov against the normal CDF (1% critical value 1.63 / sqrt(n))
    xs = np.sort(x)
    ks = np.max(np.abs(ndtr(xs) - np.arange(1, n + 1) / n))
    assert ks < 1.63 / np.sqrt(n)
    # the two halves of a block (cosine and sine of the same angles) are independent
    h = n // 2
    assert abs(np.corrcoef(x[:h], x[h:2 * h])[0, 1]) < 5 / np.sqrt(h)
    assert abs(np.corrcoef(x[:h] ** 2, x[h:2 * h] ** 2)[0, 1]) < 5 / np.sqrt(h)


def test_noise_blocks_make_runs_reproducible_whatever_is_read():
    model = cv()
    zs = simulate(model, 150, seed=3)  # crosses two noise blocks of 64 steps

    def run(read: bool):
        pf = ParticleFilter(model, X0, P0, n_particles=300, seed=8)
        for k, z in enumerate(zs):
            pf.predict(None, 1.0)
            if read:
                _ = pf.x, pf.P, pf.weights
            pf.update(z if k % 3 else None)  # some steps without a measurement
        return pf.particles.copy(), pf.x, pf.P

    for a, b in zip(run(False), run(True)):
        np.testing.assert_array_equal(a, b)


def test_systematic_counts_equal_the_search_definition():
    from uwcosim.filters.particle import _search, systematic

    rng = np.random.default_rng(2)
    for n in (2, 7, 100, 1000):
        for _ in range(50):
            w = rng.random(n) ** 4
            w[rng.random(n) < 0.3] = 0.0  # zero weights, also at the end
            if w.sum() == 0.0:
                w[0] = 1.0
            w /= w.sum()
            seed = int(rng.integers(1 << 30))
            idx = systematic(w, np.random.default_rng(seed))
            u = np.random.default_rng(seed).random()
            ref = _search(w, (u + np.arange(n)) / n)
            assert idx.size == n and np.all(w[idx] > 0.0)
            np.testing.assert_array_equal(idx, ref)


def test_ess_threshold_extremes():
    model = cv()
    zs = simulate(model, 5, seed=4)
    never = ParticleFilter(model, X0, P0, n_particles=200, ess_threshold=0.0, seed=1)
    always = ParticleFilter(model, X0, P0, n_particles=200, ess_threshold=1.0, seed=1)
    for z in zs:
        for pf in (never, always):
            pf.predict(None, 1.0)
            pf.update(z)
        assert never.diagnostics["resampled"] == 0.0
        assert always.diagnostics["resampled"] == 1.0
    # a flat likelihood leaves equal weights: ESS = N up to round-off, still resampled at 1
    flat = ParticleFilter(model, X0, P0, n_particles=200, ess_threshold=1.0, seed=1)
    flat.model = type("Flat", (), {})()
    flat.model.__dict__.update(nz=3, R=model.R, h_batch=lambda X: np.zeros((X.shape[0], 3)))
    flat.update(np.zeros(3))
    assert flat.diagnostics["ess"] == pytest.approx(200.0)
    assert flat.diagnostics["resampled"] == 1.0


def test_weights_survive_a_measurement_far_from_every_particle():
    model = cv()
    pf = ParticleFilter(model, X0, P0, n_particles=500, ess_threshold=0.0, seed=5)
    pf.predict(None, 1.0)
    pf.update(np.array([300.0, -200.0, 40.0]))  # log-likelihoods around -1e4: exp underflows
    w = pf.weights
    assert np.all(np.isfinite(w)) and w.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(np.exp(pf.logw), w, rtol=1e-12, atol=1e-300)
    assert w.max() > 0.5  # the particle nearest the measurement takes the weight
    assert np.all(np.isfinite(pf.x)) and np.all(np.isfinite(pf.P))


def test_moments_are_the_weighted_mean_and_covariance():
    model = cv()
    pf = ParticleFilter(model, X0, P0, n_particles=400, ess_threshold=0.0, seed=6)
    for z in simulate(model, 3, seed=6):
        pf.predict(None, 1.0)
        pf.update(z)
    w = pf.weights
    np.testing.assert_allclose(pf.x, np.average(pf.particles, axis=1, weights=w), rtol=1e-12)
    ref = np.cov(pf.particles, aweights=w, bias=True)
    np.testing.assert_allclose(pf.P, ref, rtol=1e-10, atol=1e-14)
    np.testing.assert_array_equal(pf.P, pf.P.T)


def test_model_noise_factor_is_a_factor_of_Q():
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry

    fast = (tan_model([0.01, 0.02, 1e-6, 2e-6], 0.05, 2.0, synthetic_bathymetry(3)))
    for u, dt in (([0.3, 0.001], 1.0), ([-2.0, 0.0], 0.5), ([0.3, 0.001], 1.0)):
        L = fast.Q_factor(None, np.array(u), dt)
        np.testing.assert_allclose(L @ L.T, fast.Q(None, np.array(u), dt), rtol=1e-12,
                                   atol=1e-18)
        assert not L.flags.writeable
