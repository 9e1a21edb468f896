"""One-line regression tests for pytest: a scenario's log must match a baseline log.

::

    from uwcosim.regress.pytest_helper import assert_matches_baseline

    def test_my_scenario(project_fmus):
        assert_matches_baseline("scenarios/my.toml", "tests/baselines/my.parquet",
                                overrides=["run.duration=300"])

A missing baseline fails (it is not created silently); set ``UWCOSIM_UPDATE_BASELINES=1`` to
write (or rewrite) it from this run instead, e.g. after a deliberate change.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from uwcosim.regress.baselines import run_log
from uwcosim.regress.compare import DEFAULT_ATOL, DEFAULT_RTOL, DEFAULT_TTOL, compare_logs

UPDATE_ENV = "UWCOSIM_UPDATE_BASELINES"


def assert_matches_baseline(scenario: str | Path, baseline: str | Path, overrides=(),
                            seed: int | None = None, rtol: float = DEFAULT_RTOL,
                            atol: float = DEFAULT_ATOL, ttol: float = DEFAULT_TTOL,
                            signals: list[str] | None = None,
                            out_dir: str | Path | None = None):
    """Run ``scenario`` (with ``overrides``, ``seed``) and compare its log with ``baseline``.

    Raises ``AssertionError`` with the comparison report (and the folder of the diff plots)
    when a signal leaves its tolerance tube. Returns the report.
    """
    baseline = Path(baseline)
    work = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="uwc_regr_"))
    log = run_log(scenario, overrides, work / "run", seed=seed)
    if os.environ.get(UPDATE_ENV) == "1":
        baseline.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(log, baseline)
    if not baseline.is_file():
        raise AssertionError(f"{baseline}: baseline missing; create it with {UPDATE_ENV}=1 "
                             f"(or 'uwcosim baseline update')")
    report = compare_logs(log, baseline, rtol, atol, ttol, signals, plot_dir=work / "diff")
    if not report.ok:
        raise AssertionError(report.text())
    if out_dir is None:
        shutil.rmtree(work, ignore_errors=True)
    return report
