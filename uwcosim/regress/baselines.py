"""Golden baselines: short runs of the shipped scenarios, kept as Parquet logs.

``uwcosim baseline update`` regenerates them on purpose (after a deliberate change to a model,
a filter or a scenario), ``uwcosim baseline check`` (and the test suite) compares fresh runs
with them. A baseline is the log of ``SCENARIO`` run with :data:`DEFAULT_OVERRIDES` (a few
hundred seconds) and its seed; the overrides are recorded in the log's metadata, so a check
runs exactly what the baseline ran.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from uwcosim.regress.compare import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    DEFAULT_TTOL,
    RegressionInputError,
    RegressionReport,
    compare_logs,
    read_columns,
)
from uwcosim.run.simulate import run_scenario
from uwcosim.scenario import load_scenario

#: the short version of a shipped scenario
DEFAULT_OVERRIDES: tuple[str, ...] = ("run.duration=300",)


def shipped_scenarios(scenario_dir: str | Path = "scenarios") -> list[Path]:
    d = Path(scenario_dir)
    found = sorted(d.glob("*.toml"))
    if not found:
        raise RegressionInputError(f"{d}: no scenarios (*.toml)")
    return found


def baseline_path(baseline_dir: str | Path, scenario: str | Path) -> Path:
    return Path(baseline_dir) / f"{Path(scenario).stem}.parquet"


def run_log(scenario: str | Path, overrides=(), out_dir: str | Path | None = None,
            seed: int | None = None) -> Path:
    """Run ``scenario`` with ``overrides`` (no figures); the path of its log."""
    loaded = load_scenario(scenario, list(overrides))
    out = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="uwc_regr_"))
    return run_scenario(loaded, out, seed=seed, figures=False).log_path


def recorded_overrides(baseline: Path) -> list[str]:
    _, meta = read_columns(baseline)
    return list(meta.get("overrides", []))


@dataclass
class BaselineResult:
    scenario: Path
    baseline: Path
    status: str  # new | unchanged | changed | ok | FAILED
    report: RegressionReport | None = None


def update_baseline(scenario: Path, baseline_dir: Path, overrides=DEFAULT_OVERRIDES
                    ) -> BaselineResult:
    """Run the short version of ``scenario`` and store its log as the baseline."""
    target = baseline_path(baseline_dir, scenario)
    with tempfile.TemporaryDirectory(prefix="uwc_baseline_") as tmp:
        log = run_log(scenario, overrides, tmp)
        report = compare_logs(log, target) if target.is_file() else None
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(log, target)
    status = "new" if report is None else \
        "unchanged" if report.ok and not report.extra else "changed"
    return BaselineResult(scenario, target, status, report)


def check_baseline(scenario: Path, baseline_dir: Path, rtol: float = DEFAULT_RTOL,
                   atol: float = DEFAULT_ATOL, ttol: float = DEFAULT_TTOL,
                   plot_dir: Path | None = None) -> BaselineResult:
    """Run ``scenario`` as its baseline was run and compare."""
    target = baseline_path(baseline_dir, scenario)
    if not target.is_file():
        raise RegressionInputError(f"{target}: no baseline for {Path(scenario).name} (create "
                                   f"it with 'uwcosim baseline update {scenario}')")
    with tempfile.TemporaryDirectory(prefix="uwc_baseline_") as tmp:
        log = run_log(scenario, recorded_overrides(target), tmp)
        report = compare_logs(log, target, rtol, atol, ttol, plot_dir=plot_dir)
        report.run = Path(f"{Path(scenario).name} (fresh run)")
    return BaselineResult(scenario, target, "ok" if report.ok else "FAILED", report)
