"""The RBPF's compiled kernels (:mod:`uwcosim.filters.rbpf_kernels`) against its numpy code:
the same filter up to round-off, with lost measurements and a split that reorders the states;
a matrix that is not positive definite leaves the particles alone and hands the step to the
numpy code."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.filters import rbpf_kernels as rk
from uwcosim.filters.rbpf import RaoBlackwellizedPF
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.models.trajectory import simulate

pytestmark = pytest.mark.skipif(not rk.ENABLED, reason="Numba not installed or disabled")

START = np.array([2000.0, 18000.0, 0.5, 0.0])
STD0 = np.array([30.0, 30.0, 0.05, 0.05])


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 200 else 0.0])


@pytest.fixture(scope="module")
def case():
    model = tan_model([0.05, 0.05, 1e-5, 1e-5], 0.05, 1.0, synthetic_bathymetry(7))
    rng = np.random.default_rng(3)
    _, _, zs = simulate(model.symbolic, START, controls, 150, rng)
    return model, zs, START + STD0 * rng.standard_normal(4)


def pair(case, linear_states):
    model, _, x0 = case
    fast, ref = (RaoBlackwellizedPF(model, x0, np.diag(STD0**2), n_particles=400, seed=5,
                                    linear_states=linear_states) for _ in range(2))
    ref.fast = False
    assert fast.fast
    return fast, ref


def steps(case, filters, n):
    """``n`` steps, the depth lost every 7th and the DVL every 11th; yields after each."""
    _, zs, _ = case
    for k in range(n):
        z = zs[k].copy()
        if k % 7 == 3:
            z[2] = np.nan
        if k % 11 == 5:
            z[:2] = np.nan
        for f in filters:
            f.predict(controls(k), 1.0)
            f.update(z)
        yield k


@pytest.mark.parametrize("linear_states", [None, ["vx"], []])
def test_compiled_and_numpy_rbpf_agree(case, linear_states):
    """Velocities marginalized (the default split) and only ``vx`` (states reordered to
    ``(x, y, vy | vx)``, the ``vy`` row measured by particles) and none (a plain PF with the
    RBPF's proposal): every step's estimate, Kalman
    covariance, particles, weights and diagnostics agree to round-off (measured: 2e-10
    relative at most over 150 steps)."""
    fast, ref = pair(case, linear_states)
    if linear_states:
        assert fast.ik == [2] and fast._perm is not None
    for _ in steps(case, (fast, ref), 150):
        np.testing.assert_allclose(fast.particles, ref.particles, rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(fast.logw, ref.logw, rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(fast.Pk, ref.Pk, rtol=1e-8, atol=1e-15)
        np.testing.assert_allclose(fast.x, ref.x, rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(fast.P, ref.P, rtol=1e-8, atol=1e-12)
        assert fast.diagnostics.keys() == ref.diagnostics.keys()
        for key, value in ref.diagnostics.items():
            assert fast.diagnostics[key] == pytest.approx(value, rel=1e-8, abs=1e-12), key


def test_refused_factorization_runs_the_numpy_code(case, monkeypatch):
    """When a kernel reports a matrix that is not positive definite the step is the numpy
    code's: with both kernels always refusing, the filter is the numpy filter bit for bit."""
    fast, ref = pair(case, None)
    monkeypatch.setattr(rk, "predict_step", lambda *a: (False, True))
    monkeypatch.setattr(rk, "update_step", lambda *a: (1, 0.0))
    for _ in steps(case, (fast, ref), 30):
        np.testing.assert_array_equal(fast.particles, ref.particles)
        np.testing.assert_array_equal(fast.P, ref.P)


def test_update_kernel_leaves_particles_alone_when_not_definite():
    """An indefinite ``R`` (code 1) returns before the particles and ``P`` are written. (Code
    2, an indefinite NIS covariance, needs ``M`` definite and is then round-off only.)"""
    rng = np.random.default_rng(0)
    n = 64
    X = rng.standard_normal((4, n))
    Pk = np.eye(2)
    X0, P0 = X.copy(), Pk.copy()
    got, _ = rk.update_step(rng.standard_normal((3, n)), np.zeros(3), np.arange(3),
                            np.diag([1.0, 1.0, -1.0]), np.eye(2), np.array([0, 1]), Pk, 2,
                            np.full(n, 1.0 / n), X, np.array([2, 3]), np.zeros((6, 5, 5)),
                            np.empty((7, n)), np.empty(n))
    assert got == 1
    np.testing.assert_array_equal(X, X0)
    np.testing.assert_array_equal(Pk, P0)
