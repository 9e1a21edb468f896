"""Lost-measurement policies: skip, zero (seed 001 eq. 2), extrapolate (seed 001 eq. 28)."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.filters.policies import POLICIES, lagrange_extrapolate

NAN = np.nan


def test_registry_lists_valid_names_on_a_typo():
    with pytest.raises(ScenarioError, match="extrapolate, skip, zero"):
        POLICIES.get("extrapolat", where="s.toml: key 'estimators.ekf.policy'")


def test_skip_passes_the_measurement_through():
    p = POLICIES.get("skip")(3)
    z, m = p(1.0, np.array([1.0, NAN, 3.0]), np.array([True, False, False]))
    np.testing.assert_array_equal(m, [True, False, False])
    np.testing.assert_array_equal(z[[0, 2]], [1.0, 3.0])
    z, m = p(2.0, None, None)
    assert z is None and not m.any()


def test_zero_feeds_zeros_for_lost_components():
    p = POLICIES.get("zero")(3)
    z, m = p(1.0, np.array([1.0, NAN, 3.0]), np.array([True, True, False]))
    np.testing.assert_array_equal(z, [1.0, 0.0, 0.0])
    assert m.all()
    z, m = p(2.0, None, None)  # eq. (2): Y_k = 0
    np.testing.assert_array_equal(z, np.zeros(3))
    assert m.all()


def test_lagrange_through_three_points_is_exact_on_a_quadratic():
    def q(t):
        return np.array([2.0 - 0.5 * t + 0.25 * t**2, -3.0 + 4.0 * t**2])

    ts = [0.3, 1.1, 2.6]  # irregular times
    ys = [q(t) for t in ts]
    for t in (3.0, 4.7, 10.0):
        np.testing.assert_allclose(lagrange_extrapolate(ts, ys, t), q(t), rtol=1e-12)


def test_extrapolate_fills_lost_components_from_received_history():
    def q(t):
        return np.array([1.0 + 2.0 * t - 0.3 * t**2, 5.0 - t])

    p = POLICIES.get("extrapolate")(2)
    times = [0.0, 0.5, 1.5]
    for t in times:
        z, m = p(t, q(t), np.array([True, True]))
        assert m.all()
    # component 1 lost at 2.0, all lost at 3.2: both from the three received values only
    z, m = p(2.0, np.array([q(2.0)[0], NAN]), np.array([True, False]))
    assert m.all()
    np.testing.assert_allclose(z, q(2.0), rtol=1e-12)
    assert p.extrapolated == 1
    z, m = p(3.2, None, None)
    assert m.all() and p.extrapolated == 2
    np.testing.assert_allclose(z, q(3.2), rtol=1e-12)
    # history holds received values only: component 1 still ends at t = 1.5
    assert [t for t, _ in p.history[1]] == times
    assert [t for t, _ in p.history[0]] == [0.5, 1.5, 2.0]


def test_extrapolate_needs_three_received_values():
    p = POLICIES.get("extrapolate")(1)
    p(0.0, np.array([1.0]), None)
    p(1.0, np.array([2.0]), None)
    z, m = p(2.0, np.array([NAN]), np.array([True]))  # NaN counts as lost
    assert not m.any() and p.extrapolated == 0
    p(2.0, np.array([3.0]), None)
    z, m = p(3.0, None, None)
    assert m.all()
    np.testing.assert_allclose(z, [4.0], rtol=1e-12)


def test_extrapolate_same_instant_replaces_the_value():
    p = POLICIES.get("extrapolate")(1)
    for t, v in ((0.0, 0.0), (1.0, 1.0), (2.0, 9.0), (2.0, 4.0)):
        p(t, np.array([v]), None)
    z, _ = p(3.0, None, None)
    np.testing.assert_allclose(z, [9.0], rtol=1e-12)  # t^2 through (0, 0), (1, 1), (2, 4)
