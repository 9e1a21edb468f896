"""Deprecated alias of :mod:`uwcosim.run.simulate` (the simulate stage moved to the run layer in
0.2): ``simulate``, ``run_scenario`` (with the report stage, :func:`uwcosim.api.run_scenario`),
``RunResult``, ``prepare_out_dir`` and ``scenario_map`` keep working from here."""

from uwcosim.api import run_scenario
from uwcosim.run.factory import scenario_map
from uwcosim.run.simulate import RunResult, prepare_out_dir, simulate

__all__ = ["RunResult", "prepare_out_dir", "run_scenario", "scenario_map", "simulate"]
