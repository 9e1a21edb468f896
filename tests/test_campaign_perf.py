"""Campaign performance reporting: per-run cost, runs/s, filter share, peak RSS, ETA."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from uwcosim.campaign import load_campaign
from uwcosim.campaign.driver import run_campaign
from uwcosim.campaign.execute import SessionStats, _eta_text, session_line
from uwcosim.cli import main

ROOT = Path(__file__).resolve().parents[1]

SPEC = """
name = "p"
seed = 3
runs = 2
[[variants]]
name = "with_terrain"
scenario = "{root}/scenarios/tan_terrain.toml"
set = ["run.duration=20", 'estimators={{ekf={{type="ekf"}}}}']
"""


@pytest.fixture
def spec_path(tmp_path, project_fmus):
    p = tmp_path / "c.toml"
    p.write_text(SPEC.format(root=ROOT))
    return p


def test_campaign_reports_cost_share_and_memory(spec_path, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["campaign", str(spec_path), "--out", str(out), "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "runs/s" in printed and "filters" in printed and "peak RSS" in printed
    session = json.loads((out / "session.json").read_text())
    assert session["runs_this_session"] == 2
    assert 0 < session["filter_share"] < 1
    assert session["runs_per_s"] == pytest.approx(2 / session["wall_time_s"])
    assert 10 < session["peak_rss_mb"] < 4096
    record = json.loads(next((out / "results").glob("*.json")).read_text())
    assert record["wall_s"] > 0 and record["peak_rss_mb"] > 10
    table = (out / "table.md").read_text()
    assert "Peak RSS per worker process" in table and "Wall time of a run" in table
    # a resumed campaign with nothing left to do says so instead of dividing by zero
    run_campaign(load_campaign(spec_path), out, resume=True, figures=False)
    assert session_line(out) == "no run finished in this session"


def test_eta_from_per_run_cost_and_parallelism():
    stats = SessionStats(remaining=10)
    assert stats.eta_s() is None and _eta_text(None) == "?"
    stats.start -= 10.0  # 10 s elapsed, two runs of 8 s each finished: 1.6 runs in flight
    for _ in range(2):
        stats.add({"wall_s": 8.0, "estimators": {"a": {"total_time_s": 2.0}}})
    assert stats.eta_s() == pytest.approx(8 * 8.0 / 1.6, rel=0.01)
    s = stats.summary()
    assert s["filter_share"] == pytest.approx(0.25)
    assert s["mean_run_wall_s"] == 8.0
    assert math.isnan(SessionStats(0).summary()["filter_share"])
    assert _eta_text(3725) == "1:02:05" and _eta_text(65) == "1:05"
