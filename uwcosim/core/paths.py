"""Where uwcosim finds its shipped files and keeps its own, independent of the current folder.

- :func:`project_root`: the source checkout the package runs from (an editable install), or
  None for an installed wheel;
- :func:`scenarios_dir`: the shipped scenarios: ``<checkout>/scenarios``, or the copy a wheel
  carries as package data (``uwcosim/_data/scenarios``, put there by ``setup.py``);
- :func:`cache_dir`: ``$XDG_CACHE_HOME/uwcosim`` (default ``~/.cache/uwcosim``), where
  ``uwcosim demo`` builds the FMUs;
- :func:`shipped_scenario`: a shipped scenario or campaign spec by its name (``tan_terrain``,
  ``smoke``, ``campaigns/smoke``), as ``uwcosim run NAME`` and ``uwcosim campaign NAME`` take it;
- :func:`baselines_dir`: ``<checkout>/tests/baselines``; for an installed wheel
  ``$XDG_DATA_HOME/uwcosim/baselines`` (default ``~/.local/share/uwcosim/baselines``) once
  ``uwcosim baseline update`` wrote there, else the baselines the wheel carries
  (``uwcosim/_data/baselines``);
- :func:`docs_dir`: ``<checkout>/docs``, or the copy a wheel carries (``uwcosim/_data/docs``);
- the project's own FMUs (:data:`PROJECT_MODELS`, built by ``uwcosim fmu build`` into ``fmus/``
  or by ``uwcosim demo`` into the cache folder): their file names (:func:`fmu_file_name`) and
  :func:`is_project_fmu`, which lets the FMI layer say how to build a missing one.
"""

from __future__ import annotations

import os
from pathlib import Path

#: the ``uwcosim`` package folder (this module is in its ``core`` subpackage)
PACKAGE_DIR = Path(__file__).resolve().parents[1]


#: the package data a wheel carries (``setup.py`` copies scenarios, baselines and docs there)
DATA_DIR = PACKAGE_DIR / "_data"


def project_root() -> Path | None:
    root = PACKAGE_DIR.parent
    if (root / "pyproject.toml").is_file() and (root / "scenarios").is_dir():
        return root
    return None


def scenarios_dir() -> Path:
    root = project_root()
    return root / "scenarios" if root is not None else DATA_DIR / "scenarios"


def shipped_scenario(name: str | Path) -> Path | None:
    """The shipped scenario or campaign spec called ``name`` (``tan_terrain``,
    ``tan_terrain.toml``, ``smoke``, ``campaigns/smoke``; scenarios first), or None when
    ``name`` is an existing file or names nothing shipped."""
    text = str(name)
    if Path(text).exists() or text.startswith(("/", ".", "~")) or not text:
        return None
    stem = text[:-5] if text.endswith(".toml") else text
    if "." in stem or "\\" in stem:
        return None
    base = scenarios_dir()
    for candidate in (base / f"{stem}.toml", base / "campaigns" / f"{stem}.toml"):
        if candidate.is_file():
            return candidate
    return None


def shipped_names(campaigns: bool = False) -> list[str]:
    """The names of the shipped scenarios (or campaign specs), sorted."""
    base = scenarios_dir() / "campaigns" if campaigns else scenarios_dir()
    return sorted(p.stem for p in base.glob("*.toml"))


def docs_dir() -> Path:
    root = project_root()
    return root / "docs" if root is not None else DATA_DIR / "docs"


def _xdg(var: str, default: str) -> Path:
    value = os.environ.get(var, "")
    return Path(value) if value and Path(value).is_absolute() else Path.home() / default


def cache_dir() -> Path:
    return _xdg("XDG_CACHE_HOME", ".cache") / "uwcosim"


def baselines_dir(for_update: bool = False) -> Path:
    """Where the golden baselines are read (``for_update``: written). A checkout's
    ``tests/baselines``; for a wheel the user's data folder, which ``baseline update`` writes,
    read once it holds baselines, else the baselines the wheel carries."""
    root = project_root()
    if root is not None:
        return root / "tests" / "baselines"
    user = _xdg("XDG_DATA_HOME", ".local/share") / "uwcosim" / "baselines"
    if for_update or any(user.glob("*.parquet")) or not (DATA_DIR / "baselines").is_dir():
        return user
    return DATA_DIR / "baselines"


#: the models of the project's own FMUs: the keys of ``uwcosim.fmu.specs.MODELS`` (one
#: specification each; ``tests/test_fmus.py`` keeps the two equal)
PROJECT_MODELS = ("AUVKinematics", "DVL", "DepthSounder", "ConstantVelocity")


def fmu_file_name(model: str, fmi3: bool = True) -> str:
    """The file name of ``model``'s FMU: ``<Model>.fmu`` (FMI 3.0), ``<Model>_fmi2.fmu``
    (FMI 2.0)."""
    return f"{model}.fmu" if fmi3 else f"{model}_fmi2.fmu"


def is_project_fmu(path: str | Path) -> bool:
    """Whether ``path`` is named as one of the project's own FMUs (in any folder)."""
    return Path(path).name in {fmu_file_name(m, v) for m in PROJECT_MODELS for v in (True, False)}
