"""``uwcosim list estimators|models|scenarios|fmus``: what is available, from the registries.

- estimators: every filter with where it comes from (built-in; an entry point of
  ``uwcosim.estimators`` with its distribution and version; a scenario's
  ``package.module:ClassName``, with ``--scenario``; one a user's module registered), the first
  sentence of its docstring (whole, however the docstring wraps it) and its settings (its
  settings model, :mod:`uwcosim.filters.settings`): name, type, default and description; first
  the keys every estimator takes (:data:`COMMON_KEYS`: ``type``, ``policy``, ``sensors``,
  ``initial_std``, the fields of :class:`uwcosim.scenario.schema.EstimatorSpec`);
- models: the built-in filter models (``[model] kind``) and the installed builders (entry
  points of ``uwcosim.models``, ``[model] type``);
- scenarios: the shipped scenarios (:func:`uwcosim.core.paths.scenarios_dir`), name and
  description;
- fmus: the project's FMU models, their description, and the built archives found in ``fmus/``
  of the checkout or the demo's cache folder.
"""

from __future__ import annotations

import re
import tomllib
import types
from pathlib import Path
from typing import Annotated, Literal, Union, get_args, get_origin

from pydantic_core import PydanticUndefined

from uwcosim.core.errors import ScenarioError
from uwcosim.core.paths import cache_dir, project_root, scenarios_dir
from uwcosim.filters.base import settings_model
from uwcosim.filters.plugins import estimator_names, estimator_origin, resolve_estimator
from uwcosim.filters.policies import POLICIES
from uwcosim.fmu.build import FMI_VERSIONS, archive_name
from uwcosim.fmu.specs import MODELS
from uwcosim.models.builder import model_types
from uwcosim.scenario.json_schema import scenario_estimator_types
from uwcosim.scenario.schema import EstimatorSpec

#: the keys of ``[estimators.NAME]`` that every estimator takes (the fields of
#: :class:`~uwcosim.scenario.schema.EstimatorSpec`), what they do
COMMON_KEYS = {
    "type": "the filter: one of the names below (or 'package.module:ClassName')",
    "policy": "what the filter is fed when a measurement is lost (uwcosim.filters.policies)",
    "sensors": "the sensors whose measurements it uses (default: every sensor of [model] "
               "sensors)",
    "initial_std": "its own initial standard deviations, one per state (default: "
                   "[estimation] initial_std)",
}


def _type_name(t) -> str:
    """A settings type as a reader writes it: ``int``, ``list[str] | None``, ``'a' | 'b'``."""
    origin, args = get_origin(t), get_args(t)
    if origin is Annotated:
        return _type_name(args[0])
    if origin in (Union, types.UnionType):
        return " | ".join(_type_name(a) for a in args)
    if origin is Literal:
        return " | ".join(repr(a) for a in args)
    if origin is list:
        return f"list[{_type_name(args[0])}]"
    return "None" if t is type(None) else getattr(t, "__name__", str(t))


def estimator_settings(kind: str) -> list[tuple[str, str, object, str]]:
    """``[(setting, type, default, description)]`` of the registered filter ``kind``."""
    model = settings_model(kind)
    return [(n, _type_name(f.annotation),
             "required" if f.default is PydanticUndefined else f.default, f.description or "")
            for n, f in model.model_fields.items()]


def summary(doc: str | None) -> str:
    """The first sentence of a docstring's first paragraph, joined across its wrapped lines
    (without its final period)."""
    lines = []
    for line in (doc or "").strip().splitlines():
        if not line.strip():
            break
        lines.append(line.strip())
    text = " ".join(lines)
    m = re.search(r"(?<!e\.g)(?<!i\.e)(?<!eq)(?<!\bal)\.(\s|$)", text)
    return (text[:m.start()] if m else text).rstrip(".")


def common_keys() -> list[str]:
    """The lines of :data:`COMMON_KEYS`: ``key=default (type): what it does``."""
    out = []
    for key, what in COMMON_KEYS.items():
        info = EstimatorSpec.model_fields[key]
        typ = _type_name(info.annotation)
        if key == "policy":
            typ = " | ".join(repr(n) for n in POLICIES.names())
        out.append(f"    {key} ({typ}, required): {what}" if info.is_required() else
                   f"    {key}={info.default!r} ({typ}): {what}")
    return out


def list_estimators(scenario: str | Path | None = None) -> str:
    """Every filter (with ``scenario``: also its ``package.module:ClassName`` types), where it
    comes from, and its settings, after the keys every estimator takes. An installed entry
    point that fails to load is listed with its error."""
    extra = scenario_estimator_types(scenario) if scenario is not None else []
    lines = ["every estimator ([estimators.NAME] of a scenario) takes:", *common_keys(),
             "and its own settings:"]
    for name in dict.fromkeys([*estimator_names(), *extra]):
        try:
            cls = resolve_estimator(name)
            origin = estimator_origin(name).label()
        except ScenarioError as exc:
            lines.append(f"{name}: cannot be loaded: {exc}")
            continue
        lines.append(f"{name}: {summary(cls.__doc__)} [{origin}]")
        settings = estimator_settings(name)
        if not settings:
            lines.append("    settings: none")
        for setting, typ, default, doc in settings:
            lines.append(f"    {setting} ({typ}, required): {doc}" if default == "required"
                         else f"    {setting}={default!r} ({typ}): {doc}")
    return "\n".join(lines)


def list_models() -> str:
    """The built-in filter models and the installed model builders."""
    return "\n".join(f"{name}: {what}" for name, what in model_types().items())


def list_scenarios(directory: Path | None = None) -> str:

    directory = Path(directory) if directory is not None else scenarios_dir()
    lines = []
    for path in sorted(directory.glob("*.toml")):
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError) as exc:
            lines.append(f"{path.stem}: unreadable ({exc})")
            continue
        lines.append(f"{data.get('name', path.stem)}: {data.get('description', '')}")
        lines.append(f"    {path}")
    return "\n".join(lines) if lines else f"no scenarios in {directory}"


def list_fmus() -> str:

    places = [d for d in ((project_root() or Path("/nonexistent")) / "fmus",
                          cache_dir() / "fmus") if d.is_dir()]
    lines = []
    for name, make in MODELS.items():
        lines.append(f"{name}: {make().description}")
        for v in FMI_VERSIONS:
            found = [d / archive_name(name, v) for d in places
                     if (d / archive_name(name, v)).is_file()]
            where = ", ".join(str(p) for p in found) or "not built ('uwcosim fmu build')"
            lines.append(f"    FMI {v}: {archive_name(name, v)}: {where}")
    return "\n".join(lines)
