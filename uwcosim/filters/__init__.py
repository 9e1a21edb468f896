"""Estimators: one module per family, registered by name in :data:`ESTIMATORS`."""

from uwcosim.filters import kalman  # noqa: F401  (registers ekf, dead_reckoning)
from uwcosim.filters.base import ESTIMATORS, Estimator, StateSpaceModel, register

__all__ = ["ESTIMATORS", "Estimator", "StateSpaceModel", "register"]
