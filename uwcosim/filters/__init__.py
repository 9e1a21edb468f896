"""The estimation library: Bayesian filters behind one interface, registered by name.

One module per family (``kalman``, ``sigma_point``, ``particle``, ``rbpf``, ``regularized``,
``variational``), the grid filters PFM-PSI in :mod:`uwcosim.filters.projection` and the point
mass in :mod:`uwcosim.filters.point_mass`, with what they share in :mod:`uwcosim.filters.grid`;
the interface and the registry :data:`ESTIMATORS` in ``base``, a user's filter named by
import path or entry point in ``plugins``, how a filter declares its settings in
``settings``, the lost-measurement policies in ``policies`` and the covariance numerics in
``numerics``. The filters see their model only through
:class:`uwcosim.models.protocol.StateSpaceModel`. Importing the package registers every
built-in filter.
"""

from uwcosim.filters import (  # noqa: F401  (importing registers the estimators)
    kalman,
    particle,
    plugins,
    rbpf,
    regularized,
    sigma_point,
    variational,
)
from uwcosim.filters.base import ESTIMATORS, Estimator, StateSpaceModel, build, register
from uwcosim.filters.point_mass.filter import PointMassFilter  # noqa: F401  (registers)
from uwcosim.filters.projection.filter import ProjectionFilter  # noqa: F401  (registers)
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field

__all__ = ["ESTIMATORS", "Estimator", "FilterSettings", "Measurements", "StateSpaceModel",
           "build", "measurements_field", "register"]
