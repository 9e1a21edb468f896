"""A third-party vehicle without process-noise inputs runs the scenario as it is: the truth runs
noise-free (said in summary.json and report.md), the filters keep the scenario's noise PSDs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from uwcosim.api import run_scenario
from uwcosim.core.errors import ScenarioError
from uwcosim.runlog import read_log

try:
    from thirdparty_fmus import PYFMU_DIR, pythonfmu_vehicle
except ImportError:  # tests/ imported as a package
    from tests.thirdparty_fmus import PYFMU_DIR, pythonfmu_vehicle

__all__ = ["pythonfmu_vehicle"]  # fixture
TWO = ['estimators={dead_reckoning={type="dead_reckoning"}, ekf={type="ekf"}}',
       "run.duration=120"]


def _vehicle(fmu: Path) -> list[str]:
    return [f'fmus.vehicle.path="{fmu}"', f'fmus.vehicle.map="{PYFMU_DIR / "map.toml"}"']


def test_vehicle_without_noise_inputs_runs_noise_free_with_a_note(tan, tmp_path,
                                                                   pythonfmu_vehicle):
    plain = run_scenario(tan([*_vehicle(pythonfmu_vehicle), *TWO]), tmp_path / "a")
    assert plain.status == "ok"
    notes = plain.summary["notes"]
    assert notes == ["the truth ran noise-free: FMU 'vehicle' has no inputs w_x, w_y, w_vx, "
                     "w_vy for noise 'process'; the filters' process noise is model.q_psd, "
                     "which defaults to these PSDs"]
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["notes"] == notes
    assert f"Note: {notes[0]}" in (tmp_path / "a" / "report.md").read_text()
    # the same as removing the noise by hand and copying its PSDs to the model
    by_hand = run_scenario(tan([*_vehicle(pythonfmu_vehicle), *TWO, "noise={}",
                                "model.q_psd=[0.05, 0.05, 1e-5, 1e-5]"]), tmp_path / "b",
                           figures=False)
    a, _ = read_log(plain.log_path)
    b, _ = read_log(by_hand.log_path)
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    # and a truth without noise: our own FMU with noise={} gives the same track
    ours = run_scenario(tan([*TWO, "noise={}", "model.q_psd=[0.05, 0.05, 1e-5, 1e-5]"]),
                        tmp_path / "c", figures=False)
    c, _ = read_log(ours.log_path)
    np.testing.assert_allclose(a["vehicle.x"], c["vehicle.x"], rtol=0, atol=1e-7)
    assert "notes" not in ours.summary


def test_a_typo_in_a_noise_target_is_still_an_error(tan):
    from uwcosim.master.master import Master
    from uwcosim.scenario import to_system

    with pytest.raises(ScenarioError, match="has no variable 'w_xx'"):
        Master(to_system(tan(['noise.process.targets=["vehicle.w_xx", "vehicle.w_yy", '
                              '"vehicle.w_vxx", "vehicle.w_vyy"]'])))
