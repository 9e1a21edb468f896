"""The truth's seafloor when it is not the filters' map (no inverse crime).

The filters' map is a survey of the seafloor; the seafloor the DepthSounder FMU measures is
the survey's spline plus what the survey got wrong::

    h_true(x, y) = h_base(x, y) + r(x, y) + e(x, y)      (on the truth's grid)

- ``h_base``: the survey's B-spline evaluated at the nodes of the truth's grid (its own extent
  and resolution: e.g. twice as fine), or another map altogether (a different seed or file);
- ``r``: fine-scale relief the survey did not resolve, a Gaussian-correlated field of standard
  deviation ``fine_relief_m`` and correlation length ``fine_scale_m``;
- ``e``: the survey's error, a Gaussian-correlated field of standard deviation ``std_m`` and
  correlation length ``correlation_m``.

A correlated field (:func:`correlated_field`) is white Gaussian noise on the grid smoothed by a
Gaussian kernel of standard deviation ``L / sqrt(2)`` (so its correlation is
``rho(d) = exp(-d^2 / (2 L^2))`` away from the edges) and scaled to the standard deviation
asked for over the grid. Its generator is one of the run's seeded streams
(:mod:`uwcosim.core.rng`): every run of a campaign sees a different realization, the same seed
the same one. The map error as the filters see it is ``h_map - h_true = -(r + e)`` at the
nodes, up to the re-interpolation of the truth's own spline.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from uwcosim.models.terrain import Bathymetry


def correlated_field(rng: np.random.Generator, shape: tuple[int, int], spacing: float,
                     std: float, correlation: float) -> np.ndarray:
    """A zero-mean Gaussian field on a ``shape`` grid of ``spacing`` (m): standard deviation
    ``std`` (m) over the grid, Gaussian correlation of length ``correlation`` (m)."""
    w = rng.standard_normal(shape)
    if std == 0.0:
        return np.zeros(shape)
    sigma_k = correlation / (np.sqrt(2.0) * spacing)  # kernel std (cells): rho = exp(-d^2/2L^2)
    f = ndimage.gaussian_filter(w, sigma_k, mode="reflect") if sigma_k > 0 else w
    f -= f.mean()
    sd = f.std()
    return f * (std / sd) if sd > 0 else np.zeros(shape)


def grid_nodes(extent: tuple[float, float, float, float],
               resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """The node coordinates ``x``, ``y`` of a regular grid over ``extent``."""
    xmin, xmax, ymin, ymax = (float(v) for v in extent)
    nx = int(round((xmax - xmin) / resolution)) + 1
    ny = int(round((ymax - ymin) / resolution)) + 1
    return xmin + resolution * np.arange(nx), ymin + resolution * np.arange(ny)


def truth_bathymetry(base: Bathymetry, extent: tuple[float, float, float, float],
                     resolution: float, *, fine_relief_m: float = 0.0,
                     fine_scale_m: float = 0.0, survey_std_m: float = 0.0,
                     survey_correlation_m: float = 500.0,
                     fine_rng: np.random.Generator | None = None,
                     survey_rng: np.random.Generator | None = None) -> Bathymetry:
    """The truth's map: ``base`` at the nodes of the grid (``extent``, ``resolution``) plus the
    fine relief (drawn from ``fine_rng``) and the survey error (from ``survey_rng``)."""
    x, y = grid_nodes(extent, resolution)
    X, Y = np.meshgrid(x, y)
    depth = base.depth(X, Y)
    if fine_relief_m > 0.0:
        depth = depth + correlated_field(fine_rng, depth.shape, resolution, fine_relief_m,
                                         fine_scale_m)
    if survey_std_m > 0.0:
        depth = depth + correlated_field(survey_rng, depth.shape, resolution, survey_std_m,
                                         survey_correlation_m)
    return Bathymetry(float(x[0]), float(y[0]), resolution, resolution, depth)
