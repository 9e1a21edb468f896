"""Estimators: one module per family, registered by name in :data:`ESTIMATORS`.

The grid filters (point mass, projection) and what only they use are in
:mod:`uwcosim.filters.grid`.
"""

from uwcosim.filters import (  # noqa: F401  (importing registers the estimators)
    kalman,
    particle,
    rbpf,
    regularized,
    settings,
    sigma_point,
    variational,
)
from uwcosim.filters.base import ESTIMATORS, Estimator, StateSpaceModel, register
from uwcosim.filters.grid import point_mass, projection  # noqa: F401

__all__ = ["ESTIMATORS", "Estimator", "StateSpaceModel", "register"]
