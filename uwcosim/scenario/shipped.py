"""The shipped scenarios as an installed wheel runs them: copies next to the FMUs they need.

A wheel carries the scenarios and campaign specs (``uwcosim/_data/scenarios``) but no FMU (they
are built for this machine, with gcc). :func:`runnable` maps a shipped file of an installed
wheel to its copy in the user cache folder (:func:`uwcosim.core.paths.cache_dir`,
``$XDG_CACHE_HOME/uwcosim/scenarios``), next to which the scenarios' relative FMU paths
(``../fmus/...``) resolve; :func:`missing_fmus` names the project FMUs a scenario needs that are
missing there (or in a checkout's ``fmus/``), which :func:`uwcosim.demo.provide_fmus` builds.
Nothing here imports the FMU tooling (a run with its FMUs in place starts fast).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from uwcosim.core.errors import UwcosimError
from uwcosim.core.paths import DATA_DIR, cache_dir, is_project_fmu, project_root, scenarios_dir
from uwcosim.scenario.loaded import LoadedScenario

#: a file every installation carries (its absence: a broken installation)
SENTINEL = "tan_terrain.toml"


def copy_shipped(cache: Path | None = None) -> Path:
    """Copy the shipped scenarios and campaign specs into ``cache/scenarios`` (files whose text
    changed are replaced); the folder."""
    cache = Path(cache) if cache is not None else cache_dir()
    src = scenarios_dir()
    if not (src / SENTINEL).is_file():
        raise UwcosimError(f"{src / SENTINEL}: shipped scenario not found (a broken "
                           f"installation: reinstall uwcosim)")
    dst = cache / "scenarios"
    try:
        for path in sorted(src.rglob("*.toml")):
            target = dst / path.relative_to(src)
            target.parent.mkdir(parents=True, exist_ok=True)
            data = path.read_bytes()
            if not target.is_file() or target.read_bytes() != data:
                target.write_bytes(data)
    except OSError as exc:
        raise UwcosimError(f"{cache}: cannot write the cache folder ({exc.strerror})") from None
    return dst


def runnable(path: str | Path, cache: Path | None = None) -> Path:
    """``path`` itself, or for a shipped file of an installed wheel (under
    ``uwcosim/_data/scenarios``) its copy in the cache folder, where the FMU paths resolve."""
    path = Path(path)
    shipped = (DATA_DIR / "scenarios").resolve()
    try:
        rel = path.resolve().relative_to(shipped)
    except ValueError:
        return path
    return copy_shipped(cache) / rel


def build_places(cache: Path | None = None) -> set[Path]:
    """The folders where a missing project FMU is built on first use: the cache's ``fmus``
    and a checkout's ``fmus``."""
    places = {((Path(cache) if cache is not None else cache_dir()) / "fmus").resolve()}
    root = project_root()
    if root is not None:
        places.add((root / "fmus").resolve())
    return places


def missing_fmus(paths: Iterable[Path], cache: Path | None = None) -> dict[Path, list[str]]:
    """The project's FMUs among ``paths`` that do not exist and are built on first use, by
    folder: ``{folder: [archive stem, ...]}`` (any other missing FMU is left to the FMI layer's
    own "FMU not found")."""
    places = build_places(cache)
    out: dict[Path, list[str]] = {}
    for p in paths:
        p = Path(p)
        if p.exists() or not is_project_fmu(p) or p.parent.resolve() not in places:
            continue
        names = out.setdefault(p.parent, [])
        if p.stem not in names:
            names.append(p.stem)
    return out


def scenario_fmus(loaded: LoadedScenario) -> list[Path]:
    """The FMU files a loaded scenario names (none for a replay or an SSP's own FMUs)."""
    fmus = getattr(loaded.spec, "fmus", None) or {}
    out = []
    for f in fmus.values():
        path = getattr(f, "path", None)
        if isinstance(path, str | Path):
            out.append(loaded.resolve(str(path)))
    return out
