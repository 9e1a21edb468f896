"""Filters on the terrain-aided navigation model (seed 000 Example 2) with a synthetic map:
the numpy fast path against CasADi, EKF Jacobians, every filter on a simulated trajectory,
divergence on NaN."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import FilterDivergence
from uwcosim.filters import particle, sigma_point, variational  # noqa: F401  (register)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.kalman import ExtendedKalmanFilter
from uwcosim.models.casadi_model import CasadiModel
from uwcosim.models.tan import TANModel, tan_model
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.models.trajectory import simulate

Q_PSD = [0.01, 0.01, 1e-6, 1e-6]
STD0 = np.array([30.0, 30.0, 0.05, 0.05])
START = np.array([2000.0, 18000.0, 0.5, 0.0])
STEPS = 300


@pytest.fixture(scope="module")
def terrain():
    return synthetic_bathymetry(7)


@pytest.fixture(scope="module")
def model(terrain):
    return tan_model(Q_PSD, 0.05, 2.0, terrain)


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 200 else 0.0])


@pytest.fixture(scope="module")
def trajectory(model):
    """Truth from the CasADi model: x' = f(x, u) + w, w ~ N(0, Q); z = h(x) + v."""
    rng = np.random.default_rng(42)
    X, _, zs = simulate(model.symbolic, START, controls, STEPS, rng)
    xs = X[1:]
    return xs, zs, START + STD0 * rng.standard_normal(4)


def run(est, zs, steps=STEPS):
    xs = []
    for k in range(steps):
        est.predict(controls(k), 1.0)
        est.t = k + 1.0
        est.update(zs[k])
        xs.append(est.x.copy())
        assert np.all(np.isfinite(est.P))
    return np.array(xs)


def terrain_inside(model, X):
    return model.terrain.inside(X[:, 0], X[:, 1])


