"""Runs an FMU ends the process of (issue 24, leftovers of items 2 and 4): in ``campaign
--workers 1`` (one failed run, one line, the campaign goes on and reports it) and in ``demo``
(one line, exit 3, as ``run``); the rows up to a crash or a ``kill -9`` are kept with the
default row group size (the log's tail file). Real ``uwcosim`` processes and the Crasher FMU
(``tests/crasher.py``)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import without_progress
from test_fmu_crashes import _crasher

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def child_env(tmp_path):
    """The processes' own temporary folder (what they leave there is checked)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    return {**os.environ, "TMPDIR": str(tmp)}


def _sets(args: list[str]) -> str:
    """``--set`` arguments as a campaign variant's ``set`` list (TOML literal strings)."""
    return ", ".join(f"'{a}'" for a in args[1::2])


def _campaign(tmp_path: Path, crash: list[str], extra: str = "") -> Path:
    light = ['estimators={ekf={type="ekf"}}', "run.duration=10"]
    spec = tmp_path / "c.toml"
    spec.write_text(
        f'seed = 3\nruns = 2\n{extra}'
        f'[[variants]]\nname = "crash"\nscenario = "{ROOT}/scenarios/tan_terrain.toml"\n'
        f"set = [{', '.join(repr(s) for s in light)}, {_sets(crash)}]\n"
        f'[[variants]]\nname = "ok"\nscenario = "{ROOT}/scenarios/tan_terrain.toml"\n'
        f"set = [{', '.join(repr(s) for s in light)}]\n")
    return spec


def _run_campaign(spec: Path, out: Path, env: dict, *args: str, workers: int = 1
                  ) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uwcosim", "campaign", str(spec), "--out",
                           str(out), "--workers", str(workers), *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(("mode", "code", "expected", "workers"), [
    ("exit", 0, "the process exited with status 0", 1),
    ("segfault", 0, "killed by SIGSEGV", 1),
    ("segfault", 0, "killed by SIGSEGV", 2),
], ids=["exit0", "segfault", "segfault-2-workers"])
def test_an_fmu_that_ends_the_process_fails_one_campaign_run(tmp_path, project_fmus, child_env,
                                                            mode, code, expected, workers):
    """``campaign --workers 1`` and ``--workers 2``: each run the FMU ends is one failed
    record and one line naming the FMU call of the process that died; the other runs (after
    it, too) finish; the campaign reports them and exits 1, never 0."""
    spec = _campaign(tmp_path, _crasher(mode, "doStep", 5.0, code))
    out = tmp_path / "camp"
    proc = _run_campaign(spec, out, child_env, workers=workers)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in without_progress(proc.stderr).splitlines() if ln.startswith("failed:")]
    want = f"FMU 'crash' ended the process during doStep at t=5 ({expected}"
    assert len(lines) == 2 and all(want in ln for ln in lines), proc.stderr
    assert sorted(ln[:len("failed: crash run 0: ")] for ln in lines) == [
        "failed: crash run 0: ", "failed: crash run 1: "]
    records = {p.stem: json.loads(p.read_text()) for p in (out / "results").glob("*.json")}
    assert sorted(records) == ["crash__00000", "crash__00001", "ok__00000", "ok__00001"]
    assert [records[k]["status"] for k in sorted(records)] == ["failed", "failed", "ok", "ok"]
    assert "2 of 4 runs failed (crash: 2" in (out / "report.md").read_text()
    kept = out / "failed" / "crash" / "run_00000"  # finished from its journal, as `run` does
    summary = json.loads((kept / "summary.json").read_text())
    assert summary["status"] == "failed" and want in summary["error"]
    assert str(kept) in records["crash__00000"]["error"]
    assert "4 runs in" in proc.stdout
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


def test_the_run_wide_watchdog_fails_one_campaign_run(tmp_path, project_fmus, child_env):
    """``run.fmu_timeout_s`` ends the run's process (a C call cannot be abandoned): in a
    campaign, that run fails with the watchdog's line and the campaign goes on."""
    spec = _campaign(tmp_path, [*_crasher("sleep", "doStep", 5.0), "--set",
                                "run.fmu_timeout_s=1.0"])
    out = tmp_path / "camp"
    proc = _run_campaign(spec, out, child_env)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    lines = [ln for ln in without_progress(proc.stderr).splitlines() if ln.startswith("failed:")]
    assert len(lines) == 2 and all(
        "FMU 'crash' did not return from doStep within 1 s at t=5 (run.fmu_timeout_s)" in ln
        and ln.count("kept in") == 1 for ln in lines), proc.stderr
    assert "uwcosim: error" not in proc.stderr  # the child's own line: the parent says it
    # the run finished its directory itself before the watchdog ended it: kept as it wrote it
    sims = [json.loads(p.read_text()) for p in (out / "failed").glob("crash/*/simulation.json")]
    assert len(sims) == 2 and all(s["estimators"]["ekf"]["total_time_s"] > 0 for s in sims)
    records = [json.loads(p.read_text()) for p in (out / "results").glob("ok__*.json")]
    assert [r["status"] for r in records] == ["ok", "ok"]
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


