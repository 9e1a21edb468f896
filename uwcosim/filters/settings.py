"""The settings of every filter, declared once: name, type, default and description.

Each filter registered in :data:`~uwcosim.filters.ESTIMATORS` has a pydantic model here (like
Stone Soup's ``Property`` declarations). The scenario loader validates ``[estimators.NAME]``
keys and values against it (:mod:`uwcosim.scenario.validate`: unknown keys list the valid ones,
wrong types name the key), ``uwcosim list estimators`` shows it with defaults and
descriptions, ``uwcosim schema`` exports it, and :func:`build` constructs the filter from the
validated values. The master's random stream (``rng``) is not a setting: a settings model says
``needs_rng = True`` and :func:`build` passes the stream.

Adding the settings of a new filter (registered as ``"rbpf"``) is a few lines::

    @settings_for("rbpf")
    class RBPFSettings(FilterSettings):
        n_particles: int = Field(500, ge=2, description="number of particles")
        measurements: Measurements = None
        needs_rng: ClassVar[bool] = True      # the filter takes the master's stream ``rng``

Field names are the keyword arguments of the filter's constructor and the defaults must be the
constructor's (``tests/test_validation.py`` checks both for every registered filter). Checks
that need the model (a measurement name, the memory of a grid) stay in the constructor and
surface in ``uwcosim check``, which builds the filters.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictFloat, StrictInt, StrictStr

from uwcosim.filters.base import ESTIMATORS, Estimator

#: ``measurements``: the measurement components a filter uses (default: all)
Measurements = list[StrictStr] | None
_MEAS = "measurement components to use (names of the model's measurements; default: all)"
_STATES = "gridded states, names or indices (default: chosen from the model structure)"


class FilterSettings(BaseModel):
    """Base of the settings models: unknown keys, NaN and infinity refused, types strict."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
    #: the filter takes the master's random stream as ``rng`` (not a setting)
    needs_rng: ClassVar[bool] = False


class NoSettings(FilterSettings):
    """The settings of a filter registered without a settings model: none."""


def settings_for(*names: str):
    """Class decorator: declare ``cls`` as the settings model of the filters ``names``."""

    def deco(cls: type[FilterSettings]) -> type[FilterSettings]:
        for name in names:
            ESTIMATORS.declare_settings(name, cls)
        return cls

    return deco


def settings_model(kind: str) -> type[FilterSettings]:
    """The settings model of the registered filter ``kind`` (:class:`NoSettings` when none is
    declared, e.g. a filter a user registers in Python without settings)."""
    return ESTIMATORS.settings(kind) or NoSettings


def settings_problems(kind: str, settings: dict[str, Any]) -> list[str]:
    """What is wrong with ``settings`` for filter ``kind``: one phrase per key."""
    from pydantic import ValidationError

    model = settings_model(kind)
    try:
        model.model_validate(settings)
    except ValidationError as exc:
        out = []
        for err in exc.errors():
            key = ".".join(str(p) for p in err["loc"])
            if err["type"] == "extra_forbidden":
                out.append(f"unknown setting {key!r} for estimator {kind!r} "
                           f"(valid: {', '.join(model.model_fields) or 'none'})")
            else:
                out.append(f"setting {key!r} = {err.get('input')!r}: {err['msg']}")
        return out
    return []


def build(kind: str, model, x0, P0, settings: dict[str, Any], rng=None) -> Estimator:
    """Construct filter ``kind`` from settings already validated by :func:`settings_model`.

    Only the keys the scenario gives are passed (the constructor's defaults are the declared
    ones); ``rng`` goes to filters whose settings model ``needs_rng``."""
    cls = ESTIMATORS.get(kind)
    kwargs = dict(settings)
    if settings_model(kind).needs_rng and rng is not None:
        kwargs["rng"] = rng
    return cls(model, x0, P0, **kwargs)


class MeasurementsOnly(FilterSettings):
    measurements: Measurements = Field(None, description=_MEAS)


settings_for("kf", "ekf", "ckf")(MeasurementsOnly)


@settings_for("dead_reckoning")
class DeadReckoningSettings(FilterSettings):
    measurements: Measurements = Field(
        None, description="measurement components to integrate (default: the velocities)")


@settings_for("ukf")
class UKFSettings(FilterSettings):
    alpha: StrictFloat = Field(1.0, gt=0, description="spread of the sigma points (1: the "
                               "whole uncertainty ellipsoid; 1e-3 nearly an EKF)")
    beta: StrictFloat = Field(2.0, description="prior knowledge of the distribution "
                              "(2: optimal for Gaussian priors)")
    kappa: StrictFloat = Field(0.0, description="secondary scaling parameter")
    measurements: Measurements = Field(None, description=_MEAS)


@settings_for("cukf")
class CUKFSettings(FilterSettings):
    a: StrictFloat | None = Field(None, gt=0, description="sigma-point scale of eq. (7) "
                                  "(default sqrt(3/L))")
    redraw: StrictBool = Field(False, description="redraw the measurement points from the "
                               "predicted moments (eqs. 10-13)")
    measurements: Measurements = Field(None, description=_MEAS)


