"""Bad input and faults: one clear line, a non-zero exit, and the log so far kept readable."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from uwcosim.api import run_scenario
from uwcosim.core.errors import (
    FilterDivergence,
    FMUError,
    RunInterrupted,
    ScenarioError,
    UwcosimError,
)
from uwcosim.filters import ESTIMATORS
from uwcosim.filters.kalman import ExtendedKalmanFilter
from uwcosim.master.observer import Callback
from uwcosim.runlog import read_log

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

FAULT_CHAIN = [
    "fmus.fault={path=\"../fmus/FaultInjector.fmu\"}",
    'connections=[["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"], '
    '["vehicle.x", "fault.u"], ["fault.y", "sounder.x"], ["vehicle.y", "sounder.y"]]',
    "run.duration=50",
]


def _rows(path) -> int:
    cols, _ = read_log(path)
    return cols["time"].size


def test_fmu_error_mid_run_keeps_the_log(tan, tmp_path):
    loaded = tan([*FAULT_CHAIN, "fmus.fault.parameters={fail_time=5.0}"])
    with pytest.raises(FMUError) as info:
        run_scenario(loaded, tmp_path, figures=False)
    msg = str(info.value)
    assert "FMU 'fault'" in msg and "injected failure" in msg and "t=4" in msg
    # rows for t = 0..4 were logged; the failing step 4 -> 5 was not
    assert _rows(tmp_path / "log.parquet") == 5
    assert '"status": "failed"' in (tmp_path / "summary.json").read_text()


def test_nan_from_an_fmu_is_reported(tan, tmp_path):
    loaded = tan([*FAULT_CHAIN, "fmus.fault.parameters={nan_time=3.0}"])
    with pytest.raises(FMUError, match=r"FMU 'fault' returned a non-finite value for y at t=3"):
        run_scenario(loaded, tmp_path, figures=False)
    assert _rows(tmp_path / "log.parquet") == 3


def test_ctrl_c_flushes_the_log(tan, tmp_path):
    def interrupt(k, view):
        if k == 10:
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted, match="interrupted at t=10"):
        run_scenario(tan(["run.duration=100"]), tmp_path, figures=False,
                     progress=Callback(interrupt))
    assert _rows(tmp_path / "log.parquet") == 11


def test_unwritable_output_directory(tan, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(UwcosimError, match="output directory is not writable"):
        run_scenario(tan(), blocker / "run", figures=False)


def test_position_outside_the_map(tan, tmp_path):
    with pytest.raises(FMUError, match="outside the map"):
        run_scenario(tan(["fmus.vehicle.start.x=-500.0", "run.duration=5"]), tmp_path,
                     figures=False)


@pytest.fixture
def broken_fmus(project_fmus, tmp_path):
    src = project_fmus / "AUVKinematics.fmu"
    truncated = tmp_path / "truncated.fmu"
    truncated.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    other = tmp_path / "other_platform.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(other, "w") as zout:
        for item in zin.infolist():
            name = item.filename.replace("x86_64-linux", "aarch64-darwin")
            name = name.replace("linux64", "darwin64").replace(".so", ".dylib")
            zout.writestr(name, zin.read(item))
    notzip = tmp_path / "text.fmu"
    notzip.write_text("not an archive")
    return {"truncated": truncated, "other": other, "notzip": notzip,
            "missing": tmp_path / "missing.fmu"}


@pytest.mark.parametrize(("kind", "expected"), [
    ("truncated", "not a valid FMU archive"),
    ("notzip", "not a valid FMU archive"),
    ("other", "no binary for this platform"),
    ("missing", "FMU not found"),
])
def test_bad_fmus_are_refused_before_the_run(tan, tmp_path, broken_fmus, kind, expected):
    path = broken_fmus[kind]
    with pytest.raises(FMUError, match=expected) as info:
        run_scenario(tan([f'fmus.vehicle.path="{path}"']), tmp_path / "run", figures=False)
    assert str(path) in str(info.value)
    assert not (tmp_path / "run" / "log.parquet").exists()


@pytest.mark.parametrize(("overrides", "expected"), [
    (['connections=[["vehicle.xx", "dvl.vx"]]'],
     "key 'connections[0]': FMU 'vehicle' has no variable 'xx'"),
    (['connections=[["vehicle.x", "dvl.vx_m"]]'],
     "'dvl.vx_m' has causality 'output', expected 'input'"),
    (['connections=[["vehicle.x", "dvl.vx"], ["vehicle.y", "dvl.vx"]]'],
     "input 'dvl.vx' is already driven by 'vehicle.x'"),
    (['connections=[["nope.x", "dvl.vx"]]'], "unknown FMU 'nope'"),
    (["run.duration=10.5"], "key 'run.duration': must be a whole number of steps"),
    (['estimators.ekf.type="ekff"'], "unknown estimator 'ekff' (valid: "),
    (["estimators.ekf.bogus=1"],
     "key 'estimators.ekf.bogus': unknown setting for estimator 'ekf' (valid: measurements, "
     "compiled, gate_probability)"),
    (['estimators.ekf.policy="guess"'], "unknown lost-measurement policy 'guess'"),
    (['model.sensors=["dvl", "sonar"]'], "unknown sensor 'sonar'"),
    (['controls.psi.target="vehicle.x"'], "'vehicle.x' has causality 'output'"),
], ids=["variable", "causality", "driven-twice", "fmu", "duration", "estimator", "setting",
        "policy", "sensor", "control-target"])
def test_scenario_errors_with_fmus(tan, tmp_path, overrides, expected):
    with pytest.raises(ScenarioError) as info:
        run_scenario(tan(overrides), tmp_path, figures=False)
    assert expected in str(info.value)
    assert "tan_terrain.toml" in str(info.value)


class _DivergesAtFive(ExtendedKalmanFilter):
    def update(self, z, mask=None):
        if self.t >= 5:
            raise FilterDivergence("covariance not positive definite beyond repair")
        super().update(z, mask)


if "test_diverging" not in ESTIMATORS:
    ESTIMATORS.add("test_diverging", _DivergesAtFive)
    _DivergesAtFive.kind = "test_diverging"


def test_a_diverging_filter_is_flagged_and_the_others_go_on(tan, tmp_path):
    res = run_scenario(tan(["run.duration=30", 'estimators.bad={type="test_diverging"}']),
                       tmp_path, figures=False)
    est = res.summary["estimators"]
    assert est["bad"]["diverged"] and est["bad"]["diverged_at_s"] == 5.0
    assert not est["ekf"]["diverged"] and np.isfinite(est["ekf"]["rmse_position_m"])
    cols, _ = read_log(res.log_path)
    assert np.isnan(cols["est.bad.x"][5:]).all() and np.isfinite(cols["est.ekf.x"]).all()


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "uwcosim", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=300)


def test_cli_user_errors_are_one_line_without_traceback(tmp_path, project_fmus):
    r = _cli("run", str(SCENARIOS / "tan_terrain.toml"), "--set", "run.stp=1",
             "--out", str(tmp_path))
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0
    assert "key 'run.stp': unknown key" in r.stderr
    bad = tmp_path / "x.fmu"
    shutil.copy(SCENARIOS / "tan_terrain.toml", bad)
    r = _cli("run", str(SCENARIOS / "tan_terrain.toml"), "--set", f'fmus.dvl.path="{bad}"',
             "--out", str(tmp_path / "r"))
    assert r.returncode == 3 and "Traceback" not in r.stderr
    assert "not a valid FMU archive" in r.stderr


def test_cli_run_writes_the_run_directory(tmp_path, project_fmus):
    r = _cli("run", str(SCENARIOS / "tan_terrain.toml"), "--set", "run.duration=50",
             "--out", str(tmp_path), "--seed", "4")
    assert r.returncode == 0, r.stderr
    assert "| ekf |" in r.stdout and str(tmp_path) in r.stdout
    assert (tmp_path / "log.parquet").is_file() and (tmp_path / "report.md").is_file()


def test_sigint_to_the_cli_keeps_the_log(tmp_path, project_fmus):
    """A real Ctrl-C (SIGINT) during a run: exit 130, one line, and a readable log."""
    import signal
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "uwcosim", "run", str(SCENARIOS / "tan_terrain.toml"),
         "--out", str(tmp_path), "--set", "log.chunk_steps=50"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    log = tmp_path / "log.parquet"
    deadline = time.monotonic() + 120
    while not log.exists() and time.monotonic() < deadline:  # the run has started
        time.sleep(0.2)
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted at t=" in err
    rows = _rows(log)
    assert 1 < rows < 5001
    assert '"status": "interrupted"' in (tmp_path / "summary.json").read_text()
