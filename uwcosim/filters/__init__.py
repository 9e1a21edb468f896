"""Estimators: one module per family, registered by name in :data:`ESTIMATORS`."""

from uwcosim.filters import (  # noqa: F401  (importing registers the estimators)
    kalman,
    particle,
    point_mass,
    projection,
    rbpf,
    regularized,
    settings,
    sigma_point,
    variational,
)
from uwcosim.filters.base import ESTIMATORS, Estimator, StateSpaceModel, register

__all__ = ["ESTIMATORS", "Estimator", "StateSpaceModel", "register"]
