"""Scenario loading: every schema error is one line naming the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
TAN = ROOT / "scenarios" / "tan_terrain.toml"


@pytest.mark.parametrize("path", sorted((ROOT / "scenarios").glob("*.toml")), ids=lambda p: p.name)
def test_shipped_scenarios_validate(path):
    loaded = load_scenario(path)
    assert loaded.spec.run.duration > 0
    assert len(loaded.sha256) == 64


@pytest.mark.parametrize(
    ("overrides", "expected"),
    [
        (["fmus.vehicle.pth=1"], "key 'fmus.vehicle.pth': unknown key (expected one of: path"),
        (["run.step=-1"], "key 'run.step': Input should be greater than 0"),
        (["run.seed=\"abc\""], "key 'run.seed': Input should be a valid integer"),
        (["sensors.dvl.loss={model=\"bernoulli\", p=2}"], "key 'sensors.dvl.loss.p'"),
        (["sensors.dvl.loss={model=\"burst\"}"], "key 'sensors.dvl.loss'"),
        (["controls.psi.waypoints=[[1.0, 2.0]]"], "give exactly one of 'table' or 'waypoints'"),
        (["noise.process.psd=[1.0]"], "'psd' has 1 values for 4 targets"),
        (["run.duration"], "expected KEY=VALUE"),
        (["run.step.x=1"], "run.step is not a table"),
    ],
    ids=["unknown-key", "negative-step", "wrong-type", "probability", "loss-model",
         "control-kind", "psd-length", "no-value", "not-a-table"],
)
def test_schema_errors_name_file_and_key(overrides, expected):
    with pytest.raises(ScenarioError) as info:
        load_scenario(TAN, overrides)
    msg = str(info.value)
    assert str(TAN) in msg
    assert expected in msg
    assert "\n" not in msg


def test_set_overrides_any_key_and_changes_hash():
    base = load_scenario(TAN)
    over = load_scenario(TAN, ["run.duration=100", "estimators.ekf.type=\"ekf\""])
    assert over.spec.run.duration == 100
    assert over.sha256 != base.sha256


def test_missing_and_invalid_files(tmp_path):
    with pytest.raises(ScenarioError, match="scenario file not found"):
        load_scenario(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[run\nduration = 1")
    with pytest.raises(ScenarioError, match="invalid TOML"):
        load_scenario(bad)
