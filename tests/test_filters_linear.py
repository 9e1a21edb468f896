"""Gaussian filters on linear-Gaussian models: KF vs batch least squares, sigma-point filters
vs KF, consistency (ANEES) over Monte Carlo runs, and the constant-velocity model."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.evaluation.metrics import anees, nees
from uwcosim.filters import particle, sigma_point, variational  # noqa: F401  (register)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.kalman import ExtendedKalmanFilter, KalmanFilter
from uwcosim.filters.sigma_point import (
    CubatureKalmanFilter,
    CubatureUnscentedKalmanFilter,
    UnscentedKalmanFilter,
)
from uwcosim.models.casadi_model import CasadiModel
from uwcosim.models.cv_equations import constant_velocity_ode
from uwcosim.models.linear import constant_velocity_model, measurement_matrix

NAMES = ("gps.px_m", "gps.py_m", "dvl.vx_m")
R3 = np.array([[4.0, 0.6, 0.0], [0.6, 2.0, 0.01], [0.0, 0.01, 0.04]])  # correlated on purpose
PSD = np.array([0.05, 0.01, 0.05, 0.02])
X0 = np.array([10.0, 1.0, -5.0, 0.5])
P0 = np.diag([9.0, 1.0, 4.0, 0.25])


def cv(q_psd=PSD):
    return constant_velocity_model(q_psd=q_psd, R=R3, measurement_names=NAMES)


def simulate(model, steps, rng, dts=None, x0=X0, P0=P0):
    """Truth and measurements of a linear model: x' = F x + w, z = H x + v."""
    dts = np.ones(steps) if dts is None else dts
    x = x0 + np.linalg.cholesky(P0) @ rng.standard_normal(model.nx)
    xs, zs = [], []
    LR = np.linalg.cholesky(model.R)
    for dt in dts:
        Q = model.Q(x, None, dt)
        w = np.linalg.cholesky(Q) @ rng.standard_normal(model.nx) if Q.any() else 0.0
        x = model.f(x, None, dt) + w
        xs.append(x)
        zs.append(model.h(x) + LR @ rng.standard_normal(model.nz))
    return np.array(xs), np.array(zs), np.asarray(dts)


def masks(steps, nz, rng):
    m = rng.random((steps, nz)) > 0.25
    m[3] = False  # one step with nothing received
    return m


def run(est, zs, dts, mask):
    xs, Ps = [], []
    for k, dt in enumerate(dts):
        est.predict(None, dt)
        est.update(zs[k] if mask[k].any() else None, mask[k])
        xs.append(est.x.copy())
        Ps.append(est.P.copy())
    return np.array(xs), np.array(Ps)


def batch_posterior(model, zs, dts, mask, K):
    """Mean and covariance of x_K given z_1..z_K from the information form of the whole
    trajectory (x_0..x_K): Lambda X = eta, Lambda = A' W A for the stacked linear residuals."""
    n = model.nx
    N = n * (K + 1)
    rows, W, r = [], [], []

    def add(block_cols, mats, rhs, cov):
        A = np.zeros((cov.shape[0], N))
        for c, M in zip(block_cols, mats):
            A[:, n * c : n * (c + 1)] = M
        rows.append(A)
        W.append(np.linalg.inv(cov))
        r.append(rhs)

    add([0], [np.eye(n)], X0, P0)
    for k in range(1, K + 1):
        dt = dts[k - 1]
        F, Q = model.FQ(None, None, dt)
        add([k, k - 1], [np.eye(n), -F], np.zeros(n), Q)
        idx = np.flatnonzero(mask[k - 1])
        if idx.size:
            Hk = model.H()[idx]
            add([k], [Hk], zs[k - 1][idx], model.R[np.ix_(idx, idx)])
    Lam = sum(A.T @ Wi @ A for A, Wi in zip(rows, W))
    eta = sum(A.T @ Wi @ ri for A, Wi, ri in zip(rows, W, r))
    X = np.linalg.solve(Lam, eta)
    E = np.zeros((N, n))
    E[n * K :, :] = np.eye(n)
    cov = np.linalg.solve(Lam, E)[n * K :, :]
    return X[n * K :], cov


