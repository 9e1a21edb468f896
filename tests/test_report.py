"""The report stage reads only the run directory; report.md's reproduce command works in a shell;
``--set`` paths are relative to the current folder; the build hint only for our own FMUs."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from uwcosim.api import run_scenario
from uwcosim.cli import main
from uwcosim.core.errors import FMUError
from uwcosim.master.observer import Callback
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "tan_terrain.toml"
RUN_FILES = ("log.parquet", "summary.json", "map.bin", "densities.npz")
FIGURES = ("trajectory.png", "position_error.png", "position_error_norm.png")


@pytest.fixture(scope="module")
def short_run(tmp_path_factory, project_fmus) -> Path:
    out = tmp_path_factory.mktemp("run")
    loaded = load_scenario(SCENARIO, ["run.duration=60", "output.density_snapshots=[10.0]"])
    run_scenario(loaded, out)
    return out


def _copy_run(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True)
    for f in RUN_FILES:
        shutil.copy(src / f, dst / f)
    return dst


def _no_live_objects(monkeypatch):
    """Fail loudly if the report stage tries to load a scenario or start a master."""
    def refuse(*a, **k):
        raise AssertionError("the report stage must read only the run directory")

    monkeypatch.setattr("uwcosim.scenario.load.load_scenario", refuse)
    monkeypatch.setattr("uwcosim.master.master.Master.__init__", refuse)
    monkeypatch.setattr("uwcosim.run.factory.build_model", refuse)


def _table(report: Path) -> list[str]:
    return [line for line in report.read_text().splitlines() if line.startswith("| ")]


def test_run_log_metadata_names_what_the_report_needs(short_run):
    _, meta = read_log(short_run / "log.parquet")
    assert meta["truth"] == ["vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy"]
    assert meta["states"] == ["x", "y", "vx", "vy"]
    assert meta["estimators"]["pfm_psi"] == "pfm_psi" and meta["map"] == "map.bin"
    assert meta["measurements"] == ["dvl.vx_m", "dvl.vy_m", "sounder.depth_m"]


def test_report_rebuilds_figures_and_report_from_the_files_alone(short_run, tmp_path,
                                                                 monkeypatch, capsys):
    run = _copy_run(short_run, tmp_path / "elsewhere" / "run")
    _no_live_objects(monkeypatch)
    assert main(["report", str(run)]) == 0
    for f in (*FIGURES, "density_t10.png", "report.md"):
        assert (run / f).is_file(), f
    assert _table(run / "report.md") == _table(short_run / "report.md")
    out = tmp_path / "other"
    assert main(["report", str(run), "--out", str(out)]) == 0
    assert (out / "report.md").read_text() == (run / "report.md").read_text()
    assert not (out / "log.parquet").exists()


def test_report_of_an_older_log_without_the_new_metadata(short_run, tmp_path, monkeypatch):
    run = _copy_run(short_run, tmp_path / "old")
    table = pq.read_table(run / "log.parquet")
    meta = json.loads(table.schema.metadata[b"uwcosim"])
    for key in ("truth", "states", "estimators", "measurements", "map", "scenario_name"):
        meta.pop(key)
    pq.write_table(table.replace_schema_metadata({"uwcosim": json.dumps(meta)}),
                   run / "log.parquet")
    (run / "summary.json").unlink()
    _no_live_objects(monkeypatch)
    assert main(["report", str(run)]) == 0
    text = (run / "report.md").read_text()
    assert "recomputed from the log" in text
    original = json.loads((short_run / "summary.json").read_text())["estimators"]
    for line in _table(run / "report.md")[2:]:
        name, pos = (c.strip() for c in line.strip("|").split("|")[:2])
        assert float(pos) == pytest.approx(original[name]["rmse_position_m"], abs=0.006)
    for f in FIGURES:
        assert (run / f).is_file(), f


def test_evaluate_rebuilds_the_summary_from_the_files_alone(short_run, tmp_path, monkeypatch):
    """evaluate() of a copy of the run directory (log, simulation.json) gives the summary the
    run wrote, timing and status included, without a scenario, a master or a model."""
    from uwcosim import evaluate

    run = _copy_run(short_run, tmp_path / "copy")
    shutil.copy(short_run / "simulation.json", run / "simulation.json")
    (run / "summary.json").unlink()
    _no_live_objects(monkeypatch)
    original = json.loads((short_run / "summary.json").read_text())
    assert json.loads(json.dumps(evaluate(run))) == original
    assert json.loads((run / "summary.json").read_text()) == original
    assert original["timing"]["fmus_per_step_s"] > 0 and original["status"] == "ok"
    assert set(original["estimators"]) == set(read_log(run / "log.parquet")[1]["estimators"])
    out = tmp_path / "elsewhere"
    evaluate(run, out)  # into another folder; the run directory is left as it is
    assert json.loads((out / "summary.json").read_text()) == original


def test_evaluate_of_a_run_killed_before_its_simulation_file(short_run, tmp_path):
    from uwcosim import evaluate

    run = _copy_run(short_run, tmp_path / "killed")
    (run / "summary.json").unlink()
    summary = evaluate(run)
    assert summary["status"] == "unknown" and summary["timing"] == {}
    assert any("recomputed from the log" in n for n in summary["notes"])
    original = json.loads((short_run / "summary.json").read_text())["estimators"]
    for name, m in summary["estimators"].items():
        assert m["rmse_position_m"] == original[name]["rmse_position_m"]


def test_report_of_a_folder_that_is_no_run(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "neither a run directory" in err


def test_map_coefficients_read_back(short_run):
    from uwcosim.models.terrain import read_coefficients, synthetic_bathymetry

    b = read_coefficients(short_run / "map.bin")
    ref = synthetic_bathymetry(7)
    assert b.extent == ref.extent
    np.testing.assert_allclose(b.depth_grid, ref.depth_grid, atol=1e-9)


def _uwcosim_env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def test_reproduce_command_in_report_md_gives_the_identical_log(project_fmus, tmp_path):
    """Overrides with spaces, quotes and braces, and a path relative to the current folder."""
    first = tmp_path / "here"
    first.mkdir()
    shutil.copy(ROOT / "fmus" / "DVL.fmu", first / "my_dvl.fmu")
    overrides = ["run.duration=40", 'sensors.depth.loss={model="bernoulli", p=0.3}',
                 "estimators.pf.n_particles=300", "fmus.dvl.path=my_dvl.fmu"]
    args = ["uwcosim", "run", str(SCENARIO), "--seed", "5", "--out", "run"]
    for o in overrides:
        args += ["--set", o]
    subprocess.run(args, cwd=first, env=_uwcosim_env(), check=True, capture_output=True)
    report = (first / "run" / "report.md").read_text()
    block = re.search(r"```sh\n(.*?)\n```", report, re.S)
    assert block, report
    command = block.group(1)
    assert "\n" not in command and command.startswith("uwcosim run ")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    res = subprocess.run(["bash", "-c", command], cwd=elsewhere, env=_uwcosim_env(),
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    again = Path(command.rsplit(" --out ", 1)[1].strip("'"))
    assert again == (first / "run").resolve().with_name("run-reproduced")
    assert (again / "log.parquet").read_bytes() == (first / "run" / "log.parquet").read_bytes()


def test_set_paths_are_relative_to_the_current_folder(project_fmus, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shutil.copy(ROOT / "fmus" / "DVL.fmu", tmp_path / "dvl.fmu")
    cli = load_scenario(SCENARIO, ["fmus.dvl.path=dvl.fmu"], overrides_base=Path.cwd())
    assert cli.spec.fmus["dvl"].path == str(tmp_path / "dvl.fmu")
    assert cli.overrides == (f'fmus.dvl.path="{tmp_path / "dvl.fmu"}"',)
    # without a base (campaign specs, the library): relative to the scenario file, as before
    lib = load_scenario(SCENARIO, ["fmus.dvl.path=dvl.fmu"])
    assert lib.resolve(lib.spec.fmus["dvl"].path) == SCENARIO.parent / "dvl.fmu"
    assert lib.overrides == (f'fmus.dvl.path="{SCENARIO.parent / "dvl.fmu"}"',)


def test_build_hint_only_for_the_projects_own_fmus(tmp_path):
    from uwcosim.fmi.adapter import read_description

    with pytest.raises(FMUError, match="uwcosim fmu build"):
        read_description(tmp_path / "AUVKinematics.fmu")
    with pytest.raises(FMUError) as exc:
        read_description(tmp_path / "ThirdPartyVehicle.fmu")
    assert str(exc.value) == f"{tmp_path / 'ThirdPartyVehicle.fmu'}: FMU not found"


def test_report_of_a_campaign_without_results(tmp_path, capsys):
    (tmp_path / "results").mkdir()
    assert main(["report", str(tmp_path), "--html"]) == 1
    assert "no run results to report" in capsys.readouterr().err


def test_report_of_an_interrupted_run(project_fmus, tmp_path, capsys):
    """A run stopped by Ctrl-C at t=30 keeps its log; the report stage makes its report."""
    from uwcosim.core.errors import RunInterrupted

    def interrupt(k, view):
        if k == 30:
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted):
        run_scenario(load_scenario(SCENARIO, ["run.duration=100"]), tmp_path,
                     progress=Callback(interrupt))
    assert not (tmp_path / "report.md").exists()
    assert main(["report", str(tmp_path), "--html"]) == 0
    text = (tmp_path / "report.md").read_text()
    assert "status interrupted" in text and "| ekf |" in text
    for f in (*FIGURES, "report.html"):
        assert (tmp_path / f).is_file(), f
    summary = json.loads((tmp_path / "summary.json").read_text())  # rebuilt by the report
    assert summary["status"] == "interrupted" and summary["steps"] == 30
    assert summary["estimators"]["ekf"]["time_per_step_s"] > 0  # from simulation.json


def test_a_failing_evaluation_still_leaves_a_summary(project_fmus, tmp_path, monkeypatch):
    """simulate() writes summary.json on every exit path, even when evaluate() breaks."""
    from uwcosim import simulate

    def broken(*a, **k):
        raise ValueError("broken metric")

    monkeypatch.setattr("uwcosim.evaluation.summary.estimator_metrics", broken)
    run = simulate(load_scenario(SCENARIO, ["run.duration=5", 'estimators={e={type="ekf"}}']),
                   tmp_path)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["estimators"] == {}
    assert any("evaluation failed (ValueError: broken metric)" in n for n in summary["notes"])
    sim = json.loads((run / "simulation.json").read_text())
    assert sim["estimators"]["e"]["time_per_step_s"] > 0 and sim["steps"] == 5
