"""The walk-through of ``docs/replay.md``, run as written: the generated mission, the
scenario in ``examples/replay``, ``uwcosim check``/``run``/``report --html``/``export --csv``
and what the page says of their outputs."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "replay"
DOC = ROOT / "docs" / "replay.md"


def test_the_committed_mission_is_what_the_generator_writes(tmp_path):
    h5netcdf = pytest.importorskip("h5netcdf")
    spec = importlib.util.spec_from_file_location("make_mission", EXAMPLE / "make_mission.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.main(tmp_path)
    assert (tmp_path / "mission.csv").read_bytes() == (EXAMPLE / "mission.csv").read_bytes()
    with h5netcdf.File(tmp_path / "seafloor.nc", "r") as a, \
            h5netcdf.File(EXAMPLE / "seafloor.nc", "r") as b:
        for v in ("lat", "lon", "elevation"):
            np.testing.assert_array_equal(a.variables[v][...], b.variables[v][...])
    # the head of the file as the page shows it
    head = (EXAMPLE / "mission.csv").read_text().splitlines()[:4]
    text = DOC.read_text()
    for line in head:
        assert line in text, line


def test_the_walk_through(tmp_path, cli, monkeypatch):
    monkeypatch.chdir(EXAMPLE)
    out = tmp_path / "mission"
    code, printed, err = cli("check", "mission.toml")
    assert code == 0 and err == []
    assert "mission.toml: ok (checked: schema, replay file, map and filters)" in printed
    assert "mission.toml: ok (checked: schema, replay file, map and filters)" in DOC.read_text()
    code, printed, err = cli("run", "mission.toml", "--out", out)
    assert code == 0, err
    progress = "uwcosim: replaying 601 steps (602 rows of mission.csv, t = 0 .. 599.437 s)"
    assert progress in err and progress.removeprefix("uwcosim: ") in " ".join(
        DOC.read_text().split())
    assert "| ekf |" in printed and f"run directory: {out}" in printed
    for f in ("log.parquet", "simulation.json", "summary.json", "trajectory.png",
              "position_error.png", "position_error_norm.png", "report.md"):
        assert (out / f).is_file(), f
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "ok" and s["steps"] == 601 and s["replay"]["rows"] == 602
    note = ("the replay's reference (mission.csv) has a position at 5 of the 601 filtered "
            "steps: RMSE and NEES are over the steps that have a reference (NEES: those with "
            "every state); no reference for vx, vy (their RMSE is NaN)")
    assert note in s["notes"] and note in " ".join(DOC.read_text().split())
    for name, m in s["estimators"].items():
        assert m["reference_steps"] == 5 and not m["diverged"], name
        assert 0 < m["rmse_position_m"] < 20, name
    report = (out / "report.md").read_text()
    assert "Replay of `mission.csv`" in report and "602 rows (of 602)" in report
    assert "+proj=tmerc" in report
    from uwcosim.runlog import read_log

    cols, meta = read_log(out / "log.parquet")
    np.testing.assert_array_equal(np.diff(cols["time"]) > 0.69, True)
    assert np.ptp(np.diff(cols["time"])) > 0.5  # irregular
    for c in ("fix.x", "fix.y", "controls.psi", "z.dvl.vx_m", "z.dvl.vx_m.received",
              "truth.lat_deg", "truth.lon_deg", "est.ekf.lat_deg", "est.ekf.lon_deg"):
        assert c in cols, c
    assert int(np.isfinite(cols["fix.x"]).sum()) == 6
    assert meta["geo"]["trajectory_axes"] == "latlon"
    # the page's claims on the columns: knots converted, heading converted to psi
    raw = (EXAMPLE / "mission.csv").read_text().splitlines()[1].split(",")
    assert cols["controls.psi"][0] == pytest.approx(np.pi / 2 - float(raw[1]) * np.pi / 180)
    second = (EXAMPLE / "mission.csv").read_text().splitlines()[2].split(",")
    assert cols["z.dvl.vx_m"][1] == pytest.approx(float(second[3]) * 1852 / 3600)
    code, printed, _ = cli("report", out, "--html")
    assert code == 0 and (out / "report.html").is_file()
    code, printed, _ = cli("export", out, "--csv")
    assert code == 0
    header = (out / "log.csv").read_text().splitlines()[0]
    assert '"truth.lat_deg [deg]"' in header and '"est.ekf.lon_deg [deg]"' in header
    # the commands of section 3 are the ones run here
    block = re.search(r"## 3\. Running it\n\n```sh\n(.*?)```", DOC.read_text(), re.S).group(1)
    for cmd in ("uwcosim check mission.toml", "uwcosim run mission.toml --out",
                "uwcosim report /tmp/mission --html", "uwcosim export /tmp/mission --csv"):
        assert cmd in block, cmd


def test_the_example_validates_against_the_json_schema():
    jsonschema = pytest.importorskip("jsonschema")
    import tomllib

    from uwcosim.scenario.json_schema import scenario_json_schema

    validator = jsonschema.Draft202012Validator(scenario_json_schema())
    data = tomllib.loads((EXAMPLE / "mission.toml").read_text())
    assert list(validator.iter_errors(data)) == []


def test_the_readme_links_the_page():
    text = (ROOT / "README.md").read_text()
    assert "docs/replay.md" in text