class CloudSettings(FilterSettings):
    """What the particle filters (``pf``, ``rbpf``, ``rpf``) share."""

    n_particles: StrictInt = Field(1000, ge=2, description="number of particles")
    resampling: Literal["systematic", "stratified", "residual", "multinomial"] = Field(
        "systematic", description="resampling scheme")
    ess_threshold: StrictFloat = Field(0.5, ge=0, le=1, description="resample when the "
                                       "effective sample size falls below this fraction of N")
    needs_rng: ClassVar[bool] = True


@settings_for("pf")
class ParticleSettings(CloudSettings):
    roughening: StrictFloat = Field(0.0, ge=0, description="Gordon et al.'s K: jitter after "
                                    "resampling (0 = off)")
    measurements: Measurements = Field(None, description=_MEAS)


@settings_for("vbakf")
class VariationalSettings(FilterSettings):
    tau: StrictFloat = Field(3.0, ge=0, description="tuning of the prior dof of P_{k|k-1}")
    rho: StrictFloat = Field(1.0 - math.exp(-4.0), gt=0, le=1,
                             description="forgetting factor of the R estimate")
    iterations: StrictInt = Field(10, ge=1, description="maximum VB iterations per update")
    tol: StrictFloat = Field(1e-6, ge=0, description="stop when the state moves less than tol "
                             "posterior standard deviations")
    u0: StrictFloat | None = Field(None, description="initial dof of R (default m + 2; must "
                                   "exceed m + 1)")
    measurements: Measurements = Field(None, description=_MEAS)


@settings_for("qivbf")
class QIVBFSettings(VariationalSettings):
    """``qivbf`` = ``vbakf`` + the ``extrapolate`` policy built in: its settings plus these."""

    extrapolate: Literal["runs", "isolated"] = Field(
        "runs", description="extrapolate every lost component with three earlier receipts "
        "(runs), or only a single loss after three receipts (isolated, seed 001 Assumption 1)")
    inflate_r: StrictBool = Field(False, description="inflate R of an extrapolated component "
                                  "by the Lagrange noise gain (our correction, not the paper's)")


@settings_for("rbpf")
class RBPFSettings(CloudSettings):
    linear_states: list[StrictStr] | None = Field(
        None, description="the Kalman (marginalized) states (default: from the model)")
    measurements: Measurements = Field(None, description=_MEAS)


@settings_for("rpf")
class RegularizedSettings(CloudSettings):
    bandwidth_scale: StrictFloat = Field(1.0, ge=0, description="times the optimal Gaussian "
                                         "kernel bandwidth")
    shrink: StrictBool = Field(False, description="Liu-West shrinkage (keeps the cloud's mean "
                               "and covariance)")
    measurements: Measurements = Field(None, description=_MEAS)


@settings_for("point_mass")
class PointMassSettings(FilterSettings):
    n_points: StrictInt | list[StrictInt] = Field(101, description="grid points per gridded "
                                                  "state (>= 5; one value or one per state)")
    span: StrictFloat = Field(8.0, gt=0, description="half-width of the grid in standard "
                              "deviations")
    states: list[StrictStr | StrictInt] | None = Field(None, description=_STATES)
    measurements: Measurements = Field(None, description=_MEAS)
    long_run: StrictBool = Field(True, description="conditional Kalman filter of the other "
                                 "states in its long-run form")


@settings_for("pfm_psi")
class ProjectionSettings(FilterSettings):
    K: StrictInt = Field(10, ge=1, description="highest harmonic per dimension")
    k_sigma: StrictFloat = Field(4.0, gt=0, description="half-width of the box (eq. 33) in "
                                 "predicted standard deviations")
    states: list[StrictStr | StrictInt] | None = Field(None, description=_STATES)
    measurements: Measurements = Field(None, description=_MEAS)
    grid_factor: StrictFloat = Field(2.5, ge=2, description="quadrature points per basis "
                                     "function and dimension")
    positivity: Literal["auto", "none", "threshold", "clip", "product", "jackson"] = Field(
        "auto", description="treatment of negative lobes of the truncated series")
    spectral_filter: StrictFloat = Field(0.0, ge=0, description="even order of an "
                                         "exponential filter (0 = off)")
    long_run: StrictBool = Field(True, description="conditional Kalman filter of the other "
                                 "states in its long-run form")
    min_halfwidth: StrictFloat = Field(0.0, ge=0, description="floor of the box half-width")
    resolution_inflation: StrictFloat = Field(1.0, ge=0, description="inflate R by the "
                                              "variation of h within a resolution cell (1 = on)")
    refine: StrictFloat = Field(0.7, gt=0, description="redo the product on the "
                                "posterior box below this width ratio (1 = off)")
    neg_limit: StrictFloat = Field(0.1, ge=0, description="negative mass above which 'auto' "
                                   "thresholds")
    moment_match: StrictBool = Field(True, description="give the series the grid "
                                     "posterior's mean and covariance after a threshold")
    gate: StrictFloat = Field(5.0, ge=0, description="implausible-measurement gate in "
                              "standard deviations (0 = off)")
