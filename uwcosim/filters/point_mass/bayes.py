"""The point-mass filter's Bayes update: the prior grid values times the likelihood of the
gridded measurement rows (:class:`~uwcosim.filters.grid.likelihood.GridLikelihood`),
normalized, and the moments of the posterior grid (:func:`~uwcosim.filters.grid.moments.
axes_moments`). A product without mass (a measurement the grid cannot explain) skips the
update (diagnostic ``update_skipped``).

:class:`BayesUpdate` is the numpy form; :class:`~uwcosim.filters.point_mass.bayes_kernels.
CompiledBayesUpdate` computes the product with one terrain row and the moments in compiled
kernels.
"""

from __future__ import annotations

import numpy as np

from uwcosim.filters.grid.conditional import ConditionalKalman
from uwcosim.filters.grid.likelihood import GridLikelihood
from uwcosim.filters.grid.moments import axes_moments
from uwcosim.filters.point_mass.grid import GridDensity


class BayesUpdate:
    """The point-mass update, numpy form (any number of gridded states)."""

    #: the step runs compiled kernels
    compiled = False

    def __init__(self, likelihood: GridLikelihood, kalman: ConditionalKalman) -> None:
        self.likelihood = likelihood
        self.kalman = kalman

    def update(self, density: GridDensity, x: np.ndarray, z, rows_k: list[int],
               rows_g: list[int], diag: dict) -> tuple[np.ndarray, np.ndarray, bool]:
        """The update of ``density`` (in place) and of the Kalman block with the available
        rows of ``z`` (``rows_k`` of the Kalman block, ``rows_g`` of the grid), at the prior
        estimate ``x``; returns the posterior's ``(x, P, finite)``."""
        self.kalman.update(x, z, rows_k, diag)
        self.product(density, z, rows_g, x, diag)
        return self.kalman.assemble(density.mean, density.cov)

    def product(self, density: GridDensity, z, rows_g: list[int], x, diag: dict) -> None:
        """``values = p(z | x) values / Z`` on the grid and the posterior moments."""
        if rows_g:
            post = self.likelihood.loglik(density.axes, z, rows_g, x)
            llmax = float(post.max())
            post -= llmax
            np.exp(post, out=post)
            post *= density.values
            Z = float(post.sum() * density.cell)
            if np.isfinite(Z) and Z > 0:
                post /= Z
                density.values = post
                diag["loglik"] = float(np.log(Z) + llmax)
            else:
                diag["update_skipped"] = 1.0
        density.mean, density.cov = self.moments(density)

    def moments(self, density: GridDensity) -> tuple[np.ndarray, np.ndarray]:
        """Mean and covariance of the grid density."""
        return axes_moments(density.axes, density.values)
