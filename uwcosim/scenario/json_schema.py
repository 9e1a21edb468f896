"""The JSON Schema of the scenario format (``uwcosim schema``), for editors.

Generated from the pydantic schema (:mod:`uwcosim.scenario.schema`) with, for
``[estimators.NAME]``, one variant per filter (its common keys and its own settings,
:mod:`uwcosim.filters.settings`) chosen by ``type``, so that an editor completes and checks the
settings of the filter named: every registered filter, every installed entry point of
``uwcosim.estimators`` (:mod:`uwcosim.filters.plugins`) and the user's classes of a scenario
given with ``uwcosim schema --scenario FILE`` (its ``package.module:ClassName`` types, imported
as a run imports them). Any other ``package.module:ClassName`` type is accepted with any
settings (``Estimator_import_path``: what it takes is known only once it is imported; ``uwcosim
check`` checks it). Use it from a TOML language server (taplo, the VS Code extension Even
Better TOML) with a first line ``#:schema ./scenario.schema.json`` in a scenario.
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import ConfigDict, Field, create_model

from uwcosim.core.errors import ScenarioError
from uwcosim.core.plugins import IMPORT_PATH, is_import_path
from uwcosim.core.tomlfile import read_toml
from uwcosim.filters.plugins import estimator_names, resolve_estimator
from uwcosim.filters.policies import POLICIES
from uwcosim.filters.settings import FilterSettings
from uwcosim.scenario.schema import FMU, EstimatorSpec, ReplayRunSpec, Scenario
from uwcosim.scenario.validate import search_dirs

SCHEMA_ID = "https://uwcosim.invalid/scenario.schema.json"
#: the variant of a ``package.module:ClassName`` type not known when the schema was made
IMPORT_PATH_VARIANT = "Estimator_import_path"

log = logging.getLogger(__name__)


def _def_name(kind: str) -> str:
    return f"Estimator_{re.sub(r'[^A-Za-z0-9_]', '_', kind)}"


def scenario_estimator_types(path: str | Path) -> list[str]:
    """The ``package.module:ClassName`` estimator types of a scenario file, imported (as a
    run imports them: the scenario's folder and the current folder on ``sys.path``)."""
    where = str(path)
    _, data = read_toml(path, "scenario", where)
    estimators = data.get("estimators") if isinstance(data.get("estimators"), dict) else {}
    out = []
    for name, raw in estimators.items():
        kind = raw.get("type") if isinstance(raw, dict) else None
        if is_import_path(kind) and kind not in out:
            try:
                resolve_estimator(kind, search_dirs(where))
            except ScenarioError as exc:
                raise ScenarioError(f"{where}: key 'estimators.{name}.type': {exc}") from None
            out.append(kind)
    return out


def _estimator_variants(extra: list[str]) -> tuple[Any, list[str]]:
    common = {n: (f.annotation, f) for n, f in EstimatorSpec.model_fields.items() if n != "type"}
    common["policy"] = (Literal[tuple(POLICIES.names())], Field(
        "skip", description="what the filter does with lost measurements"))
    variants, kinds = [], []
    for kind in [*estimator_names(), *extra]:
        if kind in kinds:
            continue
        try:
            cls = resolve_estimator(kind)
        except ScenarioError as exc:  # a broken installed entry point: not in the schema
            log.warning("%s (left out of the schema)", exc)
            continue
        settings = getattr(cls, "Settings", FilterSettings)
        fields = {n: (f.annotation, f) for n, f in settings.model_fields.items()}
        doc = (cls.__doc__ or kind).strip().splitlines()[0]
        variants.append(create_model(
            _def_name(kind), __config__=ConfigDict(extra="forbid", title=f"{kind}: {doc}"),
            type=(Literal[kind], Field(description=doc)), **common, **fields))
        kinds.append(kind)
    return Annotated[Union[tuple(variants)], Field(discriminator="type")], kinds  # noqa: UP007


def _import_path_variant(schema: dict, known: list[str]) -> None:
    """Accept any other ``package.module:ClassName`` type, with any settings."""
    est = schema["properties"]["estimators"]["additionalProperties"]
    est["oneOf"].append({"$ref": f"#/$defs/{IMPORT_PATH_VARIANT}"})
    type_schema: dict = {"type": "string", "pattern": IMPORT_PATH.pattern,
                         "description": "a class of yours, imported by path"}
    paths = [k for k in known if is_import_path(k)]
    if paths:
        type_schema["not"] = {"enum": paths}
    schema["$defs"][IMPORT_PATH_VARIANT] = {
        "title": "package.module:ClassName: a filter of yours (its settings are checked by "
                 "uwcosim check)",
        "type": "object", "properties": {"type": type_schema}, "required": ["type"],
        "additionalProperties": True}


def scenario_json_schema(extra_types: list[str] | tuple[str, ...] = ()) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario file; ``extra_types``: user's estimator
    types (``package.module:ClassName``, resolved already) to give variants of their own."""
    variants, kinds = _estimator_variants(list(extra_types))
    # one schema for both kinds of scenario: a replay's [run] has no step and no [fmus]
    # (what depends on [replay] is left to uwcosim check)
    model = create_model("Scenario", __base__=Scenario, estimators=(dict[str, variants], {}),
                         run=(ReplayRunSpec, ...), fmus=(dict[str, FMU], {}))
    out = model.model_json_schema()
    _import_path_variant(out, kinds)
    out = {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
           "title": "uwcosim scenario",
           "description": "A uwcosim scenario (TOML); see the README's 'Scenario format'.",
           **{k: v for k, v in out.items() if k not in ("title", "description")}}
    return out


def scenario_json_schema_text(extra_types: list[str] | tuple[str, ...] = ()) -> str:
    return json.dumps(scenario_json_schema(extra_types), indent=2, sort_keys=False) + "\n"
