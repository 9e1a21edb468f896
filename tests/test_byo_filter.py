"""A user's filter is a first-class estimator (docs/your_own_filter.md): by import path and by
entry point, in a run and in 2-worker campaigns (local processes, a local Dask cluster); its
settings checked like a built-in's; its errors (exception, NaN, wrong shapes) stop only it; the
log records its code; the reproduce command works."""

from __future__ import annotations

import json
import logging
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

try:
    from byo_example import EXAMPLE, SCENARIO, example_fmus, install_example, uwcosim_env
except ImportError:  # pragma: no cover - run from the project root as a package
    from tests.byo_example import EXAMPLE, SCENARIO, example_fmus, install_example, uwcosim_env

from uwcosim.core.errors import ScenarioError
from uwcosim.core.plugins import file_sha256, import_object
from uwcosim.run.simulate import simulate
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario

__all__ = ["example_fmus"]  # the fixture

ROOT = Path(__file__).resolve().parents[1]
TAN = ROOT / "scenarios" / "tan_terrain.toml"
UWCOSIM = str(Path(sys.executable).parent / "uwcosim")

FAULTY = '''
"""Filters that fail on purpose (tests/test_byo_filter.py)."""
from typing import Literal

import numpy as np
from pydantic import Field, StrictInt

from uwcosim.filters import FilterSettings
from uwcosim.filters.kalman import ExtendedKalmanFilter


class Faulty(ExtendedKalmanFilter):
    """EKF that fails at step ``at`` in the way ``how`` says."""

    class Settings(FilterSettings):
        at: StrictInt = Field(20, description="the step that fails")
        how: Literal["raise", "nan", "shape_x", "shape_P", "list_x"] = "raise"

    def update(self, z, mask=None):
        super().update(z, mask)
        if self.t >= self.settings.at:
            how = self.settings.how
            if how == "raise":
                self.x = self.x * (1.0 / (float(self.t) - float(self.t)))
            if how == "nan":
                self.x = self.x * np.nan
            if how == "shape_x":
                self.x = self.x[:3]
            if how == "shape_P":
                self.P = self.P[:3, :3]
            if how == "list_x":
                self.x = [1.0, 2.0]


class Plain:
    """A filter of the interface that derives from nothing: prediction only."""

    needs_rng = True

    def __init__(self, model, x0, P0, rng):
        assert isinstance(rng, np.random.Generator)
        self.model, self.x, self.P = model, np.array(x0, float), np.array(P0, float)

    def predict(self, u, dt):
        F, Q = self.model.F(self.x, u, dt), self.model.Q(self.x, u, dt)
        self.x = self.model.f(self.x, u, dt)
        self.P = F @ self.P @ F.T + Q

    def update(self, z, mask=None):
        pass


NOT_A_CLASS = 3


class NoUpdate:
    def predict(self, u, dt):
        pass
'''


@pytest.fixture(scope="session")
def faulty_dir(tmp_path_factory) -> Path:
    """One folder for the session with ``byo_faulty_filters`` (a module name is imported once
    per process: one file for every test)."""
    d = tmp_path_factory.mktemp("faulty")
    (d / "byo_faulty_filters.py").write_text(FAULTY)
    (d / "byo_broken_syntax.py").write_text("def f(:\n")
    (d / "byo_broken_import.py").write_text("x = {}\ny = x['boom']\n")
    return d


@pytest.fixture
def faulty(faulty_dir, monkeypatch):
    """The current folder is :func:`faulty_dir` (searched for ``package.module:Name``)."""
    monkeypatch.chdir(faulty_dir)
    return faulty_dir


