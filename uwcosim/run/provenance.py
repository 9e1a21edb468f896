"""Which user code a run used: the log's metadata key ``user_code``.

For every estimator whose type is not a built-in filter (a class imported by path, an entry
point, or one a user's module registered) and for a ``[model] type`` builder, the
:class:`~uwcosim.core.plugins.Origin` record: the type string, ``module:Name``, the module's
file and its sha256, the distribution and version providing it, and the folder it was imported
from. A run with only built-in code has no such key (its log is what it was before user code
could be named). The reproduce command (:mod:`uwcosim.reports.reproduce`) reads it.
"""

from __future__ import annotations

from uwcosim.filters.plugins import estimator_origin
from uwcosim.models.builder import builder_origin
from uwcosim.scenario.schema import Scenario


def user_code(spec: Scenario) -> dict:
    """``{"estimators": {NAME: origin}, "model": origin}`` of the scenario's user code (only
    the parts it has; empty without any)."""
    out: dict = {}
    estimators = {}
    for name, es in spec.estimators.items():
        origin = estimator_origin(es.type)
        if origin.source != "built-in":
            estimators[name] = origin.record()
    if estimators:
        out["estimators"] = estimators
    if spec.model is not None and spec.model.type is not None:
        out["model"] = builder_origin(spec.model.type).record()
    return out
