"""Point-mass (grid) Bayes filter: the reference posterior of terrain navigation.

The density of the gridded states ``p`` (all states of a low-dimensional model; the position of
the TAN model, whose velocities are handled by the conditional Kalman filter of
:mod:`uwcosim.filters.grid.conditional`, exactly as in ``pfm_psi``) lives on a regular grid
spanning ``mean -+ span * sigma``, chosen anew at every prediction from the predicted mean and
covariance (:mod:`~uwcosim.filters.point_mass.grid`). The prediction carries the density to
the new grid (:mod:`~uwcosim.filters.point_mass.prediction`), the update multiplies it by the
likelihood on the grid (:mod:`~uwcosim.filters.point_mass.bayes`); the frame of the steps
(partition, Kalman block, ``predict``, ``update``) is
:class:`~uwcosim.filters.grid.estimator.GridFilter`, shared with ``pfm_psi``.

Each step has a numpy form (any number of gridded states) and a compiled form (two gridded
states; Numba, :mod:`uwcosim.core.jit`), chosen once when the filter is built
(:attr:`PointMassFilter.fast`); they give the same results to round-off
(``tests/test_projection_kernels.py``).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, StrictBool, StrictFloat, StrictInt, StrictStr
from scipy import ndimage

from uwcosim.core.memory import memory_problem
from uwcosim.filters.base import register
from uwcosim.filters.grid.estimator import GridFilter
from uwcosim.filters.point_mass.bayes import BayesUpdate
from uwcosim.filters.point_mass.bayes_kernels import CompiledBayesUpdate
from uwcosim.filters.point_mass.grid import GridDensity
from uwcosim.filters.point_mass.prediction import Prediction
from uwcosim.filters.point_mass.prediction_kernels import CompiledPrediction
from uwcosim.filters.robust import StudentTNu, student_t_field
from uwcosim.filters.settings import MEASUREMENTS, STATES, FilterSettings, Measurements


@register("point_mass")
class PointMassFilter(GridFilter):
    """Grid (point-mass) Bayes filter with a grid re-centred on the support every step."""

    class Settings(FilterSettings):
        n_points: StrictInt | list[StrictInt] = Field(101, description="grid points per gridded "
                                                      "state (>= 5; one value or one per state)")
        span: StrictFloat = Field(8.0, gt=0, description="half-width of the grid in standard "
                                  "deviations")
        states: list[StrictStr | StrictInt] | None = Field(None, description=STATES)
        measurements: Measurements = Field(None, description=MEASUREMENTS)
        long_run: StrictBool = Field(True, description="conditional Kalman filter of the other "
                                     "states in its long-run form")
        student_t_nu: StudentTNu = student_t_field()  # filters.robust

    size_key = "n_points"

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)  # the partition, Kalman block, likelihood
        s = self.settings
        n = len(self.part.p)
        n_points = [int(v) for v in np.broadcast_to(np.asarray(s.n_points), (n,))]
        if min(n_points) < 5:
            raise ValueError("n_points must be >= 5")
        need = float(np.prod(np.asarray(n_points, dtype=float))) * 8.0 * (2 * n + 6)
        why = memory_problem(need, f"n_points {n_points}", "use fewer points")
        if why:  # the grid, its mesh and work arrays (uwcosim.core.memory)
            raise ValueError(why)
        mean, cov = self.gridded_prior()
        #: the density of the gridded states on its grid, and its moments
        self.density = GridDensity(self.kind, s.span, n_points, mean, cov)
        if self.fast:
            self.prediction = CompiledPrediction(self.part, self.kalman, self.density)
            self.bayes = CompiledBayesUpdate(self.likelihood, self.kalman, self.model.R)
        else:
            self.prediction = Prediction(self.part, self.kalman)
            self.bayes = BayesUpdate(self.likelihood, self.kalman)
        self.begin(self.prediction.translate if self.part.drift_constant
                   else self.prediction.chapman_kolmogorov, mean, cov)

    # ------------------------------------------------------------------------------------------
    @property
    def values(self) -> np.ndarray:
        """The density's values on the grid."""
        return self.density.values

    @property
    def axes(self) -> list[np.ndarray]:
        """The grid's axes."""
        return self.density.axes

    def representation(self) -> tuple[float, list[float], list[float]]:
        axes = self.density.axes
        return (float(self.density.values.size), [a.item(0) for a in axes],
                [a.item(-1) for a in axes])

    # ------------------------------------------------------------------------------------------
    def density_grid(self, axes=None, n: int | None = None):
        """Posterior density on a tensor grid: ``(axes, values)`` (default: the filter's grid).

        Other ``axes`` are served by cubic interpolation (zero outside the grid); ``n`` asks for
        ``n`` points per dimension across the grid.
        """
        density = self.density
        if axes is None and n is None:
            return [a.copy() for a in density.axes], density.values.copy()
        if axes is None:
            axes = [np.linspace(a[0], a[-1], n) for a in density.axes]
        axes = [np.asarray(a, dtype=float) for a in axes]
        coords = [(a - density.axes[d][0]) / density.spacing[d] for d, a in enumerate(axes)]
        mesh = np.meshgrid(*coords, indexing="ij")
        vals = ndimage.map_coordinates(density.values, mesh, order=3, mode="constant",
                                       cval=0.0)
        return axes, np.maximum(vals, 0.0)
