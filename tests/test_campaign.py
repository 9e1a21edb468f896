"""Campaigns: deterministic over worker counts, resumable, failures recorded, Dask cluster."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from uwcosim.campaign import load_campaign
from uwcosim.campaign.driver import run_campaign
from uwcosim.campaign.spec import run_seed
from uwcosim.core.errors import ScenarioError

ROOT = Path(__file__).resolve().parents[1]

SPEC = """
name = "t"
seed = 11
runs = 3
[[variants]]
name = "without_terrain"
scenario = "{root}/scenarios/tan_dead_reckoning.toml"
set = ["run.duration=40"]
[[variants]]
name = "with_terrain"
scenario = "{root}/scenarios/tan_terrain.toml"
set = ["run.duration=40"]
"""


@pytest.fixture
def spec(tmp_path, project_fmus):
    p = tmp_path / "c.toml"
    p.write_text(SPEC.format(root=ROOT))
    return load_campaign(p)


def _table(out: Path) -> list[dict]:
    rows = pq.read_table(out / "runs.parquet").to_pylist()
    drop = {"time_per_step_s", "total_time_s"}
    return sorted(({k: v for k, v in r.items() if k not in drop} for r in rows),
                  key=lambda r: (r["variant"], r["run"], r["estimator"]))


def test_results_do_not_depend_on_worker_count(spec, tmp_path):
    s1 = run_campaign(spec, tmp_path / "a", workers=1, figures=False)
    s2 = run_campaign(spec, tmp_path / "b", workers=2, figures=True)
    assert s1["runs"] == s2["runs"] == 6
    assert _table(tmp_path / "a") == _table(tmp_path / "b")
    rows = _table(tmp_path / "a")
    assert {r["seed"] for r in rows} == {run_seed(11, i) for i in range(3)}
    # the variants of a run share their truth: dead reckoning is identical in both
    dr = {(r["variant"], r["run"]): r["rmse_position_m"] for r in rows
          if r["estimator"] == "dead_reckoning"}
    assert all(dr[("with_terrain", i)] == dr[("without_terrain", i)] for i in range(3))
    for f in ("table.md", "table.csv", "rmse_summary.png", "report.md",
              "rmse_per_run_with_terrain.png"):
        assert (tmp_path / "b" / f).is_file()
    assert "| with_terrain | ekf | 3 |" in (tmp_path / "b" / "table.md").read_text()


def test_the_spawned_pool_gives_the_supervised_workers_results(spec, tmp_path, monkeypatch):
    """``UWCOSIM_SUPERVISE=0`` (or a platform that cannot fork): ``--workers 2`` is a pool of
    spawned processes, with the same results as the supervised children."""
    run_campaign(spec, tmp_path / "a", workers=2, figures=False)
    monkeypatch.setenv("UWCOSIM_SUPERVISE", "0")
    run_campaign(spec, tmp_path / "b", workers=2, figures=False)
    assert _table(tmp_path / "a") == _table(tmp_path / "b")


def test_resume_skips_finished_runs_and_refuses_to_overwrite(spec, tmp_path):
    out = tmp_path / "c"
    run_campaign(spec, out, runs=1, workers=1, figures=False)
    first = {p.name: p.stat().st_mtime_ns for p in (out / "results").glob("*.json")}
    assert len(first) == 2
    with pytest.raises(ScenarioError, match="already has 2 finished runs"):
        run_campaign(spec, out, runs=2, workers=1, figures=False)
    s = run_campaign(spec, out, runs=2, workers=1, resume=True, figures=False)
    assert s["runs"] == 4
    after = {p.name: p.stat().st_mtime_ns for p in (out / "results").glob("*.json")}
    assert all(after[k] == v for k, v in first.items())


def test_a_failed_run_is_recorded_and_the_campaign_goes_on(tmp_path, project_fmus):
    p = tmp_path / "c.toml"
    p.write_text(SPEC.format(root=ROOT) + f"""
