"""Real signals to real ``uwcosim`` processes (issue 10): SIGINT, SIGTERM and SIGHUP stop a run
with its log and summary kept; kill -9 keeps every finished row group; a hanging FMU does not
block a stop; the run-wide watchdog; campaigns; and no child process survives its parent."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from uwcosim.runlog import read_log

try:
    from conftest import without_progress
except ImportError:  # tests/ imported as a package
    from tests.conftest import without_progress

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"
# a light run: FMUs and one EKF, small row groups so that several are written early
SETS = ["--set", 'estimators={ekf={type="ekf"}}', "--set", "run.duration=12000",
        "--set", "log.chunk_steps=50"]
FAULT = ["--set", 'connections=[["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"], '
         '["vehicle.x", "fault.u"], ["fault.y", "sounder.x"], ["vehicle.y", "sounder.y"]]',
         "--set", "run.duration=50", "--set", "log.chunk_steps=2",
         "--set", 'estimators={ekf={type="ekf"}}']


def _hang(**extra) -> list[str]:
    inner = "".join(f", {k}={v}" for k, v in extra.items())
    return [*FAULT, "--set", f'fmus.fault={{path="{ROOT / "fmus" / "FaultInjector.fmu"}", '
                             f'parameters={{hang_time=3.0, hang_seconds=3600.0}}{inner}}}']


def _default_sigint() -> None:  # a shell may start the tests with SIGINT ignored
    signal.signal(signal.SIGINT, signal.SIG_DFL)


_CHILD_ENV: dict[str, str] = {}


@pytest.fixture(autouse=True, scope="module")
def _child_tmpdir(tmp_path_factory):
    """The children's temporary folders (unzipped FMUs, worker files) go to a pytest folder: a
    child killed with SIGKILL cannot remove its own, and /tmp would keep them."""
    _CHILD_ENV.update(os.environ, TMPDIR=str(tmp_path_factory.mktemp("child-tmp")))
    yield
    _CHILD_ENV.clear()


def _spawn(*args: str, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "uwcosim", *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint, env=env or _CHILD_ENV or None)


def _children(pid: int) -> dict[int, int]:
    """``{child pid: parent pid}`` of every process in /proc."""
    out = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                stat = Path(f"/proc/{d}/stat").read_text()
            except OSError:
                continue
            out[int(d)] = int(stat.rsplit(")", 1)[1].split()[1])
    return out


def descendants(pid: int) -> set[int]:
    parents = _children(pid)
    found, todo = set(), [pid]
    while todo:
        p = todo.pop()
        for c, pp in parents.items():
            if pp == p and c not in found:
                found.add(c)
                todo.append(c)
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def assert_all_gone(pids: set[int], within: float = 5.0) -> None:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.05)
    assert not [p for p in pids if _alive(p)], "child processes survived their parent"


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    """Until ``path`` exists and is not empty (the run is under way)."""
    deadline = time.monotonic() + timeout
    while not (path.exists() and path.stat().st_size > 0):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)


@pytest.fixture(scope="module")
def reference(tmp_path_factory, project_fmus):
    """The uninterrupted run of the same scenario (columns of its log)."""
    from uwcosim.api import run_scenario
    from uwcosim.scenario import load_scenario

    out = tmp_path_factory.mktemp("ref")
    loaded = load_scenario(SCEN, [SETS[i] for i in range(1, len(SETS), 2)])
    run_scenario(loaded, out, figures=False)
    return pq.read_table(out / "log.parquet")


def _same_as_reference(log: Path, reference, whole: int | None = None) -> int:
    """The log's rows are the reference's; with ``whole``, only its first ``whole`` rows are
    complete (a killed run: the rows after them come from the tail file, their estimates NaN
    where the filter had not reached them, every other value the reference's)."""
    cols, _ = read_log(log)
    n = cols["time"].size
    assert 1 < n < reference.num_rows
    ref = reference.slice(0, n)
    whole = n if whole is None else whole
    for name in reference.column_names:
        got, want = cols[name], ref.column(name).to_numpy()
        np.testing.assert_array_equal(got[:whole], want[:whole], err_msg=name)
        tail = got[whole:]
        if name.startswith("est."):  # not filtered yet, or the reference's value
            tail = np.where(np.isnan(tail), want[whole:], tail)
        np.testing.assert_array_equal(tail, want[whole:], err_msg=name)
    return n


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143),
                                           (signal.SIGHUP, 129)],
                         ids=["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_stops_the_run_and_keeps_log_and_summary(tmp_path, reference, sig, code):
    proc = _spawn("run", str(SCEN), "--out", str(tmp_path), "--no-figures", *SETS)
    _wait_for(tmp_path / "log.parquet.journal", proc)
    kids = descendants(proc.pid)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err and without_progress(err).strip().count("\n") == 0
    assert f"by {signal.Signals(sig).name}" in err
    n = _same_as_reference(tmp_path / "log.parquet", reference)
    # the message names the last logged row, not the step in progress
    last = reference.column("time")[n - 1].as_py()
    assert f"interrupted at t={last:g} " in err
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "interrupted" and f"t={last:g}" in summary["error"]
    assert not (tmp_path / "log.parquet.journal").exists()  # closed properly
    assert_all_gone(kids)


def test_kill_9_keeps_every_finished_row_group(tmp_path, reference):
    proc = _spawn("run", str(SCEN), "--out", str(tmp_path), "--no-figures", *SETS)
    journal = tmp_path / "log.parquet.journal"
    _wait_for(journal, proc)
    time.sleep(0.3)
    proc.kill()
    proc.communicate(timeout=30)
    with pytest.raises(Exception):  # noqa: B017 - the Parquet footer was never written
        pq.read_table(tmp_path / "log.parquet")
    from uwcosim.runlog.parquet import read_journal

    n = read_journal(journal).num_rows  # every finished row group, as the reference
    assert n % 50 == 0 and 1 < n
    _same_as_reference(tmp_path / "log.parquet", reference, whole=n)  # journal, then tail
    total = read_log(tmp_path / "log.parquet")[0]["time"].size
    assert total >= n  # and the rows after them, from the tail file (issue 24, item 4)
    from uwcosim.runlog import recover_log

    assert recover_log(tmp_path / "log.parquet") == total
    assert pq.read_table(tmp_path / "log.parquet").num_rows == total and not journal.exists()


def test_double_ctrl_c_still_writes_the_summary(tmp_path, reference):
    proc = _spawn("run", str(SCEN), "--out", str(tmp_path), "--no-figures", *SETS)
    _wait_for(tmp_path / "log.parquet.journal", proc)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err, err
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "interrupted"
    _same_as_reference(tmp_path / "log.parquet", reference)


@pytest.mark.parametrize(("extra", "sig", "code"), [
    ({}, signal.SIGTERM, 143),                 # FMU in this process: the watcher ends it
    ({}, signal.SIGINT, 130),
    ({"timeout_s": 30.0}, signal.SIGINT, 130),  # FMU in a worker: not the 30 s of timeout_s
    ({"timeout_s": 30.0}, signal.SIGHUP, 129),
], ids=["in-process-SIGTERM", "in-process-SIGINT", "worker-SIGINT", "worker-SIGHUP"])
def test_a_hanging_fmu_does_not_block_a_stop(tmp_path, project_fmus, extra, sig, code):
    proc = _spawn("run", str(SCEN), "--out", str(tmp_path), "--no-figures", *_hang(**extra))
    _wait_for(tmp_path / "log.parquet.journal", proc)
    time.sleep(1.0)  # t=3: inside the FMU's doStep, for an hour
    kids = descendants(proc.pid)
    if extra:
        assert kids  # the FMU's worker process
    t0 = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    took = time.monotonic() - t0
    assert proc.returncode == code, err
    assert took < 2.0, f"took {took:.2f} s"
    assert "Traceback" not in err and without_progress(err).strip().count("\n") == 0
    assert "interrupted at t=3 " in err and "log up to t=3 kept" in err
    cols, _ = read_log(tmp_path / "log.parquet")
    assert cols["time"].tolist() == [0.0, 1.0, 2.0, 3.0]
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "interrupted"
    assert_all_gone(kids)


def test_the_run_wide_watchdog_ends_a_hanging_fmu(tmp_path, project_fmus):
    t0 = time.monotonic()
    tmp = tmp_path.parent / f"{tmp_path.name}-tmp"  # this run's own temporary folder
    tmp.mkdir()
    proc = _spawn("run", str(SCEN), "--out", str(tmp_path), "--no-figures", *_hang(),
                  "--set", "run.fmu_timeout_s=1.0", env={**_CHILD_ENV, "TMPDIR": str(tmp)})
    _, err = proc.communicate(timeout=120)
    assert time.monotonic() - t0 < 60
    assert proc.returncode == 3, err
    assert "FMU 'fault' did not return from doStep within 1 s at t=3 (run.fmu_timeout_s)" in err
    assert "Traceback" not in err and without_progress(err).strip().count("\n") == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "failed" and "run.fmu_timeout_s" in summary["error"]
    assert read_log(tmp_path / "log.parquet")[0]["time"].tolist() == [0.0, 1.0, 2.0, 3.0]
    # the watchdog ends the process with os._exit: the unzipped FMUs are removed before
    assert list(tmp.iterdir()) == []


CAMPAIGN = """
seed = 3
runs = 40
[[variants]]
name = "v"
scenario = "{root}/scenarios/tan_terrain.toml"
set = ['estimators={{ekf={{type="ekf"}}}}', "run.duration=2000"]
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_campaign_workers_die_with_the_campaign(tmp_path, project_fmus, sig):
    spec = tmp_path / "c.toml"
    spec.write_text(CAMPAIGN.format(root=ROOT))
    out = tmp_path / "o"
    proc = _spawn("campaign", str(spec), "--out", str(out), "--workers", "2")
    deadline = time.monotonic() + 120
    while len(descendants(proc.pid)) < 2:  # the two workers
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(0.5)
    kids = descendants(proc.pid)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert_all_gone(kids)
    if sig == signal.SIGTERM:
        assert proc.returncode == 143, err
        assert "Traceback" not in err and "campaign interrupted by SIGTERM" in err
        assert "partial" in (out / "report.md").read_text().lower()


def test_fmu_worker_dies_when_the_run_is_killed(tmp_path, project_fmus):
    proc = _spawn("run", str(SCEN), "--out", str(tmp_path), "--no-figures",
                  *_hang(timeout_s=30.0))
    _wait_for(tmp_path / "log.parquet.journal", proc)
    time.sleep(0.5)
    kids = descendants(proc.pid)
    assert kids
    proc.kill()
    proc.communicate(timeout=30)
    assert_all_gone(kids)
