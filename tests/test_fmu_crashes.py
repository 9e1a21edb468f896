"""FMU faults that end or stall a process, with real ``uwcosim`` processes (issue 24, items
1, 2, 9, 14, 15): an in-process FMU that exits, aborts or segfaults (in doStep, a getter, at
initialization, at library load) ends the run as ``failed`` with one line and exit status 3,
never 0; duplicate value references are refused at load and by ``check``; ``run.fmu_timeout_s``
times a getter; the interrupt message names the log's last row; a killed run exports.

The Crasher FMU is ``tests/crasher.py`` (C hooks in ``tests/data/crasher/crash.c``).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
from conftest import without_progress
from crasher import MODES, WHERE

from uwcosim.runlog import read_log

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"
CHAIN = 'connections=[["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"], ' \
        '["vehicle.x", "crash.u"], ["crash.y", "sounder.x"], ["vehicle.y", "sounder.y"]]'
LIGHT = ["--set", 'estimators={ekf={type="ekf"}}', "--set", "run.duration=10",
         "--set", "log.chunk_steps=2"]


def _crasher(mode: str, where: str, t: float = 5.0, code: int = 0, fmi2: bool = False,
             extra: str = "") -> list[str]:
    fmu = "Crasher_fmi2.fmu" if fmi2 else "Crasher.fmu"
    return ["--set", CHAIN, "--set",
            f'fmus.crash={{path="{ROOT / "fmus" / fmu}", parameters={{mode={MODES.get(mode, 0)}, '
            f'where={WHERE.get(where, 0)}, exit_code={code}, crash_time={t}}}{extra}}}']


@pytest.fixture
def child_env(tmp_path):
    """The child's own temporary folder (what it leaves there is checked)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    return {**os.environ, "TMPDIR": str(tmp)}


def _run(out: Path, *args: str, env: dict, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out", str(out),
                           "--no-figures", *LIGHT, *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _failed_with_one_line(proc, out: Path, expected: str) -> dict:
    err = proc.stderr
    assert proc.returncode == 3, (proc.returncode, err)
    assert "Traceback" not in err and without_progress(err).strip().count("\n") == 0, err
    assert expected in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and expected in summary["error"]
    assert not (out / "log.parquet.journal").exists()  # the log was finished
    return summary


@pytest.mark.parametrize(("mode", "where", "t", "code", "fmi2", "expected"), [
    ("exit", "doStep", 5.0, 0, False, "during doStep at t=5 (the process exited with status 0"),
    ("exit", "doStep", 5.0, 7, True, "during doStep at t=5 (the process exited with status 7"),
    ("segfault", "doStep", 5.0, 0, False, "during doStep at t=5 (killed by SIGSEGV"),
    ("abort", "init", 0.0, 0, False, "during get outputs at t=0 (killed by SIGABRT"),
    ("exit", "get", 5.0, 0, False, "during get outputs at t=5 (the process exited with status 0"),
], ids=["exit0-doStep", "exit7-doStep-fmi2", "segfault-doStep", "abort-init", "exit0-getter"])
def test_an_fmu_that_ends_the_process_fails_the_run(tmp_path, project_fmus, child_env, mode,
                                                    where, t, code, fmi2, expected):
    out = tmp_path / "run"
    proc = _run(out, *_crasher(mode, where, t, code, fmi2), env=child_env)
    _failed_with_one_line(proc, out, f"FMU 'crash' ended the process {expected}")
    if where == "init":  # before the first row group: no log, no unreadable stub of one
        assert not (out / "log.parquet").exists() and "(no log row was written)" in proc.stderr
    else:  # every row up to the crash (item 4: the tail's rows after the row groups)
        times = read_log(out / "log.parquet")[0]["time"].tolist()
        last = 4.0 if where == "get" else 5.0  # a getter at t=5 never gave row 5's outputs
        assert times == [float(k) for k in range(int(last) + 1)], times
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


@pytest.mark.parametrize(("at_load", "expected"), [
    ("exit:0", "the process exited with status 0"), ("segfault", "killed by SIGSEGV")])
def test_an_fmu_that_ends_the_process_at_library_load(tmp_path, project_fmus, child_env,
                                                      at_load, expected):
    out = tmp_path / "run"
    proc = _run(out, *_crasher("none", "none"), "--set", "run.fmu_timeout_s=30",
                env={**child_env, "UWC_CRASHER_AT_LOAD": at_load})
    _failed_with_one_line(proc, out, f"FMU 'crash' ended the process during instantiate at "
                                     f"t=0 ({expected}")


def test_a_hang_in_an_output_getter_is_timed(tmp_path, project_fmus, child_env):
    out = tmp_path / "run"
    t0 = time.monotonic()
    proc = _run(out, *_crasher("sleep", "get"), "--set", "run.fmu_timeout_s=1.0",
                env=child_env)
    assert time.monotonic() - t0 < 60
    _failed_with_one_line(proc, out, "FMU 'crash' did not return from get outputs within 1 s "
                                     "at t=5 (run.fmu_timeout_s)")
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []  # item 18: no uwcosim_fmu_* left


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not (path.exists() and path.stat().st_size > 0):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)


