"""Golden baselines: the short version of every shipped scenario matches its baseline log.

After a deliberate change (a model, a filter, a scenario), regenerate them with
``uwcosim baseline update`` and commit ``tests/baselines/*.parquet``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from uwcosim.regress.baselines import (
    DEFAULT_OVERRIDES,
    baseline_path,
    recorded_overrides,
    shipped_scenarios,
)
from uwcosim.regress.pytest_helper import assert_matches_baseline

ROOT = Path(__file__).resolve().parents[1]
BASELINES = ROOT / "tests" / "baselines"


@pytest.mark.parametrize("scenario", shipped_scenarios(ROOT / "scenarios"),
                         ids=lambda p: p.stem)
def test_shipped_scenario_matches_its_baseline(project_fmus, scenario):
    baseline = baseline_path(BASELINES, scenario)
    assert baseline.is_file(), f"no baseline for {scenario.name}: run 'uwcosim baseline update'"
    assert recorded_overrides(baseline) == list(DEFAULT_OVERRIDES)
    report = assert_matches_baseline(scenario, baseline, DEFAULT_OVERRIDES)
    assert not report.extra, (f"{scenario.name} logs signals its baseline does not have "
                              f"({', '.join(report.extra[:5])}): run 'uwcosim baseline update'")
