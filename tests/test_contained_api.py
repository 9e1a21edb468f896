"""``uwcosim.run_scenario`` and ``simulate`` with ``contained=True``: the Python API's run in a
supervised child (:mod:`uwcosim.run.contained`). An FMU that ends its process, or the watchdog of
``run.fmu_timeout_s``, ends the child, not the caller (this test process), which gets an
``FMUError`` with the line ``uwcosim run`` prints and the log up to the end; a run's own error
comes back as it is; a signal stops the run as it stops ``uwcosim run``; a contained run's log
is the in-process run's, bit for bit. The Crasher FMU is ``tests/crasher.py``."""

from __future__ import annotations

import faulthandler
import json
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from test_fmu_crashes import LIGHT, _crasher

import uwcosim
from uwcosim.core.errors import FMUError, OutputError
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"


def _loaded(*args: str):
    """The light terrain scenario with ``--set`` style arguments."""
    return load_scenario(SCEN, [a for a in (*LIGHT, *args) if a != "--set"])


@pytest.fixture
def no_fault_dump():
    """No dump of pytest's fault handler from the child an FMU kills (it writes to the
    terminal, past the capture)."""
    enabled = faulthandler.is_enabled()
    faulthandler.disable()
    yield
    if enabled:
        faulthandler.enable(sys.__stderr__)


@pytest.mark.parametrize("stage", ["run_scenario", "simulate"])
def test_an_fmu_that_ends_the_process_ends_the_child_not_the_caller(tmp_path, project_fmus,
                                                                    no_fault_dump, stage):
    out = tmp_path / "run"
    loaded = _loaded(*_crasher("segfault", "doStep", 5.0))
    with pytest.raises(FMUError) as info:
        if stage == "simulate":
            uwcosim.simulate(loaded, out, contained=True)
        else:
            uwcosim.run_scenario(loaded, out, figures=False, contained=True)
    assert str(info.value) == (
        "FMU 'crash' ended the process during doStep at t=5 (killed by SIGSEGV; set "
        f"[fmus.crash] timeout_s to run it in a worker process) (log up to t=5 kept in "
        f"{out / 'log.parquet'})")
    assert read_log(out / "log.parquet")[0]["time"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert json.loads((out / "summary.json").read_text())["status"] == "failed"
    assert not (out / "log.parquet.journal").exists()


def test_the_watchdog_ends_the_child_not_the_caller(tmp_path, project_fmus, capfd):
    out = tmp_path / "run"
    with pytest.raises(FMUError) as info:
        uwcosim.run_scenario(_loaded(*_crasher("sleep", "doStep", 5.0), "--set",
                                     "run.fmu_timeout_s=1.0"), out, figures=False,
                             contained=True)
    message = str(info.value)
    assert message.startswith(
        "FMU 'crash' did not return from doStep within 1 s at t=5 (run.fmu_timeout_s)"), message
    assert message.count("kept in") == 1, message
    assert json.loads((out / "summary.json").read_text())["status"] == "failed"
    # finished by the run itself before the watchdog ended it: its record kept as it wrote it
    assert json.loads((out / "simulation.json").read_text())["estimators"]["ekf"]["total_time_s"]
    assert "uwcosim: error" not in capfd.readouterr().err  # said once: by the exception


def test_a_contained_run_gives_the_in_process_runs_log(tmp_path, project_fmus):
    loaded = _loaded()
    here = uwcosim.run_scenario(loaded, tmp_path / "here", figures=False)
    there = uwcosim.run_scenario(loaded, tmp_path / "there", figures=False, contained=True)
    assert uwcosim.simulate(loaded, tmp_path / "sim", contained=True) == tmp_path / "sim"
    assert there.status == here.status == "ok"
    assert there.out_dir == tmp_path / "there" and there.log_path == there.out_dir / "log.parquet"
    a, b = read_log(here.log_path)[0], read_log(there.log_path)[0]
    assert sorted(a) == sorted(b)
    c = read_log(tmp_path / "sim" / "log.parquet")[0]
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
        np.testing.assert_array_equal(a[name], c[name], err_msg=name)
    for key in ("rmse_position_m", "anees"):
        assert there.summary["estimators"]["ekf"][key] == here.summary["estimators"]["ekf"][key]


def test_the_runs_own_error_comes_back_as_it_is(tmp_path, project_fmus):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(OutputError) as here:
        uwcosim.run_scenario(_loaded(), blocker / "run", figures=False)
    with pytest.raises(OutputError) as there:
        uwcosim.run_scenario(_loaded(), blocker / "run", figures=False, contained=True)
    assert str(there.value) == str(here.value)
    assert any(n.startswith("raised in the run's child process:") and "Traceback" in n
               for n in there.value.__notes__)


@pytest.mark.parametrize("where", ["in_an_fmu_call", "between_steps"])
def test_a_signal_stops_a_contained_run_as_it_stops_uwcosim_run(tmp_path, project_fmus, where):
    """A script's contained run, a signal to the script: the run stops at its step (in an FMU
    call that does not return: the watcher stops it), the script gets ``RunInterrupted`` (exit
    status 128 + signal) and goes on; the log is readable up to the step named."""
    out = tmp_path / "run"
    if where == "in_an_fmu_call":
        sig, extra = signal.SIGINT, [*_crasher("sleep", "doStep", 5.0), "--set",
                                     "run.duration=50", "--set", "run.fmu_timeout_s=600"]
    else:  # a long run: the signal lands between two steps
        sig, extra = signal.SIGTERM, ["--set", "run.duration=12000"]
    script = tmp_path / "script.py"
    script.write_text(textwrap.dedent(f"""\
        import sys
        import uwcosim
        from uwcosim.core.errors import RunInterrupted
        from uwcosim.scenario import load_scenario
        sets = {[a for a in (*LIGHT, *extra) if a != "--set"]!r}
        try:
            uwcosim.run_scenario(load_scenario({str(SCEN)!r}, sets), {str(out)!r},
                                 figures=False, contained=True)
        except RunInterrupted as exc:
            print("caught", exc.exit_code, exc)
        print("the script goes on")
        """))
    proc = subprocess.Popen([sys.executable, str(script)], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out / "log.parquet").exists():
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.02)
    time.sleep(3.0 if where == "in_an_fmu_call" else 0.5)  # at t=5 in the FMU, for an hour
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 0, stderr
    lines = stdout.splitlines()
    m = re.fullmatch(rf"caught {128 + sig} interrupted at t=(\d+) by {sig.name} "
                     rf"\(log up to t=(\d+) kept in {re.escape(str(out))}/log.parquet\)",
                     lines[0])
    assert m, (stdout, stderr)
    assert lines[1] == "the script goes on"
    t = read_log(out / "log.parquet")[0]["time"]
    assert t[-1] == float(m[2]) and t.tolist() == [float(k) for k in range(t.size)]
    if where == "in_an_fmu_call":
        assert t[-1] == 5.0
    else:
        assert 0 < t[-1] < 12000
    assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
