"""Point-mass (grid) filter: exactness on linear-Gaussian problems and the TAN model."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from tests.grid_reference import gaussian_convolve
from uwcosim.core import jit
from uwcosim.core.errors import ScenarioError
from uwcosim.evaluation.distance import hellinger
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.grid.moments import axes_moments, moments2_ordered
from uwcosim.filters.point_mass import fft
from uwcosim.filters.point_mass.filter import PointMassFilter
from uwcosim.filters.point_mass.prediction import shift_blur
from uwcosim.models.casadi_model import CasadiModel
from uwcosim.models.tan import tan_model


def linear_model(n: int = 1, drift: float = 0.0, q: float = 0.1, r: float = 0.25):
    """Random walk (optionally with a linear drift ``-drift x``) measured directly."""
    x = ca.SX.sym("x", n)
    u = ca.SX.sym("u", 1)
    w = ca.SX.sym("w", n)
    ode = ca.Function("ode", [x, u, w], [-drift * x + w])
    xm = ca.MX.sym("x", n)
    h = ca.Function("h", [xm], [xm])
    names = tuple(f"x{i}" for i in range(n))
    model = CasadiModel(ode, h, [q] * n, [r] * n, names, tuple(f"z{i}" for i in range(n)))
    model.ode = ode
    return model


def test_hellinger_properties():
    x = np.linspace(-30, 30, 6001)
    p = np.exp(-0.5 * x**2)
    assert hellinger(p, p) == pytest.approx(0.0, abs=1e-7)
    assert hellinger(p, np.exp(-0.5 * (x - 20) ** 2)) == pytest.approx(1.0)
    # two unit Gaussians 0.2 apart: H^2 = 1 - exp(-d^2 / 8)
    assert hellinger(p, np.exp(-0.5 * (x - 0.2) ** 2)) == pytest.approx(
        np.sqrt(1 - np.exp(-0.04 / 8)), rel=1e-6
    )


def test_gaussian_convolve_matches_analytic():
    x = np.linspace(-10, 10, 401)
    dx = x[1] - x[0]
    X, Y = np.meshgrid(x, x, indexing="ij")
    p = np.exp(-0.5 * (X**2 / 1.0 + Y**2 / 2.0))
    D = np.array([[0.5, 0.2], [0.2, 0.3]])
    out = gaussian_convolve(p, [dx, dx], D)
    C = np.diag([1.0, 2.0]) + D
    Ci = np.linalg.inv(C)
    ref = np.exp(-0.5 * (Ci[0, 0] * X**2 + 2 * Ci[0, 1] * X * Y + Ci[1, 1] * Y**2))
    ref *= p.sum() / ref.sum()
    assert np.max(np.abs(out - ref)) < 1e-6 * ref.max()


def test_shift_blur_is_spline_interpolation_and_exact_blur():
    """The TAN prediction: with D = 0 it is the cubic spline of ndimage.map_coordinates at the
    pulled-back points; with D it is the analytic convolution of a Gaussian."""
    from scipy import ndimage

    x = np.linspace(-8.0, 8.0, 101)
    h = x[1] - x[0]
    X, Y = np.meshgrid(x, x, indexing="ij")
    C = np.array([[1.0, 0.3], [0.3, 2.0]])
    Ci = np.linalg.inv(C)
    p = np.exp(-0.5 * (Ci[0, 0] * X**2 + 2 * Ci[0, 1] * X * Y + Ci[1, 1] * Y**2))
    coords = [np.linspace(3.3, 97.2, 101), np.linspace(-2.0, 99.0, 101)]  # grid units
    ref = ndimage.map_coordinates(p, np.meshgrid(*coords, indexing="ij"), order=3,
                                  mode="constant", cval=0.0)
    out = shift_blur(p, [h, h], coords, np.zeros((2, 2)))
    assert np.max(np.abs(out - ref)) < 1e-6
    D = np.array([[0.05, -0.02], [-0.02, 0.03]])
    out = shift_blur(p, [h, h], coords, D)
    new = [x[0] + c * h for c in coords]
    NX, NY = np.meshgrid(*new, indexing="ij")
    Si = np.linalg.inv(C + D)
    exact = np.exp(-0.5 * (Si[0, 0] * NX**2 + 2 * Si[0, 1] * NX * NY + Si[1, 1] * NY**2))
    exact *= np.sqrt(np.linalg.det(C) / np.linalg.det(C + D))
    assert np.max(np.abs(out - exact)) < 1e-4


@pytest.mark.parametrize("drift", [0.0, 0.3])
def test_point_mass_matches_kalman_filter(drift):
    """Linear-Gaussian: the grid posterior is the Kalman posterior (random walk: FFT path;
    with drift: Chapman-Kolmogorov path)."""
    model = linear_model(1, drift=drift)
    rng = np.random.default_rng(4)
    kf = ESTIMATORS.get("ekf")(model, [0.3], [[2.0]])
    pm = PointMassFilter(model, [0.3], [[2.0]], n_points=801, span=10.0)
    u = np.zeros(1)
    for _ in range(10):
        z = rng.normal(0.0, 1.0, 1)
        for est in (kf, pm):
            est.predict(u, 0.5)
            est.update(z)
        assert pm.x[0] == pytest.approx(kf.x[0], abs=2e-3)
        assert pm.P[0, 0] == pytest.approx(kf.P[0, 0], rel=2e-2)
    axes, values = pm.density_grid()
    ref = np.exp(-0.5 * (axes[0] - kf.x[0]) ** 2 / kf.P[0, 0])
    assert hellinger(values, ref) < 5e-3


def test_point_mass_2d_and_missing_measurements():
    model = linear_model(2)
    pm = PointMassFilter(model, [0.0, 0.0], np.eye(2), n_points=[81, 61])
    kf = ESTIMATORS.get("ekf")(model, [0.0, 0.0], np.eye(2))
    u = np.zeros(1)
    for z, mask in (([0.5, -0.2], None), ([0.4, np.nan], None), ([0.3, 0.1], [True, False])):
        for est in (pm, kf):
            est.predict(u, 1.0)
            est.update(np.array(z), None if mask is None else np.array(mask))
    np.testing.assert_allclose(pm.x, kf.x, atol=5e-3)
    np.testing.assert_allclose(pm.P, kf.P, rtol=3e-2, atol=1e-3)
    assert pm.diagnostics["n_points"] == 81 * 61
    axes, values = pm.density_grid(n=21)
    assert values.shape == (21, 21)
    pm.predict(u, 1.0)
    pm.update(None)  # no measurement: posterior = prior


def test_point_mass_settings_are_checked():
    model = linear_model(1)
    with pytest.raises(ScenarioError, match="unknown setting"):
        PointMassFilter.from_settings(model, [0.0], [[1.0]], {"n_point": 10}, where="s.toml")
    est = PointMassFilter.from_settings(model, [0.0], [[1.0]], {"n_points": 51, "span": 6})
    assert est.kind == "point_mass" and est.values.shape == (51,)


def test_point_mass_tan_dvl_only_matches_kalman():
    """No terrain: position gridded, velocities by the conditional Kalman filter."""
    model = tan_model([0.05, 0.05, 1e-4, 1e-4], 0.03)
    pm = PointMassFilter(model, [2000.0, 18000.0, 0.5, 0.0], np.diag([900, 900, 0.0025, 0.0025]))
    kf = ESTIMATORS.get("ekf")(model, pm.x, pm.P)
    assert pm.gridded_states == ["x", "y"]
    rng = np.random.default_rng(0)
    for k in range(50):
        u = np.array([0.3 + 0.01 * k, 0.001])
        z = np.array([0.5, 0.0]) + rng.normal(0, 0.03, 2)
        for est in (pm, kf):
            est.predict(u, 1.0)
            est.update(z)
    np.testing.assert_allclose(pm.x[2:], kf.x[2:], atol=1e-6)
    assert np.linalg.norm(pm.x[:2] - kf.x[:2]) < 0.5
    np.testing.assert_allclose(np.diag(pm.P)[:2], np.diag(kf.P)[:2], rtol=2e-3)


@pytest.mark.parametrize("shape", [(101, 101), (61, 45), (7, 9)])
def test_point_mass_moment_kernel_matches_numpy(shape):
    if not jit.ENABLED:
        pytest.skip("compiled kernels (Numba) not available")
    rng = np.random.default_rng(3)
    axes = [np.linspace(-40.0, 25.0, shape[0]) + 3000.0, np.linspace(-9.0, 30.0, shape[1])]
    values = rng.random(shape) * np.exp(-np.add.outer(np.linspace(-2, 2, shape[0]) ** 2,
                                                      np.linspace(-1, 3, shape[1]) ** 2))
    mean, cov = moments2_ordered(values, axes[0], axes[1])
    ref_mean, ref_cov = axes_moments(axes, values)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-13)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-11)
    assert cov[0, 1] == cov[1, 0]


def test_fft_plan_private_binding_and_public_fallback_agree(monkeypatch):
    """The point mass's FFTs through scipy's pocketfft binding and through the public
    scipy.fft functions (the fallback when the private binding is missing): the same bits."""
    rng = np.random.default_rng(5)
    data = rng.random((108, 120))
    out = []
    for binding in (fft._pocketfft, None):
        monkeypatch.setattr(fft, "_pocketfft", binding)
        plan = fft.FFTPlan((108, 120))
        plan.buf[:] = data
        spec = plan.forward().copy()
        out.append((spec, plan.inverse().copy()))
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])
    np.testing.assert_allclose(out[0][1], data, rtol=0, atol=1e-12)
