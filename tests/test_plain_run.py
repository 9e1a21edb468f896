"""Plain co-simulation runs (no [model], no [estimators]), the master built from a System in
code, and the unzipped FMU folders the master owns and deletes."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from uwcosim.cli import main
from uwcosim.master import FMU, Control, Master, System
from uwcosim.master.observer import Callback
from uwcosim.runlog import read_log

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def private_tmp(tmp_path, monkeypatch) -> Path:
    """A temporary folder of our own (the machine's /tmp is shared with other test runs)."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(d))
    monkeypatch.setenv("TMPDIR", str(d))
    return d


def _fmu_dirs(tmp: Path) -> list[Path]:
    return sorted(tmp.glob("uwcosim_fmu_*"))


def plain_toml(fmus: Path, extra: str = "") -> str:
    """Vehicle (constant heading and acceleration) feeding a DVL; no model, no estimators."""
    return f"""
name = "plain"
connections = [["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"]]

[run]
duration = 20.0
step = 0.5

[fmus.vehicle]
path = "{fmus / 'AUVKinematics.fmu'}"
start = {{ x = 10, y = -5.0, vx = 0.5, vy = 0.0 }}

[fmus.dvl]
path = "{fmus / 'DVL_fmi2.fmu'}"

[controls.psi]
target = "vehicle.psi"
table = [[0, 0.3]]

[controls.a]
target = "vehicle.a"
table = [[0, 0.01]]

[sensors.dvl]
outputs = ["dvl.vx_m", "dvl.vy_m"]
noise_inputs = ["dvl.e_vx", "dvl.e_vy"]
sigma = [0.05, 0.05]

[log]
signals = ["vehicle.*", "dvl.vx_m", "controls.*"]
{extra}
"""


def write(tmp_path: Path, text: str, name: str = "plain.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_plain_scenario_runs_end_to_end(project_fmus, tmp_path, capsys, private_tmp):
    sc = write(tmp_path, plain_toml(project_fmus))
    out = tmp_path / "run"
    assert main(["run", str(sc), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "status ok: 40 steps of 0.5 s" in printed
    cols, meta = read_log(out / "log.parquet")
    names = pq.read_schema(out / "log.parquet").names
    assert names[0] == "time"
    assert set(names) == {"time", "vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy",
                          "vehicle.psi_out",
                          "dvl.vx_m", "controls.psi", "controls.a"}
    np.testing.assert_array_equal(cols["time"], 0.5 * np.arange(41))
    # eq. (54) with constant psi and a: the velocity along the heading grows linearly
    c, s = np.cos(0.3), np.sin(0.3)
    t = cols["time"]
    np.testing.assert_allclose(cols["vehicle.vx"], 0.5 + 0.01 * c * t, atol=1e-12)
    np.testing.assert_allclose(cols["vehicle.vy"], 0.01 * s * t, atol=1e-12)
    # the DVL's noise comes from the master's seeded stream: measured = true + noise
    assert 0.01 < np.std(cols["dvl.vx_m"][1:] - cols["vehicle.vx"][1:]) < 0.1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["estimators"] == {}
    assert summary["steps"] == 40 and summary["end_time_s"] == 20.0
    assert {"fmu.vehicle_s", "fmu.dvl_s", "master_s"} <= set(summary["timing"])
    assert summary["fmus"]["dvl"]["fmi_version"] == "2.0"
    assert summary["fmus"]["vehicle"]["time_s"] == summary["timing"]["fmu.vehicle_s"] > 0
    report = (out / "report.md").read_text()
    assert "![signals](signals.png)" in report and "| vehicle |" in report
    assert f"uwcosim run plain.toml --seed {summary['seed']}" in report
    assert (out / "signals.png").stat().st_size > 10_000
    assert _fmu_dirs(private_tmp) == []  # the master deleted the folders it unzipped to
    # the report stage rebuilds summary, signals figure and report from the files alone
    again = out.parent / "again"
    assert main(["report", str(out), "--out", str(again)]) == 0
    assert json.loads((again / "summary.json").read_text()) == summary
    assert (again / "report.md").read_text() == report and (again / "signals.png").is_file()


def test_plain_run_same_seed_same_bytes(project_fmus, tmp_path):
    sc = write(tmp_path, plain_toml(project_fmus))
    for d in ("a", "b"):
        assert main(["run", str(sc), "--out", str(tmp_path / d), "--no-figures"]) == 0
    assert (tmp_path / "a/log.parquet").read_bytes() == (tmp_path / "b/log.parquet").read_bytes()
    assert not (tmp_path / "a/report.md").exists()


def test_tan_scenario_without_estimators(project_fmus, tmp_path, capsys):
    """The issue's reproduction: a model but no estimators used to crash in the log hook."""
    out = tmp_path / "x"
    rc = main(["run", str(ROOT / "scenarios/tan_terrain.toml"), "--set", "estimators={}",
               "--set", "run.duration=10", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    cols, _ = read_log(out / "log.parquet")
    assert cols["time"].size == 11 and "vehicle.x" in cols and "controls.psi" in cols
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["estimators"] == {}
    assert (out / "report.md").is_file()


def test_plain_run_bad_variable_is_one_line(project_fmus, tmp_path, capsys):
    sc = write(tmp_path, plain_toml(project_fmus).replace('"dvl.vy"]]', '"dvl.nope"]]'))
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "key 'connections[1]'" in err and "no variable 'nope'" in err


def test_master_from_a_system_built_in_code(project_fmus, private_tmp):
    system = System(
        fmus={"vehicle": FMU(project_fmus / "AUVKinematics_fmi2.fmu", interface="me",
                             start={"x": 0.0, "vx": 1.0}),
              "dvl": FMU(project_fmus / "DVL.fmu", period=2)},
        connections=[("vehicle.vx", "dvl.vx"), ("vehicle.vy", "dvl.vy")],
        controls={"a": Control(target="vehicle.a", table=[[0, 0.0], [10, 0.2]])},
        step=0.25, duration=10.0,
    )
    m = Master(system, seed=1)
    assert not hasattr(m, "spec") and m.system is system  # the master knows no scenario
    try:
        rows = []
        m.observers.append(Callback(lambda k, v: k and rows.append(
            (v.t, v.signal("vehicle.vx"), v.signal("dvl.vx_m")))))
        m.initialize()
        assert _fmu_dirs(private_tmp) == [Path(m.unzip_root)]
        assert {p.name for p in Path(m.unzip_root).iterdir()} == {"vehicle", "dvl"}
        m.run_until(10.0)
    finally:
        m.close()
    assert _fmu_dirs(private_tmp) == []
    t, vx, dvl = np.array(rows).T
    # ME with a linear ramp of a evaluated at stage times: vx = 1 + 0.01 t^2 exactly (RK4)
    np.testing.assert_allclose(vx, 1.0 + 0.01 * t**2, atol=1e-12)
    # the DVL runs every 2 steps (k = 2, 4, ...; row i is k = i + 1): it holds in between
    np.testing.assert_array_equal(dvl[1:-1:2], dvl[2::2])
    assert np.all(np.diff(dvl[1::2]) > 0)


def test_system_errors_name_the_system(project_fmus):
    system = System(fmus={"v": FMU(project_fmus / "AUVKinematics.fmu")},
                    connections=[("v.x", "v.nothing")], step=1.0, duration=2.0)
    with pytest.raises(Exception, match=r"^system: key 'connections\[0\]': FMU 'v' has no "):
        Master(system)


def test_worker_process_fmu_leaves_no_folder(project_fmus, tmp_path, private_tmp):
    sc = write(tmp_path, plain_toml(project_fmus, ""), "p.toml")
    sc.write_text(sc.read_text().replace('[fmus.dvl]\n', '[fmus.dvl]\ntimeout_s = 30\n'))
    assert main(["run", str(sc), "--out", str(tmp_path / "r"), "--no-figures"]) == 0
    assert _fmu_dirs(private_tmp) == []


def test_unclosed_master_cleans_up_at_process_exit(project_fmus):
    """Campaign workers keep their masters open for reuse: the folder goes at process exit."""
    import subprocess
    import sys

    code = ("from uwcosim.master import FMU, Master, System\n"
            f"m = Master(System(fmus={{'v': FMU({str(project_fmus / 'DVL.fmu')!r})}}, "
            "step=1.0, duration=1.0))\n"
            "m.initialize()\nprint(m.unzip_root)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120)
    root = Path(out.stdout.strip())
    assert root.name.startswith("uwcosim_fmu_") and not root.exists()


def test_campaign_workers_leave_no_folder(project_fmus, tmp_path, private_tmp):
    """Campaign workers keep one master per scenario for many runs (instances reset, not
    unzipped again) and clean up when the pool shuts down."""
    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.driver import run_campaign

    spec = tmp_path / "c.toml"
    spec.write_text(f'name = "c"\nseed = 1\nruns = 3\n[[variants]]\nname = "plain"\n'
                    f'scenario = "{write(tmp_path, plain_toml(project_fmus))}"\n'
                    f'set = ["run.duration=5"]\n')
    summary = run_campaign(load_campaign(spec), tmp_path / "out", workers=2, figures=False)
    assert summary["runs"] == 3 and not summary.get("failed")
    assert _fmu_dirs(private_tmp) == []