def test_kf_equals_batch_least_squares():
    model = cv()
    rng = np.random.default_rng(11)
    K = 12
    dts = rng.uniform(0.5, 1.5, K)
    _, zs, dts = simulate(model, K, rng, dts)
    mask = masks(K, model.nz, rng)
    xs, Ps = run(KalmanFilter(model, X0, P0), zs, dts, mask)
    for k in (1, 4, 7, K):
        xb, Pb = batch_posterior(model, zs, dts, mask, k)
        np.testing.assert_allclose(xs[k - 1], xb, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(Ps[k - 1], Pb, rtol=1e-9, atol=1e-11)


SIGMA = [
    pytest.param(lambda m: UnscentedKalmanFilter(m, X0, P0), id="ukf"),
    pytest.param(lambda m: UnscentedKalmanFilter(m, X0, P0, alpha=0.3, kappa=1.0), id="ukf-a0.3"),
    pytest.param(lambda m: CubatureKalmanFilter(m, X0, P0), id="ckf"),
    pytest.param(lambda m: CubatureUnscentedKalmanFilter(m, X0, P0, redraw=True),
                 id="cukf-redraw"),
    pytest.param(lambda m: ExtendedKalmanFilter(m, X0, P0), id="ekf"),
]


@pytest.mark.parametrize("make", SIGMA)
def test_gaussian_filters_equal_kf_on_linear_model(make):
    model = cv()
    rng = np.random.default_rng(5)
    K = 40
    dts = rng.uniform(0.5, 1.5, K)
    _, zs, dts = simulate(model, K, rng, dts)
    mask = masks(K, model.nz, rng)
    x_kf, P_kf = run(KalmanFilter(model, X0, P0), zs, dts, mask)
    x, P = run(make(model), zs, dts, mask)
    np.testing.assert_allclose(x, x_kf, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(P, P_kf, rtol=1e-9, atol=1e-11)


def test_cukf_as_printed_is_kf_only_without_process_noise():
    """Seed 001 eq. (10) reuses the propagated points for the measurement, which leaves Q out
    of P_xz and P_zz: the printed CUKF equals the KF when Q = 0, not otherwise."""
    K = 20
    for q, equal in ((np.zeros(4), True), (PSD, False)):
        model = cv(q)
        _, zs, dts = simulate(model, K, np.random.default_rng(1))
        mask = np.ones((K, model.nz), bool)
        x_kf, P_kf = run(KalmanFilter(model, X0, P0), zs, dts, mask)
        x, P = run(CubatureUnscentedKalmanFilter(model, X0, P0), zs, dts, mask)
        assert np.allclose(P, P_kf, rtol=1e-9, atol=1e-11) is equal
        assert np.allclose(x, x_kf, rtol=1e-9, atol=1e-9) is equal


@pytest.mark.parametrize("kind", ["kf", "ukf"])
def test_anees_inside_chi2_band_over_100_runs(kind):
    model = cv()
    runs, K = 100, 50
    rng = np.random.default_rng(2024)
    N = np.empty((K, runs))
    for m in range(runs):
        xs, zs, dts = simulate(model, K, rng)
        est = ESTIMATORS.get(kind)(model, X0, P0)
        xe, Pe = run(est, zs, dts, np.ones((K, model.nz), bool))
        N[:, m] = nees(xs - xe, Pe)
    res = anees(N, dof=model.nx)
    # per-step ANEES of 100 runs in its 95% band chi2(400)/100: expect ~95% of the 50 steps;
    # 0.85 is three binomial standard deviations below
    assert res["fraction_inside"] >= 0.85
    # overall ANEES / n: 5000 correlated NEES values, the iid band is +-2%; allow +-10%
    assert 0.9 <= res["normalized"] <= 1.1


def test_kf_refuses_nonlinear_model():
    from uwcosim.models.tan import tan_model

    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05)
    with pytest.raises(ScenarioError, match="linear model"):
        ESTIMATORS.get("kf").from_settings(model, np.zeros(4), np.eye(4), {}, where="s.toml")


def test_cv_model_matches_casadi_discretization():
    """The closed-form F, Q equal RK4 of the FMU's CasADi ODE with noise held over a step."""
    x, u, w = ca.SX.sym("x", 4), ca.SX.sym("u", 1), ca.SX.sym("w", 4)
    ode = ca.Function("ode", [x, u, w], [constant_velocity_ode()(x, w)])
    xs = ca.SX.sym("x", 4)
    h = ca.Function("h", [xs], [xs])
    ref = CasadiModel(ode, h, PSD, np.ones(4), ("px", "vx", "py", "vy"), tuple("abcd"))
    model = constant_velocity_model(q_psd=PSD)
    xv, uv = np.array([1.0, 2.0, -3.0, 0.5]), np.zeros(1)
    for dt in (0.1, 1.0, 2.5):
        np.testing.assert_allclose(model.f(xv, None, dt), ref.f(xv, uv, dt), rtol=1e-12)
        np.testing.assert_allclose(model.F(xv, None, dt), ref.F(xv, uv, dt), rtol=1e-12)
        np.testing.assert_allclose(model.Q(xv, None, dt), ref.Q(xv, uv, dt), rtol=1e-12,
                                   atol=1e-15)


def test_cv_measurement_names_build_h():
    H = measurement_matrix(("gps.x_m", "dvl.vy_m", "pos.py_m"))
    np.testing.assert_array_equal(H, [[1, 0, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0]])
    with pytest.raises(ScenarioError, match="px, vx, py, vy"):
        measurement_matrix(("sounder.depth_m",))
