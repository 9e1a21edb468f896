"""Where uwcosim finds its shipped files and keeps its own, independent of the current folder.

- :func:`project_root`: the source checkout the package runs from (an editable install), or
  None for an installed wheel;
- :func:`scenarios_dir`: the shipped scenarios: ``<checkout>/scenarios``, or the copy a wheel
  carries as package data (``uwcosim/_data/scenarios``, put there by ``setup.py``);
- :func:`cache_dir`: ``$XDG_CACHE_HOME/uwcosim`` (default ``~/.cache/uwcosim``), where
  ``uwcosim demo`` builds the FMUs;
- :func:`baselines_dir`: ``<checkout>/tests/baselines``, or ``$XDG_DATA_HOME/uwcosim/baselines``
  (default ``~/.local/share/uwcosim/baselines``) for an installed wheel;
- the project's own FMUs (:data:`PROJECT_MODELS`, built by ``uwcosim fmu build`` into ``fmus/``
  or by ``uwcosim demo`` into the cache folder): their file names (:func:`fmu_file_name`) and
  :func:`is_project_fmu`, which lets the FMI layer say how to build a missing one.
"""

from __future__ import annotations

import os
from pathlib import Path

#: the ``uwcosim`` package folder (this module is in its ``core`` subpackage)
PACKAGE_DIR = Path(__file__).resolve().parents[1]


def project_root() -> Path | None:
    root = PACKAGE_DIR.parent
    if (root / "pyproject.toml").is_file() and (root / "scenarios").is_dir():
        return root
    return None


def scenarios_dir() -> Path:
    root = project_root()
    return root / "scenarios" if root is not None else PACKAGE_DIR / "_data" / "scenarios"


def _xdg(var: str, default: str) -> Path:
    value = os.environ.get(var, "")
    return Path(value) if value and Path(value).is_absolute() else Path.home() / default


def cache_dir() -> Path:
    return _xdg("XDG_CACHE_HOME", ".cache") / "uwcosim"


def baselines_dir() -> Path:
    root = project_root()
    if root is not None:
        return root / "tests" / "baselines"
    return _xdg("XDG_DATA_HOME", ".local/share") / "uwcosim" / "baselines"


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
