"""The Hellinger distance keeps a density's mass outside the window (issue 25, section 1)."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.evaluation.density import gaussian_on_grid, particles_on_grid
from uwcosim.evaluation.distance import hellinger


def window():
    axes = [np.linspace(-6.0, 6.0, 161)] * 2
    cell = float((axes[0][1] - axes[0][0]) ** 2)
    return axes, cell


def test_mass_outside_the_window_counts_as_disjoint():
    """Half of q's mass far outside the window: the true distance is sqrt(1 - 1/sqrt 2); the
    renormalized estimator sees q's window part, which is p itself, and says 0."""
    axes, cell = window()
    p = gaussian_on_grid([0.0, 0.0], np.eye(2), axes)
    q = 0.5 * p  # the other half of q sits at +-1 km, outside the window
    assert hellinger(p, q) == pytest.approx(0.0, abs=1e-7)
    assert hellinger(p, q, cell=cell) == pytest.approx(np.sqrt(1 - 1 / np.sqrt(2)), rel=1e-6)


def test_cell_form_agrees_where_all_mass_is_inside():
    axes, cell = window()
    p = gaussian_on_grid([0.0, 0.0], np.eye(2), axes)
    q = gaussian_on_grid([0.3, -0.2], np.diag([1.2, 0.8]), axes)
    assert hellinger(p, q, cell=cell) == pytest.approx(hellinger(p, q), abs=1e-4)
    assert hellinger(p, p, cell=cell) == pytest.approx(0.0, abs=1e-4)  # Riemann sum


def test_particles_outside_the_window_are_not_forgiven():
    """A cloud with 30 % of its particles beyond the window is at least that far from p."""
    axes, cell = window()
    rng = np.random.default_rng(3)
    X = rng.standard_normal((20_000, 2))
    X[:6000] += 500.0
    p = gaussian_on_grid([0.0, 0.0], np.eye(2), axes)
    q = particles_on_grid(X, np.ones(len(X)), axes, bandwidth=0.3)
    kept, dropped = hellinger(p, q, cell=cell), hellinger(p, q)
    assert dropped < 0.1
    assert kept ** 2 >= 1 - np.sqrt(0.7) - 0.01
