"""Filters that expect outliers (issue 25, section 3): the Student-t likelihood of the particle,
point-mass and projection filters (``student_t_nu``) and the chi-square gate of the Kalman
family (``gate_probability``), both off by default."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.filters import particle, sigma_point  # noqa: F401  (register)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.gating import gate_threshold
from uwcosim.filters.robust import student_t_exponent, student_t_loglik
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry

X0 = np.array([2000.0, 18000.0, 0.5, 0.0])
P0 = np.diag([30.0, 30.0, 0.05, 0.05]) ** 2
U = np.array([0.0, 0.0])


@pytest.fixture(scope="module")
def model():
    return tan_model([0.05, 0.05, 1e-5, 1e-5], [0.05, 0.05], 1.0, synthetic_bathymetry(7))


def _make(model, kind, **settings):
    import uwcosim.filters.point_mass  # noqa: F401  (register)
    import uwcosim.filters.projection  # noqa: F401

    cls = ESTIMATORS.get(kind)
    rng = np.random.default_rng(5) if cls.needs_rng else None
    return cls(model, X0.copy(), P0.copy(), rng=rng, **settings)


def test_student_t_tends_to_the_gaussian_as_nu_grows():
    e2 = np.array([0.0, 0.3, 1.0, 4.0, 25.0])
    r = 2.0
    gauss = -0.5 * e2 / r
    for nu, tol in ((1e4, 5e-3), (1e8, 1e-6)):  # the error is (e^2/r)^2 / (4 nu)
        assert student_t_loglik(e2, r, nu) == pytest.approx(gauss, abs=tol)
    # and its tails are polynomial: a 10-sigma residual costs 7.2 at nu = 4, not 50
    assert float(student_t_loglik(np.array([100.0]), 1.0, 4.0)[0]) == pytest.approx(
        -2.5 * np.log(26.0))


def test_the_student_t_exponent_of_a_gaussian_one_is_its_loglik_shifted():
    """:func:`student_t_exponent` (what the grid filters' compiled steps use) against
    :func:`student_t_loglik` of the same residuals, to round-off: a 10 sigma tail included."""
    rng = np.random.default_rng(3)
    e = rng.normal(0.0, 3.0, (40, 30))
    e[5, 7] = 10.0 * 1.5
    r = 2.25
    W = -0.5 * (e * e) / r
    top = student_t_exponent(W, 4.0)
    ref = student_t_loglik(e * e, r, 4.0)
    assert top == pytest.approx(ref.max(), rel=1e-14, abs=1e-14)
    np.testing.assert_allclose(W, ref - ref.max(), rtol=1e-13, atol=1e-13)
    assert W.max() == 0.0


def _z(model, x, depth_offset=0.0):
    z = np.asarray(model.h(x), dtype=float).copy()
    z[2] += depth_offset
    return z


@pytest.mark.parametrize("kind", ["pf", "point_mass", "pfm_psi"])
def test_a_large_nu_gives_the_gaussian_filter(model, kind):
    a, b = _make(model, kind), _make(model, kind, student_t_nu=1e9)
    truth = X0 + np.array([20.0, -15.0, 0.0, 0.0])
    for k in range(5):
        for f in (a, b):
            f.predict(U, 1.0)
            f.update(_z(model, truth, 0.3 * (-1) ** k))
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-3)
    np.testing.assert_allclose(b.P, a.P, rtol=1e-3, atol=1e-6)


@pytest.mark.parametrize("kind", ["pf", "point_mass", "pfm_psi"])
def test_a_robust_likelihood_shrugs_off_a_10_sigma_outlier(model, kind):
    """One sounder reading 10 sigma off (R = 1 m^2 plus the prior's spread of h) moves the
    Gaussian filter far more than the Student-t one (nu = 4)."""
    moves = {}
    for nu in (None, 4.0):
        f = _make(model, kind, **({} if nu is None else {"student_t_nu": nu}))
        f.predict(U, 1.0)
        x_prior = f.x.copy()
        f.update(_z(model, x_prior, 60.0))  # a multipath-like return, far in the tail
        moves[nu] = float(np.hypot(*(f.x[:2] - x_prior[:2])))
    assert moves[4.0] < 0.5 * moves[None]


@pytest.mark.parametrize("kind", ["ekf", "ukf", "ckf"])
def test_the_gate_rejects_a_10_sigma_outlier_and_keeps_the_rest(model, kind):
    f = _make(model, kind, gate_probability=0.9999)
    f.predict(U, 1.0)
    x, P = f.x.copy(), f.P.copy()
    H = np.asarray(model.H(x))
    s = float(np.sqrt(H[2] @ P @ H[2] + model.R[2, 2]))
    ref = _make(model, kind)  # the same filter updated with the velocities alone
    ref.predict(U, 1.0)
    z = _z(model, x, 10.0 * s)
    f.update(z)
    assert f.diagnostics["gated"] == 1.0
    ref.update(z, mask=np.array([True, True, False]))
    np.testing.assert_array_equal(f.x, ref.x)
    # a 1-sigma reading passes
    g = _make(model, kind, gate_probability=0.9999)
    g.predict(U, 1.0)
    g.update(_z(model, g.x, 1.0 * s))
    assert g.diagnostics["gated"] == 0.0


def test_without_the_gate_the_outlier_is_used(model):
    f = _make(model, "ekf")
    f.predict(U, 1.0)
    x = f.x.copy()
    f.update(_z(model, x, 100.0))
    assert "gated" not in f.diagnostics
    assert np.hypot(*(f.x[:2] - x[:2])) > 1.0


def test_gate_threshold_is_the_chi2_quantile():
    assert gate_threshold(0.9999) == pytest.approx(15.1367, rel=1e-4)
    assert gate_threshold(0.6827) == pytest.approx(1.0, rel=1e-3)
