"""``uwcosim demo``: run the TAN scenario from an installed package alone.

The FMUs the scenario needs are built (gcc) into the user cache folder
(:func:`uwcosim.core.paths.cache_dir`, ``$XDG_CACHE_HOME/uwcosim``), next to a copy of the shipped
scenarios, so that the scenarios' relative FMU paths (``../fmus/...``) resolve there; nothing is
written to the current folder but the run directory.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

from uwcosim.core.errors import UwcosimError
from uwcosim.core.paths import cache_dir, scenarios_dir
from uwcosim.fmu.build import build_fmus
from uwcosim.reports.run_report import report_run
from uwcosim.run.simulate import RunResult, run_scenario
from uwcosim.scenario import load_scenario

DEMO_SCENARIO = "tan_terrain.toml"
DEMO_FMUS = ("AUVKinematics", "DVL", "DepthSounder")


def prepare_cache(cache: Path | None = None) -> Path:
    """Build the demo's FMUs and copy the shipped scenarios into ``cache``; the scenario path."""
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
    scenario = prepare_cache(cache)
    loaded = load_scenario(scenario, list(overrides), overrides_base=Path.cwd())
    return run_scenario(loaded, Path(out), seed=seed, report=report_run)
