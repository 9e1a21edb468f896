"""Position marginals on a common grid (uwcosim.evaluation.density)."""

from __future__ import annotations

import numpy as np

from uwcosim.evaluation.density import (
    gaussian_on_grid,
    grid_around,
    particles_on_grid,
    silverman_bandwidth,
)
from uwcosim.evaluation.distance import hellinger


def test_gaussian_and_kde_agree_on_a_gaussian():
    mean, cov = np.array([10.0, -5.0]), np.array([[4.0, 1.5], [1.5, 2.0]])
    axes = grid_around(mean, cov, n=121)
    g = gaussian_on_grid(mean, cov, axes)
    sp = [a[1] - a[0] for a in axes]
    assert abs(g.sum() * sp[0] * sp[1] - 1.0) < 1e-6
    rng = np.random.default_rng(0)
    X = rng.multivariate_normal(mean, cov, 50_000)
    kde = particles_on_grid(X, np.ones(len(X)), axes)
    assert abs(kde.sum() * sp[0] * sp[1] - 1.0) < 1e-3
    assert hellinger(g, kde) < 0.03
    # weights matter: the same points weighted towards x > mean move the density
    w = np.where(X[:, 0] > mean[0], 3.0, 1.0)
    assert hellinger(g, particles_on_grid(X, w, axes)) > 0.1
    # Silverman: sd * n_eff^(-1/6)
    np.testing.assert_allclose(silverman_bandwidth(X, np.ones(len(X))),
                               np.sqrt(np.diag(cov)) * 50_000 ** (-1 / 6), rtol=0.02)
