"""``uwcosim demo``: run the TAN scenario from an installed package alone; and the FMUs a
shipped scenario needs, built on first use.

:func:`provide_fmus` builds the project's FMUs that a scenario names and that are missing in the
user cache folder (where an installed wheel runs its shipped scenarios from, see
:mod:`uwcosim.scenario.shipped`) or in a checkout's ``fmus/``, with one line on stderr saying so.
:func:`run_demo` copies the shipped scenarios into the cache, builds the demo's FMUs there and
runs ``tan_terrain``. Nothing is written to the current folder but the run directory.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from uwcosim.fmu.build import build_fmus
from uwcosim.master.observer import Observer
from uwcosim.reports.run_report import report_run
from uwcosim.run.simulate import ReportStage, RunResult, run_scenario
from uwcosim.scenario.load import load_scenario
from uwcosim.scenario.shipped import copy_shipped, missing_fmus

DEMO_SCENARIO = "tan_terrain.toml"
DEMO_FMUS = ("AUVKinematics", "DVL", "DepthSounder")


def _say(message: str) -> None:
    print(f"uwcosim: {message}", file=sys.stderr, flush=True)


def provide_fmus(paths: Iterable[Path], cache: Path | None = None,
                 say: Callable[[str], None] = _say) -> list[Path]:
    """Build the missing project FMUs among ``paths`` (see :func:`missing_fmus`), saying so in
    one line per folder; the archives built."""
    built: list[Path] = []
    for folder, names in missing_fmus(paths, cache).items():
        t0 = time.perf_counter()
        say(f"building the project's FMUs {', '.join(f'{n}.fmu' for n in names)} into "
            f"{folder} (first use only, gcc, a few seconds)")
        built += build_fmus(folder, names=names)
        say(f"built {len(names)} FMU{'s' * (len(names) != 1)} in "
            f"{time.perf_counter() - t0:.1f} s")
    return built


def prepare_cache(cache: Path | None = None) -> Path:
    """Copy the shipped scenarios into ``cache`` and build the demo's FMUs there; the demo
    scenario's path."""
    scenarios = copy_shipped(cache)
    provide_fmus([scenarios.parent / "fmus" / f"{m}.fmu" for m in DEMO_FMUS], cache)
    return scenarios / DEMO_SCENARIO


def run_demo(out: Path, overrides: Sequence[str] = (), cache: Path | None = None,
             seed: int | None = None, progress: Observer | None = None,
             report: ReportStage | None = None) -> RunResult:
    """Prepare the cache and run the TAN scenario into ``out``; the :class:`RunResult`.
    ``report``: the report stage (default :func:`uwcosim.reports.run_report.report_run`)."""
    if report is None:
        report = report_run
    scenario = prepare_cache(cache)
    loaded = load_scenario(scenario, list(overrides), overrides_base=Path.cwd())
    return run_scenario(loaded, Path(out), seed=seed, report=report, progress=progress)
