"""Marginalized (``rbpf``) and regularized (``rpf``) particle filters on the TAN model:
the RBPF against the Kalman filter without terrain (where the Kalman filter is exact) and
against the point-mass filter with terrain (Hellinger distance of the position marginal), the
RPF's bandwidth, tracking and seeded determinism."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.evaluation.density import gaussian_on_grid, particles_on_grid
from uwcosim.evaluation.distance import hellinger
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.rbpf import RaoBlackwellizedPF
from uwcosim.filters.regularized import RegularizedPF, optimal_bandwidth
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.models.trajectory import simulate

START = np.array([2000.0, 18000.0, 0.5, 0.0])
STD0 = np.array([30.0, 30.0, 0.05, 0.05])


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 200 else 0.0])


def run(ests, zs, steps):
    for k in range(steps):
        for e in ests:
            e.predict(controls(k), 1.0)
            e.t = k + 1.0
            e.update(zs[k])


@pytest.fixture(scope="module")
def terrain_model():
    return tan_model([0.05, 0.05, 1e-5, 1e-5], 0.05, 1.0, synthetic_bathymetry(7))


def test_rbpf_equals_the_kalman_filter_without_terrain():
    """No terrain: the model is linear-Gaussian and the Kalman filter is the exact posterior.
    The RBPF's velocities are Kalman-filtered per particle, its positions sampled; with 20000
    particles its mean and variances must agree with the KF's within Monte Carlo error."""
    model = tan_model([0.05, 0.05, 1e-3, 1e-3], 0.05)  # noisy velocities: every term matters
    rng = np.random.default_rng(1)
    _, _, zs = simulate(model.symbolic, START, controls, 60, rng)
    x0 = START + STD0 * rng.standard_normal(4)
    kf = ESTIMATORS.get("ekf")(model, x0, np.diag(STD0**2))  # the KF on a linear model
    rb = RaoBlackwellizedPF(model, x0, np.diag(STD0**2), n_particles=20000, seed=1)
    assert (rb.ip, rb.ik) == ([0, 1], [2, 3])
    run([kf, rb], zs, 60)
    sd = np.sqrt(np.diag(kf.P))
    # position: Monte Carlo error of 20000 particles (~0.01 sd) plus slow degeneracy
    np.testing.assert_allclose((rb.x - kf.x)[:2] / sd[:2], 0.0, atol=0.1)
    np.testing.assert_allclose(np.diag(rb.P)[:2], np.diag(kf.P)[:2], rtol=0.06)
    # velocity: Kalman-filtered, only the mixture of means varies
    np.testing.assert_allclose((rb.x - kf.x)[2:] / sd[2:], 0.0, atol=0.01)
    np.testing.assert_allclose(np.diag(rb.P)[2:], np.diag(kf.P)[2:], rtol=2e-3)
    corr = (rb.P - kf.P)[:2, 2:] / np.outer(sd[:2], sd[2:])  # cross-covariance, correlations
    np.testing.assert_allclose(corr, 0.0, atol=0.05)


def test_rbpf_position_marginal_is_the_point_mass_posterior(terrain_model):
    """With terrain the point-mass filter (151 x 151 grid) is the reference. The RBPF's position
    marginal (kernel density of 20000 particles) must be as close to it as a kernel density of
    20000 exact draws from the grid density is (the estimator's own floor), plus 0.05; the EKF's
    Gaussian is not."""
    rng = np.random.default_rng(3)
    _, _, zs = simulate(terrain_model.symbolic, START, controls, 20, rng)
    x0 = START + STD0 * rng.standard_normal(4)
    P0 = np.diag(STD0**2)
    pm = ESTIMATORS.get("point_mass")(terrain_model, x0, P0, n_points=151)
    rb = RaoBlackwellizedPF(terrain_model, x0, P0, n_particles=20000, seed=2)
    ekf = ESTIMATORS.get("ekf")(terrain_model, x0, P0)
    run([pm, rb, ekf], zs, 20)
    axes, ref = pm.density_grid(n=161)
    p = ref.ravel() / ref.sum()
    draw = np.random.default_rng(0)
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)
    spacing = np.array([a[1] - a[0] for a in axes])
    X = nodes[draw.choice(p.size, 20000, p=p)] + (draw.random((20000, 2)) - 0.5) * spacing
    floor = hellinger(ref, particles_on_grid(X, np.ones(20000), axes))
    d_rb = hellinger(ref, particles_on_grid(rb.particles[:2].T, rb.weights, axes))
    d_ekf = hellinger(ref, gaussian_on_grid(ekf.x[:2], ekf.P[:2, :2], axes))
    assert d_rb < floor + 0.05, (d_rb, floor)
    assert d_ekf > floor + 0.05, (d_ekf, floor)


