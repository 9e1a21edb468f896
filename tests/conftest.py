"""Shared fixtures: the project's FMUs in fmus/ (built incrementally, with the test model
FaultInjector of tests/fault_injector.py and Crasher of tests/crasher.py, both on
tests/hooked_model.py) and scenario helpers."""

from __future__ import annotations

import signal
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


def pytest_configure(config):
    """With pytest-xdist (``-n N``: ``make test``), bring ``fmus/`` up to date once, in the
    controller, before the workers start: otherwise each worker's ``project_fmus`` would build
    the test FMUs at the same time."""
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    from uwcosim.fmu.build import build_fmus

    build_fmus(ROOT / "fmus")


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


@pytest.fixture
def cli(capsys):
    """``uwcosim.cli.main`` in this process: ``cli(*argv) -> (status, stdout, stderr lines)``,
    with no traceback on stderr and the signal handlers the CLI installs restored."""
    from uwcosim.cli import main

    saved = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}

    def run(*argv):
        try:
            try:
                code = main([str(a) for a in argv])
            except SystemExit as exc:  # argparse
                code = exc.code
        finally:
            for s, h in saved.items():
                signal.signal(s, h)
        out, err = capsys.readouterr()
        assert "Traceback" not in err
        return code, out, err.strip().splitlines()

    return run
