"""One validation pass over a scenario's data that reports every problem, not only the first.

This is the first of ``uwcosim check``'s three levels, each a list of one-line
:class:`Problem` s naming the file, the key and what was expected (the other two need the FMUs
and the filters' model: :mod:`uwcosim.run.preflight`):

1. :func:`validate_data` (at load time, :func:`uwcosim.scenario.load_scenario`): every schema
   error of the data (all pydantic errors, one line per key), every ``[estimators.NAME]``
   against its filter's settings model (:mod:`uwcosim.filters.settings`: unknown keys list the
   valid ones) and lost-measurement policy, and the cross-references that need no FMU
   (``model.sensors``/``controls``, ``estimators.NAME.sensors``, the shape of the filters'
   model, a map for a depth sensor). ``load_scenario`` raises the first with
   ``(and N more; see uwcosim check)``.
2. the FMUs' model descriptions; 3. the map, the filters' model and every filter built.

After validation the estimator bank and the model factory trust their input.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from uwcosim.core.errors import FMUError, ScenarioError, UwcosimError
from uwcosim.filters.base import settings_model
from uwcosim.filters.plugins import resolve_estimator
from uwcosim.filters.policies import POLICIES
from uwcosim.filters.settings import FilterSettings
from uwcosim.models.builder import resolve_builder
from uwcosim.models.states import MODEL_STATES
from uwcosim.scenario import schema
from uwcosim.scenario.geo import geo_problems
from uwcosim.scenario.replay import replay_problems
from uwcosim.scenario.schema import EstimatorSpec, Scenario, scenario_model


@dataclass(frozen=True)
class Problem:
    """One problem: a one-line message and the exit status it maps to (2 scenario, 3 FMU)."""

    message: str
    exit_code: int = 2

    @classmethod
    def of(cls, exc: UwcosimError) -> Problem:
        return cls(str(exc), exc.exit_code)


def first_error(problems: list[Problem]) -> UwcosimError:
    """The first problem as an exception, saying how many more there are."""
    p = problems[0]
    more = f" (and {len(problems) - 1} more; see uwcosim check)" if len(problems) > 1 else ""
    exc = FMUError if p.exit_code == 3 else ScenarioError
    err = exc(p.message + more)
    err.exit_code = p.exit_code
    return err


# -- level 1: the schema ------------------------------------------------------------------------
def _is_record(v: Any) -> bool:
    """A pydantic model or a pydantic dataclass (the system layer's records)."""
    return isinstance(v, type) and (issubclass(v, BaseModel)
                                    or (dataclasses.is_dataclass(v)
                                        and hasattr(v, "__pydantic_fields__")))


def _fields(model: Any) -> dict:
    """The fields of a record (model or pydantic dataclass)."""
    return getattr(model, "model_fields", None) or getattr(model, "__pydantic_fields__", {})


_MODEL_NAMES = {n for n, v in vars(schema).items() if _is_record(v)}
_TAG = re.compile(r"^(float|int|bool|str|none|[a-z-]+\[.*\])$")


def _is_tag(part: Any) -> bool:
    """A union member's tag in a pydantic error location (not a key of the scenario)."""
    return isinstance(part, str) and (bool(_TAG.match(part)) or part in _MODEL_NAMES
                                      or part in ("bernoulli", "gilbert_elliott"))


def _submodel(loc: tuple, root: type[BaseModel]) -> type[BaseModel] | None:
    """The pydantic model that owns the key at ``loc`` (for 'expected one of')."""
    model: Any = root
    for part in loc[:-1]:
        if isinstance(part, int) or model is None:
            continue
        fld = _fields(model).get(part)
        if fld is None:
            continue
        ann = fld.annotation
        args = getattr(ann, "__args__", ())
        candidates = [a for a in (ann, *args) if _is_record(a)]
        model = candidates[0] if candidates else None
    return model


def _got(value: Any) -> str:
    got = repr(value)
    return got if len(got) <= 60 else got[:57] + "..."


def schema_problems(exc: ValidationError, where: str, root: type[BaseModel] = Scenario,
                    prefix: tuple = (),
                    unknown: str = "unknown key (expected one of: {valid})") -> list[Problem]:
    """One line per key of a pydantic error (a value refused by every member of a union is one
    line listing the types it may have); ``unknown``: the message of an unknown key."""
    by_key: dict[tuple, list[dict]] = {}
    for err in exc.errors():
        loc = tuple(p for p in err["loc"] if not _is_tag(p))
        by_key.setdefault(loc, []).append(err)
    out = []
    for loc, errs in by_key.items():
        key = ".".join(str(p) for p in (*prefix, *loc)) or "(top level)"
        err = errs[0]
        etype = err["type"]
        if etype in ("extra_forbidden", "unexpected_keyword_argument"):
            owner = _submodel(loc, root)
            valid = ", ".join(_fields(owner)) if owner is not None else ""
            msg = f"key '{key}': " + unknown.format(valid=valid or "none")
        elif etype == "missing":
            msg = f"key '{key}': required key is missing"
        elif len(errs) > 1 and all(e["type"].endswith("_type") for e in errs):
            kinds = [str(e["loc"][-1]).split("[")[0] for e in errs if _is_tag(e["loc"][-1])]
            msg = (f"key '{key}': invalid type (expected {' or '.join(dict.fromkeys(kinds))}; "
                   f"got {_got(err.get('input'))})")
        elif "input" in err and etype != "value_error":
            msg = f"key '{key}': {err['msg']} (got {_got(err['input'])})"
        else:
            msg = f"key '{key}': {err['msg']}"
        out.append(Problem(f"{where}: {msg}"))
    return out


def format_validation_error(exc: ValidationError, where: str,
                            root: type[BaseModel] = Scenario) -> str:
    """The first problem of a pydantic error, one line (and how many more there are)."""
    problems = schema_problems(exc, where, root)
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    return problems[0].message + more


def search_dirs(where: str) -> tuple[Path, Path]:
    """Where a user's module named ``package.module:Name`` in the scenario file ``where`` is
    looked for (in front of ``sys.path`` for its import): the scenario's folder, then the
    current folder."""
    return Path(where).resolve().parent, Path.cwd()


def estimator_problems(data: dict, where: str) -> list[Problem]:
    """``[estimators.NAME]`` of the raw data: filter type (a registered filter, a user's class
    ``package.module:ClassName`` imported with :func:`search_dirs`, or an entry point:
    :mod:`uwcosim.filters.plugins`), policy and the filter's settings (the settings model
    declared on its class, :mod:`uwcosim.filters.settings`)."""
    out: list[Problem] = []
    estimators = data.get("estimators")
    if not isinstance(estimators, dict):
        return out
    common = set(EstimatorSpec.model_fields)
    for name, raw in estimators.items():
        if not isinstance(raw, dict):
            continue  # the schema says so
        key = f"estimators.{name}"
        kind, policy = raw.get("type"), raw.get("policy", "skip")
        if isinstance(policy, str) and policy not in POLICIES:
            out.append(Problem(f"{where}: key '{key}.policy': unknown lost-measurement policy "
                               f"{policy!r} (valid: {', '.join(POLICIES.names())})"))
        if not isinstance(kind, str):
            continue
        try:
            cls = resolve_estimator(kind, search_dirs(where))
        except ScenarioError as exc:
            out.append(Problem(f"{where}: key '{key}.type': {exc}"))
            continue
        model = getattr(cls, "Settings", FilterSettings)
        settings = {k: v for k, v in raw.items() if k not in common}
        try:
            model.model_validate(settings)
        except ValidationError as exc:
            out += schema_problems(exc, where, model, ("estimators", name),
                                   f"unknown setting for estimator {kind!r} (valid: {{valid}})")
    return out


def validated_settings(spec: EstimatorSpec) -> dict[str, Any]:
    """The filter settings of a validated ``[estimators.NAME]``, as the scenario gives them."""
    extra = dict(spec.model_extra or {})
    model = settings_model(spec.type).model_validate(extra)
    return model.model_dump(include=set(extra))


def reference_problems(spec: Scenario, where: str) -> list[Problem]:
    """Cross-references between sections that need no FMU."""
    out: list[str] = []
    if spec.estimators and spec.model is None:
        out.append("key 'model': required when estimators are given")
    m = spec.model
    if m is not None:
        if m.type is None:
            out += state_problems(spec, MODEL_STATES[m.kind], f"{m.kind} model")
        else:  # the states are known once the model is built (uwcosim.run.factory)
            try:
                resolve_builder(m.type, search_dirs(where))
            except ScenarioError as exc:
                out.append(f"key 'model.type': {exc}")
        for c in m.controls if spec.replay is None else ():  # a replay's: replay_problems
            if c not in spec.controls:
                out.append(f"key 'model.controls': unknown control {c!r} "
                           f"(controls: {', '.join(spec.controls)})")
        known = [s for s in m.sensors if s in spec.sensors]
        for s in m.sensors:
            if s not in spec.sensors:
                out.append(f"key 'model.sensors': unknown sensor {s!r} "
                           f"(sensors: {', '.join(spec.sensors)})")
        for s in known:
            sen = spec.sensors[s]
            if len(sen.sigma) != len(sen.outputs):
                out.append(f"key 'sensors.{s}.sigma': the filter model needs one sigma per "
                           f"output ({len(sen.outputs)})")
        q, _ = schema.model_noise_psds(spec)
        out += _control_noise_problems(spec)
        if m.type is None and m.kind == "tan":
            if len(q) != 4:
                what = "model.q_psd" if m.q_psd is not None or spec.replay else "noise"
                hint = ("; name the control-noise source in model.control_noise or give "
                        "model.q_psd" if len(spec.noise) > 1 and m.control_noise is None
                        and m.q_psd is None else "")
                out.append(f"key '{what}': the TAN model needs 4 process-noise PSDs "
                           f"(x, y, vx, vy), got {len(q)}{hint}")
            shapes = [len(spec.sensors[s].outputs) for s in known]
            if len(known) == len(m.sensors) and shapes not in ([2], [2, 1]):
                out.append(f"key 'model.sensors': the TAN model takes a 2-output velocity "
                           f"sensor and optionally a 1-output depth sensor, got {shapes}")
            if len(m.sensors) == 2 and spec.map is None:
                out.append("key 'map': a depth sensor needs a map")
        if m.type is None and m.kind == "cv" and len(q) not in (1, 4):
            what = "model.q_psd" if m.q_psd is not None or spec.replay else "noise"
            out.append(f"key '{what}': the constant-velocity model needs 1 or 4 process-noise "
                       f"PSDs (px, vx, py, vy), got {len(q)}")
        for ename, es in spec.estimators.items():
            for s in es.sensors or []:
                if s not in m.sensors:
                    out.append(f"key 'estimators.{ename}.sensors': {s!r} is not among "
                               f"model.sensors ({', '.join(m.sensors)})")
    if spec.run.step is not None and spec.run.duration is not None:
        n = spec.run.duration / spec.run.step
        if abs(n - round(n)) > 1e-9 * max(1.0, n):
            out.insert(0, f"key 'run.duration': must be a whole number of steps of "
                       f"{spec.run.step:g} s (got {spec.run.duration:g})")
    if spec.replay is not None:
        out += replay_problems(spec, where)
    out += geo_problems(spec, where)
    return [Problem(f"{where}: {msg}") for msg in out]


def state_problems(spec: Scenario, states: tuple[str, ...] | list[str],
                   label: str) -> list[str]:
    """``model.truth`` and the ``initial_std`` s against the states of the filters' model
    (``label``: e.g. ``tan model``): one signal and one value per state."""
    out = []
    per_state = f"one per state of the {label} ({', '.join(states)})"
    m = spec.model
    if len(m.truth) != len(states):
        out.append(f"key 'model.truth': {len(m.truth)} signals; expected {per_state}")
    stds = [("estimation.initial_std", spec.estimation.initial_std if spec.estimation
             else None)]
    stds += [(f"estimators.{n}.initial_std", es.initial_std)
             for n, es in spec.estimators.items()]
    for key, std in stds:
        if std is not None and len(std) != len(states):
            out.append(f"key '{key}': {len(std)} values; expected {per_state}")
    init = spec.estimation.initial_state if spec.estimation else None
    for s in init or {}:
        if s not in states:
            out.append(f"key 'estimation.initial_state.{s}': not a state of the {label} "
                       f"({', '.join(states)})")
    return out


def _control_noise_problems(spec: Scenario) -> list[str]:
    """Problems of ``model.control_noise`` (the noise source on the controls)."""
    m = spec.model
    name = m.control_noise
    if name is None:
        return []
    key = "key 'model.control_noise'"
    if m.type is not None:  # a user's model: its builder gets the PSDs (ModelContext)
        return [] if name in spec.noise else [
            f"{key}: unknown noise source {name!r} (noise: {', '.join(spec.noise) or 'none'})"]
    if m.kind != "tan":
        return [f"{key}: only the tan model has controls (model.kind is {m.kind!r})"]
    if name not in spec.noise:
        return [f"{key}: unknown noise source {name!r} (noise: "
                f"{', '.join(spec.noise) or 'none'})"]
    n = len(spec.noise[name].psd)
    if n != 2 or len(m.controls) != 2:
        return [f"{key}: noise {name!r} needs one PSD per model control (psi, a): 2 PSDs "
                f"and 2 model.controls, got {n} and {len(m.controls)}"]
    return []


def validate_data(data: dict, where: str) -> tuple[Scenario | None, list[Problem]]:
    """Validate scenario data (after overrides): the spec (None if the schema refuses it) and
    every problem found."""
    problems = estimator_problems(data, where)
    root = scenario_model(data)
    try:
        spec = root.model_validate(data)
    except ValidationError as exc:
        return None, schema_problems(exc, where, root) + problems
    return spec, problems + reference_problems(spec, where)
