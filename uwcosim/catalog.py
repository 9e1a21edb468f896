"""``uwcosim list estimators|scenarios|fmus``: what is available, from the registries.

- estimators: every registered filter, the first line of its docstring and its settings with
  their defaults (the keyword arguments of its constructor, as the scenario passes them; ``rng``
  is the master's and not a setting);
- scenarios: the shipped scenarios (:func:`uwcosim.paths.scenarios_dir`), name and description;
- fmus: the project's FMU models, their description, and the built archives found in ``fmus/``
  of the checkout or the demo's cache folder.
"""

from __future__ import annotations

import inspect
import tomllib
from pathlib import Path

NOT_SETTINGS = ("self", "model", "x0", "P0", "rng")


def _first_line(doc: str | None) -> str:
    return (doc or "").strip().splitlines()[0].rstrip(".") if doc and doc.strip() else ""


def estimator_settings(cls) -> dict[str, object]:
    """``{setting: default}`` of an estimator class (``inspect.Parameter.empty``: required)."""
    params = inspect.signature(cls.__init__).parameters
    return {n: p.default for n, p in params.items() if n not in NOT_SETTINGS
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}


def _fmt_default(v) -> str:
    return "required" if v is inspect.Parameter.empty else repr(v)


def list_estimators() -> str:
    from uwcosim.filters import ESTIMATORS

    lines = []
    for name in ESTIMATORS.names():
        cls = ESTIMATORS.get(name)
        lines.append(f"{name}: {_first_line(cls.__doc__)}")
        settings = estimator_settings(cls)
        lines.append("    settings: " + (", ".join(f"{k}={_fmt_default(v)}"
                                                   for k, v in settings.items()) or "none"))
    return "\n".join(lines)


def list_scenarios(directory: Path | None = None) -> str:
    from uwcosim.paths import scenarios_dir

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
    from uwcosim.fmu.build import FMI_VERSIONS, archive_name
    from uwcosim.fmu.specs import MODELS
    from uwcosim.paths import cache_dir, project_root

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
