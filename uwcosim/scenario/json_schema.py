"""The JSON Schema of the scenario format (``uwcosim schema``), for editors.

Generated from the pydantic schema (:mod:`uwcosim.scenario.schema`) with, for
``[estimators.NAME]``, one variant per registered filter (its common keys and its own settings,
:mod:`uwcosim.filters.settings`) chosen by ``type``, so that an editor completes and checks the
settings of the filter named. Use it from a TOML language server (taplo, the VS Code extension
Even Better TOML) with a first line ``#:schema ./scenario.schema.json`` in a scenario.
"""

from __future__ import annotations

import json
from typing import Annotated, Any, Literal, Union

from pydantic import ConfigDict, Field, create_model

from uwcosim.filters import ESTIMATORS
from uwcosim.filters.base import settings_model
from uwcosim.filters.policies import POLICIES
from uwcosim.scenario.schema import FMU, EstimatorSpec, ReplayRunSpec, Scenario

SCHEMA_ID = "https://uwcosim.invalid/scenario.schema.json"


def _estimator_variants() -> Any:
    common = {n: (f.annotation, f) for n, f in EstimatorSpec.model_fields.items() if n != "type"}
    common["policy"] = (Literal[tuple(POLICIES.names())], Field(
        "skip", description="what the filter does with lost measurements"))
    variants = []
    for kind in ESTIMATORS.names():
        settings = settings_model(kind)
        fields = {n: (f.annotation, f) for n, f in settings.model_fields.items()}
        cls = ESTIMATORS.get(kind)
        doc = (cls.__doc__ or kind).strip().splitlines()[0]
        variants.append(create_model(
            f"Estimator_{kind}", __config__=ConfigDict(extra="forbid", title=f"{kind}: {doc}"),
            type=(Literal[kind], Field(description=doc)), **common, **fields))
    return Annotated[Union[tuple(variants)], Field(discriminator="type")]  # noqa: UP007


def scenario_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario file."""
    # one schema for both kinds of scenario: a replay's [run] has no step and no [fmus]
    # (what depends on [replay] is left to uwcosim check)
    model = create_model("Scenario", __base__=Scenario,
                         estimators=(dict[str, _estimator_variants()], {}),
                         run=(ReplayRunSpec, ...), fmus=(dict[str, FMU], {}))
    out = model.model_json_schema()
    out = {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
           "title": "uwcosim scenario",
           "description": "A uwcosim scenario (TOML); see the README's 'Scenario format'.",
           **{k: v for k, v in out.items() if k not in ("title", "description")}}
    return out


def scenario_json_schema_text() -> str:
    return json.dumps(scenario_json_schema(), indent=2, sort_keys=False) + "\n"
