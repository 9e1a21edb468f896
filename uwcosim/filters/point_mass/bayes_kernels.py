"""Compiled form of the point-mass filter's Bayes update (two gridded states, a terrain-depth
row: the TAN model): :class:`CompiledBayesUpdate`.

:func:`terrain_exponent` (the terrain row's log-likelihood on the grid, from the map's
:class:`~uwcosim.filters.grid.likelihood.TerrainMap`; Gaussian, made Student-t by
:func:`~uwcosim.filters.robust.student_t_exponent` with ``student_t_nu``), then, after numpy's
``exp``,
:func:`grid_product_moments` (the normalized product and its moments); without a grid row the
moments alone (:func:`~uwcosim.filters.grid.moments.moments2_ordered`). The same quantities as
:class:`~uwcosim.filters.point_mass.bayes.BayesUpdate` to round-off
(``tests/test_projection_kernels.py``).
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit, jit_fast
from uwcosim.core.reductions import max2, row_sum
from uwcosim.filters.grid.likelihood import terrain_depth
from uwcosim.filters.grid.moments import moments2, moments2_marginals, moments2_ordered
from uwcosim.filters.point_mass.bayes import BayesUpdate
from uwcosim.filters.point_mass.grid import GridDensity, scale_values
from uwcosim.filters.robust import student_t_exponent


@jit_fast
def terrain_exponent(xs, ys, terrain, z, var, shift):
    """``ll - max(ll)`` of the terrain row on the grid ``xs x ys``, ``ll = -(h - z)^2 / (2
    var)`` with ``h`` the depth on the map ``terrain``, and ``max(ll)``; without ``shift``,
    ``ll`` itself and 0 (the Student-t likelihood's input,
    :func:`~uwcosim.filters.robust.student_t_exponent`)."""
    h = terrain_depth(xs, ys, terrain)
    c = -0.5 / var  # one division, not one per point (round-off: 1 ulp of the exponent)
    for i in range(h.shape[0]):
        for j in range(h.shape[1]):
            e = h[i, j] - z
            h[i, j] = (e * e) * c
    if not shift:
        return h, 0.0
    tmax = max2(h)
    h -= tmax
    return h, tmax


@jit
def grid_product_moments(values, lik, cell, xs, ys):
    """``post = values * lik`` normalized, its mass ``Z`` and moments (point-mass update).

    When the mass is not finite and positive, ``post`` is ``values`` unchanged (the update is
    skipped, ``Z`` is returned for the caller to report)."""
    Mx, My = values.shape
    post = np.empty((Mx, My))
    m0 = np.zeros(Mx)
    m1 = np.zeros(My)
    for i in range(Mx):
        for j in range(My):
            p = values[i, j] * lik[i, j]
            post[i, j] = p
            m1[j] += p
        m0[i] = row_sum(post, i, False)
    Z = m0.sum() * cell
    if math.isfinite(Z) and Z > 0.0:
        scale_values(post, 1.0 / Z)
        m0 /= Z
        m1 /= Z
        mean, cov = moments2_marginals(post, m0, m1, xs, ys)
    else:
        post = values
        mean, cov = moments2(post, xs, ys, False)
    return post, Z, mean, cov


class CompiledBayesUpdate(BayesUpdate):
    """:class:`~uwcosim.filters.point_mass.bayes.BayesUpdate` with the product of one terrain
    row and the moments compiled (other rows: the numpy form's product)."""

    compiled = True

    def __init__(self, likelihood, kalman, R: np.ndarray) -> None:
        super().__init__(likelihood, kalman)
        self._var = [float(v) for v in np.diag(R)]
        # the maps as the kernels take them (jit: plain tuples)
        self._maps = {r: tuple(tg.map) for r, tg in likelihood.terrain_rows.items()}

    def product(self, density: GridDensity, z, rows_g: list[int], x, diag: dict) -> None:
        if not (len(rows_g) == 1 and rows_g[0] in self._maps):
            super().product(density, z, rows_g, x, diag)
            return
        r = rows_g[0]
        ax = density.axes
        nu = self.likelihood.nu
        E, llmax = terrain_exponent(ax[0], ax[1], self._maps[r], float(z[r]), self._var[r],
                                    nu is None)
        if nu is not None:  # the Student-t likelihood (filters.robust)
            llmax = student_t_exponent(E, nu)
        np.exp(E, out=E)
        post, Z, density.mean, density.cov = grid_product_moments(density.values, E,
                                                                  density.cell, ax[0], ax[1])
        if math.isfinite(Z) and Z > 0:
            density.values = post
            diag["loglik"] = math.log(Z) + llmax
        else:
            diag["update_skipped"] = 1.0

    def moments(self, density: GridDensity) -> tuple[np.ndarray, np.ndarray]:
        ax = density.axes
        return moments2_ordered(density.values, ax[0], ax[1])
