"""How a filter declares its settings: once, on its class, as a pydantic model.

A filter class carries its settings as ``Settings``, a :class:`FilterSettings` subclass (as
Stone Soup declares properties on the class): name, type, default and description of every
keyword the constructor takes, and nothing else. The constructor validates them
(:meth:`uwcosim.filters.base.Estimator.validate_settings`: unknown keys list the valid ones,
types are strict) and keeps them as ``self.settings``; the scenario loader validates
``[estimators.NAME]`` against the same model (:mod:`uwcosim.scenario.validate`),
``uwcosim list estimators`` shows it and ``uwcosim schema`` exports it. The master's random
stream (``rng``) is not a setting: a filter that draws says ``needs_rng = True`` on its class.

A filter of one's own declares its settings the same way (named in a scenario by import path,
``type = "mypkg.filters:GatedEKF"``, or by an entry point of ``uwcosim.estimators``:
:mod:`uwcosim.filters.plugins`, ``docs/your_own_filter.md``; ``@register`` is for a name in
this process)::

    class GatedEKF(ExtendedKalmanFilter):
        class Settings(FilterSettings):
            gate: float = Field(5.0, gt=0, description="gate in standard deviations")
            measurements: Measurements = measurements_field()

        def __init__(self, model, x0, P0, **settings):
            super().__init__(model, x0, P0, **settings)
            self.gate = self.settings.gate

Checks that need the model (a measurement name, the memory of a grid) stay in the constructor
and surface in ``uwcosim check``, which builds the filters.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, StrictStr, ValidationError

#: ``measurements``: the measurement components a filter uses (default: all)
Measurements = list[StrictStr] | None
MEASUREMENTS = "measurement components to use (names of the model's measurements; default: all)"
STATES = "gridded states, names or indices (default: chosen from the model structure)"


class FilterSettings(BaseModel):
    """Base of the settings models: unknown keys, NaN and infinity refused, types strict.

    Without fields of its own it is the settings of a filter that takes none."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True, frozen=True)


def measurements_field(description: str = MEASUREMENTS) -> Any:
    """The ``measurements`` setting (default: all components)."""
    return Field(None, description=description)


def settings_problems(model: type[FilterSettings], kind: str,
                      settings: dict[str, Any]) -> list[str]:
    """What is wrong with ``settings`` for filter ``kind`` (its settings ``model``): one phrase
    per key."""
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