def _default_sigint() -> None:  # a shell may start the tests with SIGINT ignored
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _spawn(out: Path, *args: str, env: dict) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out",
                             str(out), "--no-figures", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_the_interrupt_message_names_the_logs_last_row(tmp_path, project_fmus, child_env, sig):
    """Rows still waiting for their filter block are written first, and named (item 14); no
    unzipped FMU is left (item 18)."""
    out = tmp_path / "run"
    proc = _spawn(out, "--set", 'estimators={ekf={type="ekf"}}', "--set", "run.duration=50",
                  *_crasher("sleep", "doStep"), "--set", "run.fmu_timeout_s=600", env=child_env)
    while not (out / "log.parquet").exists():  # opened: the run starts (no row group yet)
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    time.sleep(3.0)  # t=5: inside the FMU's doStep, for an hour; rows 0..5 not written yet
    assert not (out / "log.parquet.journal").stat().st_size
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    assert "interrupted at t=5 " in err and "log up to t=5 kept" in err, err
    assert read_log(out / "log.parquet")[0]["time"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


def test_a_killed_run_can_be_exported(tmp_path, project_fmus, child_env):
    out = tmp_path / "run"
    proc = _spawn(out, "--set", 'estimators={ekf={type="ekf"}}', "--set", "run.duration=50",
                  "--set", "log.chunk_steps=2", *_crasher("sleep", "doStep"), env=child_env)
    _wait_for(out / "log.parquet.journal", proc)
    time.sleep(2.0)
    proc.kill()
    proc.communicate(timeout=30)
    time.sleep(0.5)  # the run's child dies with it
    rows = read_log(out / "log.parquet")[0]["time"].size
    assert rows >= 2
    r = subprocess.run([sys.executable, "-m", "uwcosim", "export", str(out), "--csv"],
                       cwd=ROOT, env=child_env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    lines = (out / "log.csv").read_text().splitlines()
    assert lines[0].startswith('"time [s]"') and len(lines) == rows + 1


def _vx_reference(fmu: Path) -> str:
    """The value reference of the DVL FMU's input ``vx`` (the one ``_shared_vr`` gives ``vy``)."""
    with zipfile.ZipFile(fmu) as z:
        text = z.read("modelDescription.xml").decode()
    return re.search(r'name="vx" valueReference="(\d+)"', text).group(1)


def _shared_vr(src: Path, dst: Path) -> Path:
    """The DVL FMU with ``vy`` on the value reference of ``vx`` (an invalid FMI 3 FMU)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                vx = re.search(r'name="vx" valueReference="(\d+)"', text).group(1)
                vy = re.search(r'name="vy" valueReference="(\d+)"', text).group(1)
                text = text.replace(f'name="vy" valueReference="{vy}"',
                                    f'name="vy" valueReference="{vx}"')
                def deps(m, vx=vx, vy=vy) -> str:
                    return 'dependencies="' + " ".join(
                        vx if d == vy else d for d in m.group(1).split()) + '"'

                text = re.sub(r'dependencies="([\d ]*)"', deps, text)
                data = text.encode()
                assert f'name="vy" valueReference="{vx}"'.encode() in data
            zout.writestr(item.filename, data)
    return dst


def test_duplicate_value_references_are_refused_by_run_and_check(tmp_path, project_fmus,
                                                                   child_env):
    bad = _shared_vr(project_fmus / "DVL.fmu", tmp_path / "SharedVR.fmu")
    args = ["--set", f'fmus.dvl.path="{bad}"']
    shared = f"inputs 'vx' and 'vy' share value reference {_vx_reference(bad)}"
    proc = _run(tmp_path / "run", *args, env=child_env)
    assert proc.returncode == 3, proc.stderr
    assert shared in proc.stderr
    assert "Traceback" not in proc.stderr
    assert without_progress(proc.stderr).strip().count("\n") == 0
    check = subprocess.run([sys.executable, "-m", "uwcosim", "check", str(SCEN), *LIGHT, *args],
                           cwd=ROOT, env=child_env, capture_output=True, text=True, timeout=120)
    assert check.returncode == 3, check.stdout + check.stderr
    assert shared in check.stdout + check.stderr


def _with_member(src: Path, dst: Path, name: str, size: int) -> Path:
    """``src`` plus a member ``name`` of ``size`` zero bytes (deflated: a few kB per MiB)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED,
                                                     compresslevel=1) as zout:
        for item in zin.infolist():
            zout.writestr(item.filename, zin.read(item))
        with zout.open(name, "w") as fh:
            block = bytes(1 << 20)
            for _ in range(size >> 20):
                fh.write(block)
    return dst


def test_a_zip_bomb_is_refused_before_it_is_unpacked(tmp_path, project_fmus, child_env):
    """Over the default limit (512 MiB): ``fmu validate`` and ``run`` refuse it in one line,
    nothing is extracted (item 7)."""
    from uwcosim.fmi.archive import MAX_UNPACKED_MB, archive_problems

    bomb = _with_member(project_fmus / "DVL.fmu", tmp_path / "Bomb.fmu", "resources/big.bin",
                        (MAX_UNPACKED_MB + 1) << 20)
    assert bomb.stat().st_size < 4 << 20
    assert "more than the limit of 512 MiB" in archive_problems(bomb)[0]
    v = subprocess.run([sys.executable, "-m", "uwcosim", "fmu", "validate", str(bomb)],
                       cwd=ROOT, env=child_env, capture_output=True, text=True, timeout=60)
    assert v.returncode == 1 and "more than the limit of 512 MiB" in v.stdout + v.stderr
    proc = _run(tmp_path / "run", "--set", f'fmus.dvl.path="{bomb}"', env=child_env)
    assert proc.returncode == 3, proc.stderr
    assert "FMU archive unpacks to 513 MiB, more than the limit of 512 MiB " \
           "(UWCOSIM_FMU_MAX_UNPACKED_MB)" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert without_progress(proc.stderr).strip().count("\n") == 0
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


def test_the_unpacked_size_limit_is_configurable_and_only_what_is_needed_is_unpacked(
        tmp_path, project_fmus, monkeypatch):
    from uwcosim.core.errors import ScenarioError
    from uwcosim.fmi.archive import archive_problems, unzip

    fmu = _with_member(project_fmus / "DVL.fmu", tmp_path / "Docs.fmu",
                       "documentation/manual.bin", 3 << 20)
    assert archive_problems(fmu) == []
    monkeypatch.setenv("UWCOSIM_FMU_MAX_UNPACKED_MB", "2")
    assert "more than the limit of 2 MiB" in archive_problems(fmu)[0]
    monkeypatch.setenv("UWCOSIM_FMU_MAX_UNPACKED_MB", "lots")
    with pytest.raises(ScenarioError, match="UWCOSIM_FMU_MAX_UNPACKED_MB='lots': expected a "
                                            "positive number of MiB"):
        archive_problems(fmu)
    monkeypatch.delenv("UWCOSIM_FMU_MAX_UNPACKED_MB")
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
    assert any(n.startswith("binaries/") for n in names)
    out = unzip(fmu, tmp_path / "unzipped")
    got = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert "modelDescription.xml" in got and "documentation/manual.bin" not in got
    assert all(n == "modelDescription.xml" or n.startswith(("binaries/", "resources/"))
               for n in got)
    assert {n for n in names if n.startswith("binaries/x86_64-linux/")} <= got


def _one_line(proc, code: int, expected: str) -> None:
    assert proc.returncode == code, (proc.returncode, proc.stderr)
    assert expected in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert without_progress(proc.stderr).strip().count("\n") == 0, proc.stderr


def test_the_unpacked_size_limit_is_a_scenario_key(tmp_path, project_fmus, child_env):
    """``run.fmu_max_unpacked_mb`` sets the limit for the scenario's FMUs (over the environment
    variable), in this process and in an FMU's worker process (``timeout_s``); ``check`` applies
    it as ``run`` does; a bad value is a scenario error naming the key."""
    fmu = _with_member(project_fmus / "DVL.fmu", tmp_path / "Docs.fmu",
                       "documentation/manual.bin", 3 << 20)
    dvl = ["--set", f'fmus.dvl.path="{fmu}"']
    proc = _run(tmp_path / "a", *dvl, "--set", "run.fmu_max_unpacked_mb=2", env=child_env)
    _one_line(proc, 3, f"{fmu}: FMU archive unpacks to 3 MiB, more than the limit of 2 MiB "
                       f"(run.fmu_max_unpacked_mb)")
    check = subprocess.run([sys.executable, "-m", "uwcosim", "check", str(SCEN), *dvl, "--set",
                            "run.fmu_max_unpacked_mb=2"], cwd=ROOT, env=child_env,
                           capture_output=True, text=True, timeout=120)
    assert check.returncode == 3 and "more than the limit of 2 MiB (run.fmu_max_unpacked_mb)" \
        in check.stderr, (check.returncode, check.stderr)
    small = {**child_env, "UWCOSIM_FMU_MAX_UNPACKED_MB": "2"}
    proc = _run(tmp_path / "b", *dvl, "--set", "run.fmu_max_unpacked_mb=8", env=small)
    assert proc.returncode == 0, proc.stderr
    proc = _run(tmp_path / "c", "--set", f'fmus.dvl={{path="{fmu}", timeout_s=30}}', "--set",
                "run.fmu_max_unpacked_mb=8", env=small)
    assert proc.returncode == 0, proc.stderr  # the worker process has the scenario's limit
    proc = _run(tmp_path / "d", *dvl, env=small)
    _one_line(proc, 3, "more than the limit of 2 MiB (UWCOSIM_FMU_MAX_UNPACKED_MB)")
    proc = _run(tmp_path / "e", "--set", "run.fmu_max_unpacked_mb=0", env=child_env)
    _one_line(proc, 2, "run.fmu_max_unpacked_mb")
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


def test_an_ssp_zip_bomb_is_refused_before_it_is_read(tmp_path, project_fmus, child_env):
    """The limit applies to an ``.ssp`` archive too (item 7): one line, exit 3, alone or as a
    scenario's ``system.ssp`` (where ``run.fmu_max_unpacked_mb`` sets it)."""
    from test_ssp import auv_ssp

    ssp = auv_ssp(tmp_path / "auv.ssp", project_fmus)
    base = sum(i.file_size for i in zipfile.ZipFile(ssp).infolist()) / (1 << 20)
    big = _with_member(ssp, tmp_path / "big.ssp", "resources/big.bin", 8 << 20)
    assert big.stat().st_size < ssp.stat().st_size + (1 << 20)  # + 8 MiB of deflated zeros
    proc = subprocess.run([sys.executable, "-m", "uwcosim", "run", str(big), "--out",
                           str(tmp_path / "a"), "--no-figures"], cwd=ROOT,
                          env={**child_env, "UWCOSIM_FMU_MAX_UNPACKED_MB": "4"},
                          capture_output=True, text=True, timeout=120)
    _one_line(proc, 3, f"{big}: SSP archive unpacks to {base + 8:.0f} MiB, more than the limit "
                       f"of 4 MiB (UWCOSIM_FMU_MAX_UNPACKED_MB)")
    assert not (tmp_path / "a").exists()
    toml = tmp_path / "s.toml"
    toml.write_text('name = "s"\n[run]\nfmu_max_unpacked_mb = 4\n[system]\nssp = "big.ssp"\n')
    proc = subprocess.run([sys.executable, "-m", "uwcosim", "run", str(toml), "--out",
                           str(tmp_path / "b"), "--no-figures"], cwd=ROOT, env=child_env,
                          capture_output=True, text=True, timeout=120)
    _one_line(proc, 3, f"{big}: SSP archive unpacks to {base + 8:.0f} MiB, more than the limit "
                       f"of 4 MiB (run.fmu_max_unpacked_mb)")
    toml.write_text('name = "s"\n[run]\nfmu_max_unpacked_mb = "x"\n[system]\nssp = "big.ssp"\n')
    proc = subprocess.run([sys.executable, "-m", "uwcosim", "run", str(toml), "--out",
                           str(tmp_path / "c"), "--no-figures"], cwd=ROOT, env=child_env,
                          capture_output=True, text=True, timeout=120)
    _one_line(proc, 2, "key 'run.fmu_max_unpacked_mb': expected a positive number of MiB "
                       "(got 'x')")
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []


CAMPAIGN = """
seed = 3
runs = 6
[[variants]]
name = "v"
scenario = "{root}/scenarios/tan_terrain.toml"
set = ['estimators={{ekf={{type="ekf"}}}}', "run.duration=3000"]
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP],
                         ids=["SIGINT", "SIGTERM", "SIGHUP"])
def test_an_interrupted_campaign_leaves_no_temporary_folder(tmp_path, project_fmus, child_env,
                                                           sig):
    """The pool workers' run folders (``uwcosim_run_*``) and unzipped FMUs are in the
    campaign's temporary folder, removed when the campaign stops (item 18)."""
    spec = tmp_path / "c.toml"
    spec.write_text(CAMPAIGN.format(root=ROOT))
    tmp = Path(child_env["TMPDIR"])
    proc = subprocess.Popen([sys.executable, "-m", "uwcosim", "campaign", str(spec), "--out",
                             str(tmp_path / "o"), "--workers", "2"], cwd=ROOT, env=child_env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    deadline = time.monotonic() + 120
    while not list(tmp.rglob("uwcosim_run_*")):  # a run is in flight
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    assert list(tmp.iterdir()) == []


def _without_token(src: Path, dst: Path) -> Path:
    import re

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb'\s+instantiationToken="[^"]*"', b"", data)
            zout.writestr(item.filename, data)
    return dst


@pytest.mark.parametrize(("case", "expected"), [
    ("fmu_parameter", "key 'map.fmu_parameter': FMU 'sounder' has no variable 'nope'"),
    ("no_token", "has no instantiationToken (FMI 3.0 requires one)"),
    ("shared_vr", "inputs 'vx' and 'vy' share value reference {vr}"),
    ("outside", "key 'fmus.vehicle.start': the vehicle starts at (x, y) = (-500, 18000) m, "
                "outside the map (x in [0, 25000], y in [0, 25000])"),
])
def test_check_finds_what_run_refuses_at_load(tmp_path, project_fmus, case, expected):
    """Item 16: ``check`` reports what ``run`` refuses when it loads (and ``run`` names the
    same key)."""
    from uwcosim.api import run_scenario
    from uwcosim.core.errors import UwcosimError
    from uwcosim.run.preflight import check_scenario
    from uwcosim.scenario import load_scenario

    dvl = project_fmus / "DVL.fmu"
    expected = expected.replace("{vr}", _vx_reference(dvl))
    if case == "no_token":
        sets = [f'fmus.dvl.path="{_without_token(dvl, tmp_path / "t.fmu")}"']
    elif case == "shared_vr":
        sets = [f'fmus.dvl.path="{_shared_vr(dvl, tmp_path / "v.fmu")}"']
    else:
        sets = {"fmu_parameter": ["map.fmu_parameter=sounder.nope"],
                "outside": ["fmus.vehicle.start.x=-500.0"]}[case]
    report = check_scenario(SCEN, sets)
    assert [p for p in report.problems if expected in p.message], report.problems
    assert report.exit_code != 0
    with pytest.raises(UwcosimError) as err:
        run_scenario(load_scenario(SCEN, [*sets, "run.duration=3"]), tmp_path / "run",
                     figures=False)
    if case != "outside":  # run: the FMU's own words at t=0 ("outside the map")
        assert expected in str(err.value)
    else:
        assert "outside the map" in str(err.value)


def test_a_terminals_ctrl_c_to_the_process_group_stops_the_supervised_run(tmp_path,
                                                                           project_fmus,
                                                                           child_env):
    """A terminal sends Ctrl-C to its foreground process group: the supervising parent only
    (the run's child has a group of its own), which passes it on once."""
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out",
                             str(out), "--no-figures", "--set", 'estimators={ekf={type="ekf"}}',
                             "--set", "run.duration=12000"], cwd=ROOT, env=child_env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    while not (out / "log.parquet").exists():
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    time.sleep(1.0)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and without_progress(err).strip().count("\n") == 0, err
    assert "interrupted at t=" in err and "by SIGINT" in err
    assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
    assert list(Path(child_env["TMPDIR"]).iterdir()) == []