[[variants]]
name = "off_map"
scenario = "{ROOT}/scenarios/tan_terrain.toml"
set = ["run.duration=40", "fmus.vehicle.start.x=24990.0"]
""")
    s = run_campaign(load_campaign(p), tmp_path / "o", runs=1, workers=1, figures=False)
    assert s["runs"] == 3
    assert [f["variant"] for f in s["failed"]] == ["off_map"]
    rec = json.loads((tmp_path / "o/results/off_map__00000.json").read_text())
    assert rec["status"] == "failed" and "outside the map" in rec["error"]
    assert (tmp_path / "o/results/with_terrain__00000.json").is_file()


def test_bad_campaign_specs(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('runs = 2\n[[variants]]\nname = "a"\nscenario = "nope.toml"\n')
    with pytest.raises(ScenarioError, match=r"variants\[0\].scenario': file not found"):
        load_campaign(p)
    p.write_text('runz = 2\n[[variants]]\nname = "a"\nscenario = "x.toml"\n')
    with pytest.raises(ScenarioError, match="key 'runz': unknown key"):
        load_campaign(p)


def test_dask_local_cluster(spec, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        s = run_campaign(spec, tmp_path / "d", runs=2, scheduler=cluster.scheduler_address,
                         figures=False)
    assert s["runs"] == 4 and not s["failed"]
    run_campaign(spec, tmp_path / "l", runs=2, workers=1, figures=False)
    assert _table(tmp_path / "d") == _table(tmp_path / "l")


def _record(results: Path, variant: str, run: int, status: str = "ok", rmse: float = 1.0,
            diverged: bool = False) -> None:
    est = {} if status != "ok" else {"ekf": {"rmse_position_m": rmse, "diverged": diverged,
                                             "anees": 1.0}}
    results.mkdir(parents=True, exist_ok=True)
    (results / f"{variant}__{run:05d}.json").write_text(json.dumps(
        {"variant": variant, "run": run, "seed": run, "status": status,
         "error": "boom" if status != "ok" else "", "estimators": est, "wall_s": 0.1}))


def test_failed_and_nan_runs_are_counted_per_variant(tmp_path):
    """Issue 24, item 4: variant ``a`` whose three runs failed vanished from table.md and
    report.md, and a NaN RMSE was averaged away while the table said "runs 3"."""
    from uwcosim.campaign.driver import collect

    res = tmp_path / "results"
    for i in range(3):
        _record(res, "a", i, status="failed")
        _record(res, "b", i, rmse=float("nan") if i == 1 else 2.0 * (i + 1))
    s = collect(tmp_path, figures=False)
    table = (tmp_path / "table.md").read_text()
    assert "| a | - | 0 | 3 | 0 | nan" in table, table
    assert "| b | ekf | 2 | 0 | 1 | 4.00 ± 2.83" in table, table  # mean of 2 and 6
    report = (tmp_path / "report.md").read_text()
    assert "3 of 6 runs failed (a: 3;" in report and "NaN position RMSE (b/ekf: 1)" in report
    assert "over 6 runs, 3 of them failed" in table
    assert [f["variant"] for f in s["failed"]] == ["a"] * 3
    assert s["nan"] == [{"variant": "b", "run": 1, "estimator": "ekf"}]
    row = {r["variant"]: r for r in s["table"]}
    assert row["a"]["failed"] == 3 and row["b"]["nan"] == 1 and row["b"]["runs"] == 2


def test_every_run_failed_is_a_table_of_failures_and_a_non_zero_exit(tmp_path, project_fmus):
    """Issue 24, item 4, through the command line: a campaign whose every run fails says so
    in table.md and report.md, and exits 1."""
    import subprocess
    import sys

    p = tmp_path / "c.toml"
    p.write_text(f"""seed = 1
runs = 2
[[variants]]
name = "off_map"
scenario = "{ROOT}/scenarios/tan_terrain.toml"
set = ["run.duration=5", "fmus.vehicle.start.x=26000.0", 'estimators={{ekf={{type="ekf"}}}}']
""")
    r = subprocess.run([sys.executable, "-m", "uwcosim", "campaign", str(p), "--out",
                        str(tmp_path / "o"), "--workers", "1"], capture_output=True, text=True,
                       cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "| off_map | - | 0 | 2 | 0 |" in (tmp_path / "o" / "table.md").read_text()
    assert "2 of 2 runs failed (off_map: 2" in (tmp_path / "o" / "report.md").read_text()
    assert "Traceback" not in r.stderr
