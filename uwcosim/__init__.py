"""uwcosim: a co-simulation testbench for underwater navigation filters.

The truth side (AUV kinematics and sensors) runs as FMUs stepped by our own master on fmpy;
the estimation side is a library of Bayesian filters (``uwcosim.filters``); every run is logged
to Parquet with its metadata (``uwcosim.runlog``). The package is layered, every import
pointing down (``docs/architecture.md``): core, then FMI, models and the log format, the
master and the filters, the scenario, the evaluation, the run, the figures and reports, the
tools, the command line.

The public API, imported on first use (``import uwcosim`` stays light)::

    from uwcosim import Master, System, load_scenario, run_scenario, simulate, evaluate, report

    run = simulate("scenarios/tan_terrain.toml", "runs/tan")  # log.parquet, simulation.json
    summary = evaluate(run)                                     # summary.json, from the files
    report(run)                                                 # figures and report.md

``run_scenario`` is the three in a row (``uwcosim run``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from uwcosim.core.version import __version__

_EXPORTS = {
    "Master": "uwcosim.master.master",
    "System": "uwcosim.master.system",
    "load_scenario": "uwcosim.scenario.load",
    "run_scenario": "uwcosim.api",
    "simulate": "uwcosim.run.simulate",
    "RunResult": "uwcosim.run.simulate",
    "evaluate": "uwcosim.evaluation.summary",
    "report": "uwcosim.api",
}

__all__ = ["Master", "RunResult", "System", "__version__", "evaluate", "load_scenario", "report",
           "run_scenario", "simulate"]

if TYPE_CHECKING:
    from uwcosim.api import report, run_scenario
    from uwcosim.evaluation.summary import evaluate
    from uwcosim.master.master import Master
    from uwcosim.master.system import System
    from uwcosim.run.simulate import RunResult, simulate
    from uwcosim.scenario.load import load_scenario


def __getattr__(name: str) -> object:
    if name in _EXPORTS:  # imported on first use: ``import uwcosim`` stays light
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'uwcosim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