def test_fast_model_equals_casadi(model):
    fast, model = model, model.symbolic  # the closed form against its CasADi form
    assert isinstance(fast, TANModel) and isinstance(model, CasadiModel)
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(0, 25000, 500), rng.uniform(0, 25000, 500),
                         rng.normal(0, 1, 500), rng.normal(0, 1, 500)])
    X[:5, :2] = [[-100.0, 50.0], [25100.0, 3.0], [10.0, -7.0], [0.0, 0.0], [25000.0, 25000.0]]
    for u, dt in ((np.array([0.3, 0.01]), 1.0), (np.array([-2.5, -0.2]), 0.37)):
        np.testing.assert_allclose(fast.f_batch(X, u, dt), model.f_batch(X, u, dt),
                                   rtol=1e-12, atol=1e-12)
        for a, b in zip(fast.FG(X[7], u, dt), model.FG(X[7], u, dt)):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(fast.Q(X[7], u, dt), model.Q(X[7], u, dt), rtol=1e-12,
                                   atol=1e-15)
    inside = terrain_inside(model, X)
    assert (~inside).sum() == 3
    np.testing.assert_allclose(fast.h_batch(X[inside]), model.h_batch(X[inside]), rtol=1e-12,
                               atol=1e-12)
    # outside the map CasADi's bspline extrapolates; the filters' fast path clamps to the edge
    # like Bathymetry.depth (the truth FMU stops there anyway)
    np.testing.assert_allclose(fast.h_batch(X[~inside])[:, 2],
                               model.terrain.depth(X[~inside, 0], X[~inside, 1]), rtol=1e-12)
    for x in X[5:40]:
        np.testing.assert_allclose(fast.h(x), model.h(x), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(fast.H(x), model.H(x), rtol=1e-12, atol=1e-12)


def test_filters_use_the_model_they_are_given(model):
    """No silent swap: a filter runs the implementation the model factory chose (the closed
    form of tan_model, or the CasADi form when given that); the grid filters analyse the
    CasADi form of either."""
    P0 = np.diag(STD0**2)
    assert ExtendedKalmanFilter(model, START, P0).model is model
    assert ExtendedKalmanFilter(model.symbolic, START, P0).model is model.symbolic
    pm = ESTIMATORS.get("point_mass")(model, START, P0)
    assert pm.model is model.symbolic
    assert isinstance(tan_model(Q_PSD, 0.05), TANModel)


@pytest.mark.parametrize("fast", [False, True], ids=["casadi", "numpy"])
def test_ekf_jacobians_equal_finite_differences(model, fast):
    m = model if fast else model.symbolic
    rng = np.random.default_rng(3)
    for _ in range(5):
        x = np.array([rng.uniform(2000, 23000), rng.uniform(2000, 23000), *rng.normal(0, 1, 2)])
        u = np.array([rng.uniform(-3, 3), rng.normal(0, 0.05)])
        F, _ = m.FG(x, u, 1.0)
        H = m.H(x)
        # central differences: f is linear, the spline C2; steps against round-off at 1e4 m
        eps = np.array([1e-2, 1e-2, 1e-3, 1e-3])
        Fd = np.column_stack([(m.f(x + e, u, 1.0) - m.f(x - e, u, 1.0)) / (2 * e[i])
                              for i, e in enumerate(np.diag(eps))])
        Hd = np.column_stack([(m.h(x + e) - m.h(x - e)) / (2 * e[i])
                              for i, e in enumerate(np.diag(eps))])
        np.testing.assert_allclose(F, Fd, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(H, Hd, rtol=1e-4, atol=1e-7)


ALL = ["ekf", "ukf", "ckf", "cukf", "pf", "vbakf", "qivbf", "dead_reckoning"]


@pytest.fixture(scope="module")
def estimates(model, trajectory):
    xs, zs, x0 = trajectory
    out = {}
    for name in ALL:
        # the random stream is the driver's, not a setting
        est = ESTIMATORS.get(name).from_settings(model, x0, np.diag(STD0**2), {},
                                                 rng=np.random.default_rng(1))
        out[name] = run(est, zs)
    return out


def position_rmse(x_est, xs, steps=slice(STEPS // 2, None)):
    e = (x_est - xs)[steps, :2]
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


@pytest.mark.parametrize("name", ALL)
def test_every_filter_tracks_the_tan_trajectory(name, estimates, trajectory):
    xs, _, _ = trajectory
    x = estimates[name]
    assert np.all(np.isfinite(x))
    # velocity from the DVL in every filter; position at least as good as the initial error
    assert np.sqrt(np.mean((x - xs)[:, 2:] ** 2)) < 0.05
    assert position_rmse(x, xs) < 3 * np.hypot(STD0[0], STD0[1])


@pytest.mark.parametrize("name", ["ekf", "ukf", "pf"])
def test_terrain_filters_beat_dead_reckoning(name, estimates, trajectory):
    xs, _, _ = trajectory
    dr = position_rmse(estimates["dead_reckoning"], xs)
    assert position_rmse(estimates[name], xs) < dr


@pytest.mark.parametrize("name", ALL)
def test_nan_raises_filter_divergence(name, model):
    est = ESTIMATORS.get(name).from_settings(model, START, np.diag(STD0**2), {},
                                             rng=np.random.default_rng(0))
    with pytest.raises(FilterDivergence):
        est.predict(np.array([np.nan, 0.0]), 1.0)
        est.update(model.h(START))


def test_ekf_diagnostics_and_masks(model):
    est = ExtendedKalmanFilter(model, START, np.diag(STD0**2))
    est.predict(controls(0), 1.0)
    est.update(model.h(START), np.array([True, True, False]))
    assert est.diagnostics["nis_dof"] == 2.0
    assert est.diagnostics["pd_repairs"] == 0.0
    est.update(None)  # a new step without predict: fresh diagnostics, no NIS
    assert est.diagnostics == {"pd_repairs": 0.0}


def test_fast_terrain_point_gradient_and_fallback(terrain, monkeypatch):
    from uwcosim.models import tan as fast_tan

    ft = fast_tan.FastTerrain(terrain)
    rng = np.random.default_rng(5)
    xs, ys = rng.uniform(0, 25000, 20), rng.uniform(0, 25000, 20)
    h, gx, gy = terrain.gradient(xs, ys)
    for i in range(20):
        np.testing.assert_allclose(ft.point(xs[i], ys[i]), (h[i], gx[i], gy[i]), rtol=1e-12,
                                   atol=1e-12)
    # outside: clamped depth, flat (zero derivative) across the edge
    d, ddx, ddy = ft.point(-500.0, 1234.0)
    assert d == pytest.approx(float(terrain.depth(0.0, 1234.0)), rel=1e-12)
    assert ddx == 0.0 and ddy == pytest.approx(float(terrain.gradient(0.0, 1234.0)[2]))
    np.testing.assert_allclose(ft.gradient(np.array([-500.0]), np.array([1234.0]))[1], 0.0)
    # maps too large for the table use Bathymetry.depth
    monkeypatch.setattr(fast_tan, "TABLE_MAX_BYTES", 0)
    small = synthetic_bathymetry(3, extent=(0.0, 2000.0, 0.0, 2000.0))
    slow = fast_tan.FastTerrain(small)
    assert slow._table is None
    np.testing.assert_allclose(slow.depth(xs / 20, ys / 20), small.depth(xs / 20, ys / 20))
    np.testing.assert_allclose(slow.point(100.0, 200.0), [a[0] for a in small.gradient(
        np.array([100.0]), np.array([200.0]))])


def test_dead_reckoning_does_no_terrain_work(model, trajectory):
    """Dead reckoning runs on the DVL-only view of the TAN model (no terrain lookup) and gives
    the numbers of the EKF restricted to the DVL rows of the full model, to the bit."""
    from uwcosim.filters import build

    _, zs, x0 = trajectory
    P0 = np.diag(STD0 ** 2)
    dr = build("dead_reckoning", model, x0, P0, {})
    assert dr.model.terrain is None and dr.model.nz == 2 and list(dr.rows) == [0, 1]
    ekf = build("ekf", model, x0, P0, {"measurements": list(model.measurement_names[:2])})
    np.testing.assert_array_equal(run(dr, zs), run(ekf, zs))
    np.testing.assert_array_equal(dr.P, ekf.P)
