"""``uwcosim demo``: run the TAN scenario from an installed package alone.

The FMUs the scenario needs are built (gcc) into the user cache folder
(:func:`uwcosim.paths.cache_dir`, ``$XDG_CACHE_HOME/uwcosim``), next to a copy of the shipped
scenarios, so that the scenarios' relative FMU paths (``../fmus/...``) resolve there; nothing is
written to the current folder but the run directory.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from uwcosim.simulation import RunResult

DEMO_SCENARIO = "tan_terrain.toml"
DEMO_FMUS = ("AUVKinematics", "DVL", "DepthSounder")


def prepare_cache(cache: Path | None = None) -> Path:
    """Build the demo's FMUs and copy the shipped scenarios into ``cache``; the scenario path."""
    from uwcosim.errors import UwcosimError
    from uwcosim.fmu.build import build_fmus
    from uwcosim.paths import cache_dir, scenarios_dir

    cache = Path(cache) if cache is not None else cache_dir()
    src = scenarios_dir()
    if not (src / DEMO_SCENARIO).is_file():
        raise UwcosimError(f"{src / DEMO_SCENARIO}: shipped scenario not found (a broken "
                           f"installation: reinstall uwcosim)")
    try:
        (cache / "scenarios").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UwcosimError(f"{cache}: cannot create the cache folder ({exc.strerror})") from None
    build_fmus(cache / "fmus", names=list(DEMO_FMUS))
    for p in src.glob("*.toml"):
        shutil.copyfile(p, cache / "scenarios" / p.name)
    return cache / "scenarios" / DEMO_SCENARIO


def run_demo(out: Path, overrides: Sequence[str] = (), cache: Path | None = None,
             seed: int | None = None) -> RunResult:
    """Prepare the cache and run the TAN scenario into ``out``; the :class:`RunResult`."""
    from uwcosim.scenario import load_scenario
    from uwcosim.simulation import run_scenario

    scenario = prepare_cache(cache)
    loaded = load_scenario(scenario, list(overrides), overrides_base=Path.cwd())
    return run_scenario(loaded, Path(out), seed=seed)
