"""The lean helpers of the Kalman-family steps agree with the plain formulas they replace.

``symmetrize_``, ``joseph_update`` (with a kept identity), the sigma-point set as one product
and the mean/covariance as ``np.dot`` give the same bits as the written-out formulas;
``gain_and_nis`` (one solve for the gain and the NIS) agrees with ``kalman_gain`` + ``nis`` to
round-off (the LAPACK solve may order a multi-column solve differently).
"""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.filters.numerics import (
    gain_and_nis,
    joseph_update,
    kalman_gain,
    nis,
    symmetrize,
    symmetrize_,
)
from uwcosim.filters.sigma_point import cubature_rule, cukf_unscented_rule, unscented_rule


def _spd(n, rng, scale=1.0):
    A = rng.standard_normal((n, n)) * scale
    return A @ A.T + n * np.eye(n) * scale**2


def test_symmetrize_in_place_gives_the_same_bits():
    rng = np.random.default_rng(0)
    for n in (1, 2, 4, 7):
        A = rng.standard_normal((n, n)) * 1e3
        ref = symmetrize(A)
        B = A.copy()
        out = symmetrize_(B)
        assert out is B and np.array_equal(out, ref) and np.array_equal(out, out.T)


def test_joseph_with_kept_identity_gives_the_plain_formula():
    rng = np.random.default_rng(1)
    P, R = _spd(4, rng, 10.0), _spd(3, rng)
    H, K = rng.standard_normal((3, 4)), rng.standard_normal((4, 3))
    IKH = np.eye(4) - K @ H
    ref = symmetrize(IKH @ P @ IKH.T + K @ R @ K.T)
    assert np.array_equal(joseph_update(P, K, H, R, np.eye(4)), ref)
    assert np.array_equal(joseph_update(P, K, H, R), ref)


@pytest.mark.parametrize("m", [1, 2, 3])
def test_gain_and_nis_agree_with_separate_solves(m):
    rng = np.random.default_rng(m)
    P, R = _spd(4, rng, 30.0), _spd(m, rng, 0.1)
    H = rng.standard_normal((m, 4))
    PHt = P @ H.T
    S = H @ PHt + R
    y = rng.standard_normal(m)
    K_ref, cho = kalman_gain(PHt, S)
    K, v = gain_and_nis(PHt, S, y)
    np.testing.assert_allclose(K, K_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(v, nis(y, cho), rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(v, y @ np.linalg.solve(S, y), rtol=1e-10)


def test_gain_and_nis_repairs_an_indefinite_S_and_counts_it():
    S = np.array([[1.0, 1.0], [1.0, 1.0]])  # singular: jittered
    counter = {}
    K, v = gain_and_nis(np.eye(2), S, np.array([1.0, -1.0]), counter)
    assert counter["pd_repairs"] == 1.0 and np.isfinite(K).all() and v > 0


@pytest.mark.parametrize("rule", [unscented_rule(4), unscented_rule(4, 0.3, 2.0, 1.0),
                                  cubature_rule(4), cukf_unscented_rule(4, 0.8)])
def test_sigma_points_and_moments_give_the_written_out_bits(rule):
    rng = np.random.default_rng(2)
    x = np.array([2000.0, 18000.0, 0.5, -0.1])
    L = np.linalg.cholesky(_spd(4, rng, 20.0))
    n, c = rule.n, int(rule.center)
    ref = np.empty((2 * n + c, n))
    ref[:] = x
    sL = rule.scale * L.T
    ref[c:c + n] += sL
    ref[c + n:] -= sL
    X = rule.points(x, L)
    assert np.array_equal(X, ref)
    Y = X**2 / 1e3
    m, P, D = rule.moments(Y)
    m_ref = Y[0] + rule.wm @ (Y - Y[0])
    assert np.array_equal(m, m_ref)
    assert np.array_equal(D, Y - m_ref)
    assert np.array_equal(P, ((Y - m_ref).T * rule.wc) @ (Y - m_ref))