def test_an_fmu_that_ends_the_process_fails_the_demo(tmp_path, project_fmus, child_env):
    """``demo`` is supervised as ``run`` is: one line, exit 3, summary failed."""
    cache = tmp_path / "cache"
    (cache / "uwcosim" / "fmus").mkdir(parents=True)
    for name in ("AUVKinematics", "DVL", "DepthSounder"):  # the demo's FMUs: not rebuilt
        shutil.copy(project_fmus / f"{name}.fmu", cache / "uwcosim" / "fmus")
    out = tmp_path / "demo"
    proc = subprocess.run(
        [sys.executable, "-m", "uwcosim", "demo", "--out", str(out), "--set",
         'estimators={ekf={type="ekf"}}', "--set", "run.duration=10", "--set",
         "log.chunk_steps=2", *_crasher("exit", "doStep", 5.0)], cwd=tmp_path,
        env={**child_env, "XDG_CACHE_HOME": str(cache)}, capture_output=True, text=True,
        timeout=300)
    assert proc.returncode == 3, (proc.returncode, proc.stderr)
    err = without_progress(proc.stderr).strip()
    assert "Traceback" not in err and err.count("\n") == 0, err
    assert "FMU 'crash' ended the process during doStep at t=5 (the process exited with " \
           "status 0" in err
    assert json.loads((out / "summary.json").read_text())["status"] == "failed"
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


def _default_chunk_run(out: Path, env: dict, *crash: str) -> list[str]:
    """``uwcosim run`` with the default ``[log] chunk_steps`` (1000) and filter block (64)."""
    return [sys.executable, "-m", "uwcosim", "run", str(ROOT / "scenarios" / "tan_terrain.toml"),
            "--out", str(out), "--no-figures", "--set", 'estimators={ekf={type="ekf"}}',
            "--set", "run.duration=50", *crash]


def test_a_crash_keeps_the_rows_up_to_it_with_the_default_chunk(tmp_path, project_fmus,
                                                                 child_env):
    """Item 4: a segfault at t=5 of a default run (no row group written, the rows waiting for
    their filter block) keeps rows 0..5: the truth as logged, the estimates NaN where the
    filter had not got to them."""
    out = tmp_path / "run"
    proc = subprocess.run(_default_chunk_run(out, child_env, *_crasher("segfault", "doStep")),
                          cwd=ROOT, env=child_env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 3, proc.stderr
    assert "during doStep at t=5 (killed by SIGSEGV" in proc.stderr
    assert f"(log up to t=5 kept in {out / 'log.parquet'})" in proc.stderr
    from uwcosim.runlog import read_log

    cols, _ = read_log(out / "log.parquet")
    assert cols["time"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert np.all(np.isfinite(cols["vehicle.x"]))
    est = cols["est.ekf.x"]  # the initial estimate (row 0); then the block not filtered yet
    assert np.isfinite(est[0]) and np.all(np.isnan(est[1:])), est
    assert not (out / "log.parquet.journal").exists() and not (out / "log.parquet.tail").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 5


def test_a_killed_run_keeps_the_rows_up_to_the_kill(tmp_path, project_fmus, child_env):
    """``kill -9`` of ``uwcosim run`` while an FMU hangs at t=5 (its child dies with it): the
    log reads (``read_log``, ``export``) with rows 0..5 although no row group was written."""
    out = tmp_path / "run"
    proc = subprocess.Popen(_default_chunk_run(out, child_env, *_crasher("sleep", "doStep")),
                            cwd=ROOT, env=child_env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    from uwcosim.runlog import read_log
    from uwcosim.runlog.tail import tail_path, tail_table

    tail = tail_path(out / "log.parquet")
    try:
        while True:  # row 5 is in the tail: the FMU sleeps in the doStep from t=5
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no tail file with rows 0..5"
            try:
                rows = tail_table(tail, 0)[1]
            except (OSError, ValueError):
                rows = None
            if rows is not None and rows.num_rows == 6:
                break
            time.sleep(0.05)
    finally:
        proc.kill()
        proc.communicate(timeout=30)
    time.sleep(0.5)  # the run's child dies with it
    assert not (out / "log.parquet.journal").stat().st_size > 1000  # no row group in it
    assert read_log(out / "log.parquet")[0]["time"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    r = subprocess.run([sys.executable, "-m", "uwcosim", "export", str(out), "--csv"],
                       cwd=ROOT, env=child_env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert len((out / "log.csv").read_text().splitlines()) == 7
