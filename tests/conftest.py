"""Shared fixtures: the project's FMUs in fmus/ (built incrementally, with the test model
FaultInjector of tests/fault_injector.py and Crasher of tests/crasher.py, both on
tests/hooked_model.py) and scenario helpers."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

try:
    from crasher import register as register_crasher
    from fault_injector import register
except ImportError:  # pragma: no cover - run from the project root as a package
    from tests.crasher import register as register_crasher
    from tests.fault_injector import register

register()  # every FMU build of the test session includes FaultInjector
register_crasher()  # and Crasher


@pytest.fixture(scope="session")
def project_fmus() -> Path:
    """``fmus/`` with every project FMU, FaultInjector and Crasher, built if missing or out of date
    (about 3 s)."""
    from uwcosim.fmu.build import build_fmus

    build_fmus(ROOT / "fmus")
    return ROOT / "fmus"


@pytest.fixture
def tan(project_fmus):
    """Load ``scenarios/tan_terrain.toml`` with overrides: ``tan(["run.duration=50"])``."""
    from uwcosim.scenario import load_scenario

    def load(overrides=(), name="tan_terrain.toml"):
        return load_scenario(SCENARIOS / name, list(overrides))

    return load


#: how the progress lines of ``run``/``demo`` begin on stderr (uwcosim.run.progress; one line
#: per stage when stderr is no terminal)
PROGRESS_LINES = ("uwcosim: simulating", "uwcosim: simulated", "uwcosim: evaluating",
                  "uwcosim: figures", "uwcosim: compiling", "uwcosim: building the project",
                  "uwcosim: built ")


def without_progress(err: str) -> str:
    """``err`` without the progress lines: what is left is the errors and warnings."""
    return "".join(line for line in err.splitlines(keepends=True)
                   if not line.startswith(PROGRESS_LINES))