def test_rbpf_settings_and_split(terrain_model):
    est = ESTIMATORS.get("rbpf").from_settings(
        terrain_model, START, np.diag(STD0**2), {"n_particles": 50, "linear_states": ["vx", "vy"]})
    assert est.kind == "rbpf" and est.ik == [2, 3] and est.rows_k == [0, 1] and est.rows_p == [2]
    with pytest.raises(ScenarioError, match="s.toml: unknown setting 'particles'"):
        ESTIMATORS.get("rbpf").from_settings(terrain_model, START, np.diag(STD0**2),
                                             {"particles": 5}, where="s.toml")
    with pytest.raises(ScenarioError, match="depend on both"):
        ESTIMATORS.get("rbpf").from_settings(terrain_model, START, np.diag(STD0**2),
                                             {"linear_states": ["y", "vy"]})


def test_rbpf_and_rpf_are_seeded_and_track(terrain_model):
    rng = np.random.default_rng(5)
    xs, _, zs = simulate(terrain_model.symbolic, START, controls, 150, rng)
    x0 = START + STD0 * rng.standard_normal(4)

    def final(name, seed, **kw):
        est = ESTIMATORS.get(name)(terrain_model, x0, np.diag(STD0**2), n_particles=500,
                                   seed=seed, **kw)
        run([est], zs, 150)
        return est

    for name, kw in (("rbpf", {}), ("rpf", {}), ("rpf", {"shrink": True})):
        a, b, c = final(name, 4, **kw), final(name, 4, **kw), final(name, 5, **kw)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.P, b.P)
        assert not np.array_equal(a.x, c.x)
        e = a.x[:2] - xs[-1, :2]
        nees = float(e @ np.linalg.solve(a.P[:2, :2], e))
        assert np.isfinite(a.P).all() and nees < 13.8, (name, kw, nees)  # chi2(2) 99.9 %
        assert np.sqrt(np.trace(a.P[2:, 2:])) < 0.05  # the DVL's velocities


def test_rpf_bandwidth_and_jitter(terrain_model):
    assert optimal_bandwidth(1000, 4) == pytest.approx((4 / 6) ** 0.125 * 1000 ** -0.125)
    est = RegularizedPF(terrain_model, START, np.diag(STD0**2), n_particles=400, seed=1,
                        ess_threshold=1.0, bandwidth_scale=0.5)
    assert est.bandwidth == pytest.approx(0.5 * optimal_bandwidth(400, 4))
    est.predict(controls(0), 1.0)
    est.update(terrain_model.h(START))
    assert est.diagnostics["resampled"] == 1.0 and est.diagnostics["bandwidth"] == est.bandwidth
    # jitter splits the copies that resampling made: all particles distinct again
    assert np.unique(est.particles[0]).size == 400
    with pytest.raises(ValueError, match="shrink needs a bandwidth below 1"):
        RegularizedPF(terrain_model, START, np.diag(STD0**2), n_particles=10, shrink=True,
                      bandwidth_scale=10.0)


def test_rbpf_partial_measurements(terrain_model):
    """Depth only (DVL lost), DVL only, nothing: the linear block is left alone without DVL."""
    est = RaoBlackwellizedPF(terrain_model, START, np.diag(STD0**2), n_particles=300, seed=3)
    z = terrain_model.h(START)
    est.predict(controls(0), 1.0)
    Pk = est.Pk.copy()
    means = est.particles[2:].copy()
    est.update(z, np.array([False, False, True]))
    assert est.diagnostics["nis_dof"] == 1.0 and est.diagnostics["pd_repairs"] == 0.0
    np.testing.assert_array_equal(est.Pk, Pk)
    if not est.diagnostics["resampled"]:
        np.testing.assert_array_equal(est.particles[2:], means)
    est.predict(controls(1), 1.0)
    est.update(z, np.array([True, True, False]))
    assert est.diagnostics["nis_dof"] == 2.0 and np.trace(est.Pk) < np.trace(Pk)
    est.predict(controls(2), 1.0)
    est.update(None)
    assert np.isfinite(est.P).all()