def _cli(*args, cwd=None, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([UWCOSIM, *args], cwd=cwd, env=env or uwcosim_env(),
                          capture_output=True, text=True, timeout=600)


def _meta(run: Path) -> dict:
    return json.loads(pq.read_schema(run / "log.parquet").metadata[b"uwcosim"])


# -- by path: a run and everything downstream ------------------------------------------------
def test_user_filter_by_path_in_a_run_and_everything_downstream(example_fmus, tmp_path):
    run = tmp_path / "run"
    res = _cli("run", str(SCENARIO), "--set", "run.duration=200", "--set",
               'estimators={ekf={type="ekf"}, gated_ekf={type="current_nav.gated_ekf:GatedEKF"'
               ', gate=3.0}}', "--out", str(run), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    summary = json.loads((run / "summary.json").read_text())
    m = summary["estimators"]["gated_ekf"]
    assert np.isfinite(m["rmse_position_m"]) and np.isfinite(m["anees"]) and not m["diverged"]
    assert np.isfinite(m["mean_nis"])
    cols, meta = read_log(run / "log.parquet")
    assert np.isfinite(cols["est.gated_ekf.nees"][1:]).all()
    assert "est.gated_ekf.diverged" in cols
    origin = meta["user_code"]["estimators"]["gated_ekf"]
    file = EXAMPLE / "current_nav" / "gated_ekf.py"
    assert origin["source"] == "path" and origin["target"] == "current_nav.gated_ekf:GatedEKF"
    assert origin["module_file"] == str(file) and origin["module_sha256"] == file_sha256(file)
    assert origin["version"] == "0.1.0" and origin["found_in"] == str(EXAMPLE)
    report = (run / "report.md").read_text()
    assert "User code of this run:" in report and "current_nav.gated_ekf:GatedEKF" in report
    assert (run / "trajectory.png").is_file()
    assert _cli("report", str(run), "--html").returncode == 0
    html = (run / "report.html").read_text()
    assert "gated_ekf" in html and "User code" in html
    same = _cli("regress", str(run), str(run / "log.parquet"), "--rtol", "0", "--atol", "0",
                "--ttol", "0", "--no-plots")
    assert same.returncode == 0 and "identical values" in same.stdout
    base = tmp_path / "baselines"
    sets = ["--set", "run.duration=100"]
    assert _cli("baseline", "update", str(SCENARIO), "--dir", str(base), *sets).returncode == 0
    check = _cli("baseline", "check", str(SCENARIO), "--dir", str(base))
    assert check.returncode == 0, check.stdout + check.stderr


def test_user_filter_by_path_also_through_the_python_api(example_fmus, tmp_path):
    """``load_scenario`` + ``simulate``: the scenario's folder is searched from any folder."""
    loaded = load_scenario(SCENARIO, ["run.duration=50", 'estimators={g={type='
                                      '"current_nav.gated_ekf:GatedEKF", gated=["beacon_a.'
                                      'range_m"]}}'])
    out = simulate(loaded, tmp_path / "api", seed=1)
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["estimators"]["g"]["diverged"]
    assert summary["estimators"]["g"]["rmse_position_m"] < 50


# -- settings and import errors: one line, as for built-ins ---------------------------------
def test_settings_problems_are_the_built_in_filters_one_liners(example_fmus, tmp_path):
    res = _cli("check", str(SCENARIO), "--set", "estimators.gated_ekf.gat=1", "--set",
               'estimators.gated_ekf.gate="3"', "--set", "estimators.ekf.gate=3.0")
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and len(lines) == 3, res.stderr
    assert any("key 'estimators.gated_ekf.gat': unknown setting for estimator "
               "'current_nav.gated_ekf:GatedEKF' (valid: gate, gated, measurements)" in ln
               for ln in lines)
    assert any("key 'estimators.gated_ekf.gate': Input should be a valid number (got '3')"
               in ln for ln in lines)
    # the built-in's line, for comparison: the same words
    assert any("key 'estimators.ekf.gate': unknown setting for estimator 'ekf' (valid: "
               "measurements, compiled, gate_probability)" in ln for ln in lines)
    bad = _cli("check", str(SCENARIO), "--set", 'estimators.gated_ekf.gated=["nope"]')
    assert bad.returncode == 2 and "key 'estimators.gated_ekf': gated: unknown measurements " \
        "['nope']" in bad.stderr


@pytest.mark.parametrize("type_, expected", [
    ("byo_nowhere.mod:X", "type 'byo_nowhere.mod:X': no module named 'byo_nowhere'"),
    ("byo_faulty_filters:Missing", "module 'byo_faulty_filters' ("),
    ("byo_faulty_filters:NOT_A_CLASS", "'byo_faulty_filters:NOT_A_CLASS': it is not a class "
                                       "(an object of type int)"),
    ("byo_faulty_filters:NoUpdate", "it has no update method"),
    ("byo_broken_syntax:X", "importing 'byo_broken_syntax' failed: SyntaxError: "),
    ("byo_broken_import:X", "importing 'byo_broken_import' failed: KeyError: 'boom' "
                            "(byo_broken_import.py:2)"),
    ("not a path", "unknown estimator 'not a path' (valid: "),
])
def test_import_errors_are_one_line_naming_the_type(faulty, type_, expected):
    with pytest.raises(ScenarioError) as info:
        load_scenario(TAN, [f'estimators.e.type="{type_}"'])
    msg = str(info.value)
    assert "\n" not in msg and "key 'estimators.e.type'" in msg and expected in msg, msg


def test_cli_import_error_exit_2_without_traceback(faulty):  # a process of its own
    res = _cli("run", str(TAN), "--set", 'estimators.e.type="byo_faulty_filters:Missing"',
               cwd=faulty)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_sys_path_is_restored_and_the_module_stays_imported(faulty):
    before = list(sys.path)
    load_scenario(TAN, ['estimators.e.type="byo_faulty_filters:Faulty"'])
    assert sys.path == before and "byo_faulty_filters" in sys.modules


def test_one_module_name_per_process(tmp_path):
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "byo_twice.py").write_text("class X:\n    pass\n")
    obj, origin = import_object("byo_twice:X", [tmp_path / "a"])
    assert origin.found_in == str(tmp_path / "a")
    assert import_object("byo_twice:X", [tmp_path / "a"])[0] is obj
    with pytest.raises(ScenarioError, match=r"module 'byo_twice' is already imported from "
                       r".*a/byo_twice\.py, not from .*b/byo_twice\.py"):
        import_object("byo_twice:X", [tmp_path / "b"])


def test_list_and_schema_cover_a_user_filter(example_fmus, tmp_path):
    jsonschema = pytest.importorskip("jsonschema")
    import tomllib

    res = _cli("list", "estimators", "--scenario", str(SCENARIO))
    assert res.returncode == 0, res.stderr
    assert "ekf: EKF" in res.stdout and "[built-in]" in res.stdout
    assert re.search(r"current_nav\.gated_ekf:GatedEKF: .* \[by path .*gated_ekf\.py "
                     r"\(version 0\.1\.0\)\]", res.stdout)
    assert "    gate=3.0 (float): innovation gate" in res.stdout
    out = tmp_path / "schema.json"
    assert _cli("schema", "--scenario", str(SCENARIO), "--out", str(out)).returncode == 0
    validator = jsonschema.Draft202012Validator(json.loads(out.read_text()))
    data = tomllib.loads(SCENARIO.read_text())
    assert list(validator.iter_errors(data)) == []
    data["estimators"]["gated_ekf"]["gat"] = 1
    assert list(validator.iter_errors(data))  # its own variant: unknown keys refused
    generic = tmp_path / "generic.json"
    assert _cli("schema", "--out", str(generic)).returncode == 0
    validator = jsonschema.Draft202012Validator(json.loads(generic.read_text()))
    assert list(validator.iter_errors(data)) == []  # any settings of an unknown class
    data["estimators"]["gated_ekf"]["type"] = "not a path"
    assert list(validator.iter_errors(data))


# -- an error inside a user filter stops only that estimator ---------------------------------
@pytest.mark.parametrize("how, why", [
    ("raise", r"ZeroDivisionError: float division by zero \(byo_faulty_filters\.py:\d+\)"),
    ("nan", r"estimate has NaN or infinite entries"),
    ("shape_x", r"x has shape \(3,\), expected \(4,\)"),
    ("shape_P", r"P has shape \(3, 3\), expected \(4, 4\)"),
    ("list_x", r"x has shape \(2,\), expected \(4,\)"),
])
def test_a_failing_user_filter_stops_only_itself(project_fmus, faulty, tmp_path, caplog, how,
                                                 why):
    common = ["run.duration=60", "output.density_snapshots=[]"]
    with caplog.at_level(logging.WARNING, logger="uwcosim.run.bank"):
        sets = [*common, 'estimators={ekf={type="ekf"}, bad={type="byo_faulty_filters:Faulty", '
                f'at=20, how="{how}"}}}}']
        bad = simulate(load_scenario(TAN, sets), tmp_path / "bad", seed=2)
    good = simulate(load_scenario(TAN, [*common, 'estimators={ekf={type="ekf"}}']),
                    tmp_path / "good", seed=2)
    summary = json.loads((bad / "summary.json").read_text())
    assert summary["status"] == "ok"
    est = summary["estimators"]["bad"]
    assert est["diverged"] and est["diverged_at_s"] == 20.0 and est["stopped_step"] == 20
    assert re.search(why, est["error"]), est["error"]
    assert not summary["estimators"]["ekf"]["diverged"]
    lines = [r.getMessage() for r in caplog.records if r.name == "uwcosim.run.bank"]
    assert len(lines) == 1 and re.search(
        r"^estimator 'bad' \(byo_faulty_filters:Faulty\) stopped at step 20 \(t=20 s\): "
        + why, lines[0]), lines
    cols, _ = read_log(bad / "log.parquet")
    ref, _ = read_log(good / "log.parquet")
    assert cols["time"].size == ref["time"].size == 61  # the log goes on
    for c in ref:  # the other estimator, bit for bit
        if c.startswith("est.ekf."):
            np.testing.assert_array_equal(cols[c], ref[c])
    assert np.isnan(cols["est.bad.x"][20:]).all() and cols["est.bad.diverged"][20:].all()
    assert np.isfinite(cols["est.bad.x"][:20]).all()


def test_a_plain_class_with_the_interface_is_an_estimator(project_fmus, faulty, tmp_path):
    out = simulate(load_scenario(TAN, ["run.duration=20", "output.density_snapshots=[]",
                                       'estimators={p={type="byo_faulty_filters:Plain"}}']),
                   tmp_path / "plain", seed=1)
    est = json.loads((out / "summary.json").read_text())["estimators"]["p"]
    assert not est["diverged"] and np.isnan(est["mean_nis"])


# -- the reproduce command ------------------------------------------------------------------
def test_reproduce_command_of_a_run_with_a_user_filter(project_fmus, tmp_path):
    """The module is in the run's current folder (not beside the scenario): the command cd's
    there, and gives the identical log from another folder."""
    here = tmp_path / "here"
    here.mkdir()
    (here / "byo_repro_filters.py").write_text(FAULTY)
    run = _cli("run", str(TAN), "--seed", "4", "--out", "run", "--no-figures", "--set",
               "run.duration=30", "--set", 'estimators={ekf={type="ekf"}, mine={type='
               '"byo_repro_filters:Faulty", at=1000}}', cwd=here)
    assert run.returncode == 0, run.stderr
    assert _cli("report", str(here / "run")).returncode == 0
    report = (here / "run" / "report.md").read_text()
    command = re.search(r"```sh\n(.*?)\n```", report, re.S).group(1)
    assert command.startswith(f"cd {here} && uwcosim run "), command
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    res = subprocess.run(["bash", "-c", command], cwd=elsewhere, env=uwcosim_env(),
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    again = here / "run-reproduced" / "log.parquet"
    assert again.read_bytes() == (here / "run" / "log.parquet").read_bytes()


def test_reproduce_command_of_the_example_needs_no_cd(example_fmus, tmp_path):
    res = _cli("run", str(SCENARIO), "--set", "run.duration=20", "--set",
               'estimators={g={type="current_nav.gated_ekf:GatedEKF"}}', "--out", "r",
               "--no-figures", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert _cli("report", str(tmp_path / "r")).returncode == 0
    command = re.search(r"```sh\n(.*?)\n```", (tmp_path / "r" / "report.md").read_text(),
                        re.S).group(1)
    assert command.startswith("uwcosim run ")
    res = subprocess.run(["bash", "-c", command], cwd=ROOT, env=uwcosim_env(),
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "r-reproduced" / "log.parquet").read_bytes() == \
        (tmp_path / "r" / "log.parquet").read_bytes()


# -- campaigns: local processes and Dask ----------------------------------------------------
CAMPAIGN = """
name = "byo"
seed = 3
runs = 2
[[variants]]
name = "example"
scenario = "{scenario}"
set = ["run.duration=60", 'estimators={{ekf={{type="ekf"}}, gated={{type="{gated}"}}}}']
{model}
"""


def _rows(out: Path) -> list[dict]:
    rows = pq.read_table(out / "runs.parquet").to_pylist()
    drop = {"time_per_step_s", "total_time_s"}
    return sorted(({k: v for k, v in r.items() if k not in drop} for r in rows),
                  key=lambda r: (r["run"], r["estimator"]))


def test_campaign_with_a_user_filter_on_local_processes_and_dask(example_fmus, tmp_path):
    distributed = pytest.importorskip("distributed")
    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.driver import run_campaign

    spec = tmp_path / "c.toml"
    spec.write_text(CAMPAIGN.format(scenario=SCENARIO, gated="current_nav.gated_ekf:GatedEKF",
                                    model=""))
    local = _cli("campaign", str(spec), "--workers", "2", "--out", str(tmp_path / "local"),
                 cwd=tmp_path)
    assert local.returncode == 0, local.stderr
    rows = _rows(tmp_path / "local")
    assert {r["status"] for r in rows} == {"ok"} and len(rows) == 4
    assert {r["estimator"] for r in rows} == {"ekf", "gated"}
    campaign = load_campaign(spec)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        s = run_campaign(campaign, tmp_path / "dask", scheduler=cluster.scheduler_address,
                         figures=False)
    assert s["runs"] == 2 and not s["failed"]
    assert _rows(tmp_path / "dask") == rows


# -- installed: the entry points ------------------------------------------------------------
def test_user_filter_and_model_by_entry_point(example_fmus, tmp_path):
    """The example installed with pip (its dist-info declares the entry points), used from a
    scenario in a folder where the package cannot be found by path: a run, list, campaign."""
    site = install_example(tmp_path / "site")
    env = uwcosim_env(PYTHONPATH=str(site))
    text = SCENARIO.read_text()
    text = text.replace('path = "fmus/', f'path = "{EXAMPLE}/fmus/').replace(
        'path = "../../fmus/', f'path = "{ROOT}/fmus/')
    text = text.replace('type = "current_nav.gated_ekf:GatedEKF"', 'type = "gated_ekf"')
    text = text.replace('type = "current_nav.model:build"', 'type = "current_nav"')
    away = tmp_path / "away"
    away.mkdir()
    scenario = away / "installed.toml"
    scenario.write_text(text)
    listed = _cli("list", "estimators", cwd=away, env=env)
    assert re.search(r"^gated_ekf: EKF whose update .* \[entry point uwcosim\.estimators "
                     r"\(uwcosim-current-nav 0\.1\.0, current_nav\.gated_ekf:GatedEKF\)\]$",
                     listed.stdout, re.M), listed.stdout
    models = _cli("list", "models", cwd=away, env=env)
    assert "current_nav: entry point uwcosim.models (current_nav.model:build)" in models.stdout
    run = _cli("run", str(scenario), "--set", "run.duration=60", "--set",
               'estimators={ekf={type="ekf"}, gated={type="gated_ekf"}}', "--out", "run",
               "--no-figures", cwd=away, env=env)
    assert run.returncode == 0, run.stderr
    meta = _meta(away / "run")
    origin = meta["user_code"]["estimators"]["gated"]
    assert origin["source"] == "entry point" and origin["group"] == "uwcosim.estimators"
    assert origin["package"] == "uwcosim-current-nav" and origin["version"] == "0.1.0"
    assert origin["module_file"].startswith(str(site))
    assert meta["user_code"]["model"]["type"] == "current_nav"
    # without the installed package the names are unknown, in one line
    plain = _cli("check", str(scenario), cwd=away)
    assert plain.returncode == 2 and "unknown estimator 'gated_ekf'" in plain.stderr
    spec = tmp_path / "c.toml"
    spec.write_text(CAMPAIGN.format(scenario=scenario, gated="gated_ekf", model=""))
    camp = _cli("campaign", str(spec), "--workers", "2", "--out", str(tmp_path / "camp"),
                cwd=away, env=env)
    assert camp.returncode == 0, camp.stderr
    rows = _rows(tmp_path / "camp")
    assert {r["status"] for r in rows} == {"ok"} and len(rows) == 4


def test_the_example_package_declares_its_entry_points():
    import tomllib

    data = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())
    eps = data["project"]["entry-points"]
    assert eps["uwcosim.estimators"] == {"gated_ekf": "current_nav.gated_ekf:GatedEKF"}
    assert eps["uwcosim.models"] == {"current_nav": "current_nav.model:build"}
