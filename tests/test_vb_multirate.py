"""VB-AKF and QIVBF with sensors at different rates: partial updates of the inverse-Wishart
``U`` of ``R`` keep it positive definite (:func:`uwcosim.filters.variational.partial_iw_update`),
reduce to the old update where they should, and the filter stays consistent."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from uwcosim.filters.numerics import symmetrize
from uwcosim.filters.variational import (
    ExtrapolatingVBAKF,
    VariationalBayesAKF,
    partial_iw_update,
    vb_update,
)
from uwcosim.models.linear import seed001_model

try:
    from test_filters_vb import X0
    from test_filters_vb import simulate as simulate_with_r
except ImportError:  # tests/ imported as a package
    from tests.test_filters_vb import X0
    from tests.test_filters_vb import simulate as simulate_with_r


def simulate(model, steps, seed):
    """Truth and measurements of the seed 001 model (H = I, R = I: the truth's R is known)."""
    return simulate_with_r(model, np.array(model.R), steps, seed)


def two_rate_mask(k, period=5):
    """Sensor A (components 0, 1) every step, sensor B (2, 3) every ``period`` steps."""
    b = k % period == 0
    return np.array([True, True, b, b])


def run(cls, zs, mask_of, on_step=None):
    est = cls(seed001_model(), X0, np.eye(4))
    for k, z in enumerate(zs):
        est.predict(None, 1.0)
        est.t = k + 1.0
        mask = mask_of(k)
        est.update(np.where(mask, z, np.nan), mask)
        if on_step is not None:
            on_step(k, est)
    return est


def old_partial(U, idx, U_oo):
    """The block write-back before the fix: the observed block replaced, cross terms kept."""
    out = U.copy()
    out[np.ix_(idx, idx)] = U_oo
    return symmetrize(out)


@pytest.mark.parametrize("seed", [6, 7])
def test_two_sensors_at_two_rates_are_not_stopped(seed):
    # before the fix: U's smallest eigenvalue went negative over the A-only steps and the
    # filter was stopped ("covariance not positive definite") at step 10 for both seeds
    _, zs = simulate(seed001_model(), 30, seed)
    smallest = []
    run(VariationalBayesAKF, zs, two_rate_mask,
        lambda k, est: smallest.append(np.linalg.eigvalsh(est.U).min()))
    assert len(smallest) == 30
    assert min(smallest) > 0.0


@pytest.mark.parametrize("cls", [VariationalBayesAKF, ExtrapolatingVBAKF])
@pytest.mark.parametrize("seed", range(12))
def test_U_stays_symmetric_positive_definite_over_a_long_multirate_run(cls, seed):
    rng = np.random.default_rng(1000 + seed)
    period = int(rng.integers(2, 9))
    lost = rng.random((400, 4)) < 0.1  # and some single components lost at random

    def mask_of(k):
        return two_rate_mask(k, period) & ~lost[k]

    _, zs = simulate(seed001_model(), 400, seed)

    def check(k, est):
        np.testing.assert_array_equal(est.U, est.U.T)
        assert np.linalg.eigvalsh(est.U).min() > 0.0, f"step {k}"
        assert np.linalg.eigvalsh(est.P).min() > 0.0, f"step {k}"

    run(cls, zs, mask_of, check)


def test_partial_update_keeps_the_unobserved_block_and_its_schur_complement():
    rng = np.random.default_rng(5)
    A = rng.standard_normal((5, 5))
    U = A @ A.T + 0.1 * np.eye(5)
    idx = np.array([1, 3])
    rest = np.array([0, 2, 4])
    B = rng.standard_normal((2, 2))
    U_oo = 0.3 * (B @ B.T + 0.01 * np.eye(2))  # a smaller observed block: broke the old rule
    new = partial_iw_update(U, idx, U_oo)
    np.testing.assert_array_equal(new[np.ix_(idx, idx)], symmetrize(U_oo))
    np.testing.assert_array_equal(new[np.ix_(rest, rest)], U[np.ix_(rest, rest)])

    def schur(M):
        return M[np.ix_(rest, rest)] - M[np.ix_(rest, idx)] @ np.linalg.solve(
            M[np.ix_(idx, idx)], M[np.ix_(idx, rest)])

    np.testing.assert_allclose(schur(new), schur(U), rtol=1e-10, atol=1e-12)
    assert np.linalg.eigvalsh(new).min() > 0.0
    assert np.linalg.eigvalsh(old_partial(U, idx, U_oo)).min() < 0.0  # the defect


def test_partial_update_without_cross_terms_is_the_old_update_bit_for_bit():
    rng = np.random.default_rng(2)
    U = np.zeros((4, 4))
    for block in ([0, 1], [2, 3]):  # block-diagonal: independent sensors
        A = rng.standard_normal((2, 2))
        U[np.ix_(block, block)] = A @ A.T + np.eye(2)
    idx = np.array([0, 1])
    A = rng.standard_normal((2, 2))
    U_oo = A @ A.T + np.eye(2)
    np.testing.assert_array_equal(partial_iw_update(U, idx, U_oo), old_partial(U, idx, U_oo))


def test_full_measurements_give_the_old_update_bit_for_bit():
    # all sensors at every step: the filter is Huang's Algorithm 1 as before the fix, written
    # out here from vb_update and the time update of eqs. 14-15
    model = seed001_model()
    _, zs = simulate(model, 50, seed=4)
    vb = run(VariationalBayesAKF, zs, lambda k: np.ones(4, dtype=bool))
    x, P, m = X0.copy(), np.eye(4), 4
    u = m + 2.0
    U = (u - m - 1.0) * np.array(model.R)
    rho = vb.rho
    for z in zs:
        F, Q = model.F(x, None, 1.0), model.Q(x, None, 1.0)
        x = model.f(x, None, 1.0)
        P = symmetrize(F @ P @ F.T + Q)
        u, U = rho * (u - m - 1.0) + m + 1.0, rho * U
        res = vb_update(x, P, z - model.h(x), model.H(x), u, U)
        x, P, u, U = res.x, res.P, res.u, res.U
    np.testing.assert_array_equal(vb.x, x)
    np.testing.assert_array_equal(vb.P, P)
    np.testing.assert_array_equal(vb.U, U)
    assert vb.u == u


@pytest.mark.parametrize("settings", [
    {"cls": VariationalBayesAKF},
    # qivbf with seed 001's Assumption 1 (only isolated losses extrapolated). With the default
    # "runs" the four-step extrapolations of sensor B make it overconfident here (mean NEES
    # 8.6, with inflate_r 13.0, out of the band): a property of the extrapolation, not of U
    {"cls": ExtrapolatingVBAKF, "extrapolate": "isolated"},
], ids=["vbakf", "qivbf_isolated"])
def test_multirate_filter_is_consistent(settings):
    # NEES at the last step of independent runs (the truth's R is the nominal R = I): its mean
    # over N runs times N is chi-square with 4 N dof for a consistent filter; two-sided 99.9%
    runs, steps, n = 60, 150, 4
    settings = dict(settings)
    cls = settings.pop("cls")
    nees = []
    for seed in range(runs):
        xs, zs = simulate(seed001_model(), steps, 100 + seed)
        est = run(lambda *a: cls(*a, **settings), zs, two_rate_mask)
        e = xs[-1] - est.x
        nees.append(e @ np.linalg.solve(est.P, e))
    low, high = stats.chi2.ppf([0.0005, 0.9995], n * runs) / runs
    assert low <= np.mean(nees) <= high, (np.mean(nees), low, high)


def test_a_non_positive_definite_block_is_a_divergence():
    from uwcosim.core.errors import FilterDivergence

    with pytest.raises(FilterDivergence, match="U of R"):
        partial_iw_update(np.eye(3), np.array([0, 1]), -np.eye(2))
