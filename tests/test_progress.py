"""Progress of ``uwcosim run``/``demo``: an observer of the master (one line per stage without
a terminal, a tqdm bar on one), and the first-use kernel compile announced."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from uwcosim.run.progress import COMPILE_NOTE, RunProgress
from uwcosim.run.simulate import run_scenario
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def _run(tmp_path, progress):
    loaded = load_scenario(ROOT / "scenarios" / "lost_measurements.toml", ["run.duration=40"])
    return run_scenario(loaded, tmp_path / "run", figures=False, progress=progress)


def test_progress_is_an_observer_with_one_line_per_stage(tmp_path, project_fmus):
    stream = io.StringIO()
    progress = RunProgress(40, 1.0, 0.0, stream=stream)
    assert callable(getattr(progress, "on_step", None))  # the Observer protocol
    _run(tmp_path, progress)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "uwcosim: simulating 40 steps of 1 s (t = 0 .. 40 s)"
    assert lines[1].startswith("uwcosim: simulated 40 steps in ") and "steps/s" in lines[1]
    assert lines[2] == "uwcosim: evaluating (summary.json)"
    assert len(lines) == 3 and "\r" not in stream.getvalue()


def test_progress_bar_on_a_terminal(tmp_path, project_fmus):
    stream = _Tty()
    progress = RunProgress(40, 1.0, 0.0, stream=stream)
    assert progress.use_bar
    _run(tmp_path, progress)
    text = stream.getvalue()
    assert "simulating" in text and "/40" in text and "step/s" in text and "\r" in text
    assert "uwcosim: evaluating (summary.json)" in text


def test_quiet_shows_nothing(tmp_path, project_fmus):
    stream = _Tty()
    _run(tmp_path, RunProgress(40, 1.0, 0.0, stream=stream, enabled=False))
    assert stream.getvalue() == ""


def test_first_compile_says_what_and_how_long_once():
    stream = io.StringIO()
    progress = RunProgress(10, 1.0, stream=stream)
    progress.compiling("kernel_a")
    progress.compiling("kernel_b")
    assert stream.getvalue() == f"uwcosim: {COMPILE_NOTE}\n"
    assert "usually 1-3 min" in COMPILE_NOTE


def test_numba_compile_events_reach_the_hook():
    """The listener :mod:`uwcosim.core.jit` registers hears a real compile (a cache miss)."""
    numba = pytest.importorskip("numba")
    from uwcosim.core import jit

    heard = []
    jit.listen(heard.append)

    @numba.njit(cache=False)
    def plus_one(x):
        return x + 1

    assert plus_one(1) == 2
    assert "test_numba_compile_events_reach_the_hook.<locals>.plus_one" in heard


REPLAY = """\
name = "cv_replay"
[replay]
file = "fixes.csv"
time = "t"
[replay.measurements]
"gps.px_m" = "x"
"gps.py_m" = "y"
[sensors.gps]
outputs = ["gps.px_m", "gps.py_m"]
sigma = [2.0, 3.0]
[model]
kind = "cv"
truth = ["ref.px", "ref.vx", "ref.py", "ref.vy"]
sensors = ["gps"]
q_psd = [0.0, 0.01, 0.0, 0.02]
[estimation]
initial_std = [10.0, 1.0, 10.0, 1.0]
initial_error = "zero"
initial_state = {px = 0.0, vx = 0.5, py = 0.0, vy = 0.25}
[estimators.kf]
type = "kf"
"""


def _replay(tmp_path, progress):
    """A replay of 36 rows with irregular time stamps (no FMU): 35 steps, t = 1000 .. 1030."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    t = 1000.0 + 30.0 * (np.arange(36) / 35.0) ** 2  # irregular gaps
    pcsv.write_csv(pa.table({"t": t, "x": 0.5 * (t - 1000.0), "y": 0.25 * (t - 1000.0)}),
                   tmp_path / "fixes.csv")
    (tmp_path / "replay.toml").write_text(REPLAY)
    loaded = load_scenario(tmp_path / "replay.toml")
    return run_scenario(loaded, tmp_path / "run", figures=False, progress=progress)


def test_a_replay_takes_its_total_from_the_recording(tmp_path):
    """A replay's scenario has no step count (the CLI passes ``steps=None``): the total comes
    from the file at the first row, and the run ends with its time and the evaluation."""
    stream = io.StringIO()
    _replay(tmp_path, RunProgress(None, None, stream=stream))
    lines = stream.getvalue().splitlines()
    assert lines[0] == "uwcosim: replaying 35 steps (36 rows of fixes.csv, t = 1000 .. 1030 s)"
    assert lines[1].startswith("uwcosim: replayed 35 steps in ") and "steps/s" in lines[1]
    assert lines[2] == "uwcosim: evaluating (summary.json)"
    assert len(lines) == 3


def test_a_replay_bar_has_its_total_and_the_rows_time_stamps(tmp_path):
    stream = _Tty()
    _replay(tmp_path, RunProgress(None, None, stream=stream))
    text = stream.getvalue()
    assert "replaying" in text and "/35" in text and "t = 1030 s" in text and "\r" in text
    assert "uwcosim: evaluating (summary.json)" in text
