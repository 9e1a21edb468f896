"""The estimation library: Bayesian filters behind one interface, registered by name.

One module per family (``kalman``, ``sigma_point``, ``particle``, ``rbpf``, ``regularized``,
``variational``), the grid filters PFM-PSI in :mod:`uwcosim.filters.projection` and the point
mass in :mod:`uwcosim.filters.point_mass`, with what they share in :mod:`uwcosim.filters.grid`;
the interface and the registry :data:`ESTIMATORS` in ``base``, a user's filter named by
import path or entry point in ``plugins``, how a filter declares its settings in
``settings``, the lost-measurement policies in ``policies`` and the covariance numerics in
``numerics``. The filters see their model only through
:class:`uwcosim.models.protocol.StateSpaceModel`.

Importing the package declares every built-in filter (:data:`BUILT_IN`: its name and the
module that registers it): a filter's module is imported on the first lookup of its name
(:meth:`uwcosim.core.registry.Registry.declare`), so a run imports the filters it uses and
their dependencies only (the grid filters' scipy modules, the particle filters' kernels).
:meth:`ESTIMATORS.load_all() <uwcosim.core.registry.Registry.load_all>` imports them all.
"""

from uwcosim.filters import plugins  # noqa: F401  (installs the fallback: a user's filter)
from uwcosim.filters.base import ESTIMATORS, Estimator, StateSpaceModel, build, register
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field

#: the built-in filters: registry name -> the module whose import registers it
BUILT_IN = {
    "kf": "uwcosim.filters.kalman",
    "ekf": "uwcosim.filters.kalman",
    "dead_reckoning": "uwcosim.filters.kalman",
    "ukf": "uwcosim.filters.sigma_point",
    "ckf": "uwcosim.filters.sigma_point",
    "cukf": "uwcosim.filters.sigma_point",
    "pf": "uwcosim.filters.particle",
    "rpf": "uwcosim.filters.regularized",
    "rbpf": "uwcosim.filters.rbpf",
    "vbakf": "uwcosim.filters.variational",
    "qivbf": "uwcosim.filters.variational",
    "point_mass": "uwcosim.filters.point_mass.filter",
    "pfm_psi": "uwcosim.filters.projection.filter",
}
for _name, _module in BUILT_IN.items():
    ESTIMATORS.declare(_name, _module)

__all__ = ["BUILT_IN", "ESTIMATORS", "Estimator", "FilterSettings", "Measurements",
           "StateSpaceModel", "build", "measurements_field", "register"]
