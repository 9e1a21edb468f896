"""Regression comparison of run logs: tolerance tubes, NaN and flags, reports, diff plots, the
``uwcosim regress`` exit statuses and the pytest helper."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from uwcosim.regress.compare import RegressionInputError, compare_logs
from uwcosim.regress.pytest_helper import UPDATE_ENV, assert_matches_baseline
from uwcosim.runlog import RunLogger

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"


def write_log(path: Path, t, columns: dict, flags: dict | None = None) -> Path:
    flags = flags or {}
    log = RunLogger(path, list(columns), list(flags), {"seed": 0}, chunk=64)
    for k in range(len(t)):
        log.append(np.array([t[k], *(columns[c][k] for c in columns)]),
                   np.array([flags[f][k] for f in flags], dtype=bool))
    log.close()
    return path


@pytest.fixture
def base(tmp_path):
    t = np.arange(0.0, 101.0)
    cols = {"x": 1000.0 + 0.5 * t, "s": np.sin(np.maximum(t - 10.0, 0.0) / 5.0),
            "z": np.where(t % 7 == 0, np.nan, t)}
    flags = {"z.received": t % 7 != 0}
    return t, cols, flags, write_log(tmp_path / "base.parquet", t, cols, flags)


def test_identical_logs_pass(base, tmp_path):
    t, cols, flags, ref = base
    rep = compare_logs(write_log(tmp_path / "run.parquet", t, cols, flags), ref)
    assert rep.ok and len(rep.results) == 4 and "identical values" in rep.text()


def test_a_deviation_is_reported_with_its_size_and_time(base, tmp_path):
    t, cols, flags, ref = base
    x = cols["x"].copy()
    x[40] += 0.05  # tolerance: 1e-9 + 1e-6 * 1050 = 1.05e-3
    x[41] += 1e-4  # inside
    run = write_log(tmp_path / "run.parquet", t, {**cols, "x": x}, flags)
    rep = compare_logs(run, ref, plot_dir=tmp_path / "plots")
    assert not rep.ok and [r.name for r in rep.failures] == ["x"]
    bad = rep.failures[0]
    assert bad.n_out == 1 and bad.t_max_dev == 40.0 and bad.max_dev == pytest.approx(0.05)
    assert "FAILED x: 1 of 101 samples outside the tube; largest deviation 0.05 at t=40" \
        in rep.text()
    assert rep.plots == [tmp_path / "plots" / "x.png"] and rep.plots[0].stat().st_size > 1000
    assert compare_logs(run, ref, rtol=1e-4).ok  # a wider band takes it


def test_the_time_tolerance_widens_the_tube_in_time(base, tmp_path):
    t, cols, flags, ref = base
    shifted = {**cols, "s": np.sin(np.maximum(t - 10.4, 0.0) / 5.0)}  # 0.4 s late
    run = write_log(tmp_path / "run.parquet", t, shifted, flags)
    # a sampled peak is cut by the piecewise-linear reference: some value tolerance as well
    assert [r.name for r in compare_logs(run, ref, rtol=1e-2).failures] == ["s"]
    assert compare_logs(run, ref, rtol=1e-2, ttol=0.5).ok


def test_nan_patterns_and_flags_must_match(base, tmp_path):
    t, cols, flags, ref = base
    z = cols["z"].copy()
    z[10] = np.nan
    rec = flags["z.received"].copy()
    rec[10] = False
    run = write_log(tmp_path / "run.parquet", t, {**cols, "z": z}, {"z.received": rec})
    rep = compare_logs(run, ref)
    assert sorted(r.name for r in rep.failures) == ["z", "z.received"]
    assert "NaN pattern differs from the baseline (first at t=10)" in rep.text()


def test_other_time_grids_and_coverage(base, tmp_path):
    t, cols, flags, ref = base
    tf = np.arange(0.0, 100.5, 0.5)  # twice as fine: the linear x matches between samples
    fine = write_log(tmp_path / "fine.parquet", tf, {"x": 1000.0 + 0.5 * tf})
    rep = compare_logs(fine, ref, signals=["x"])
    assert rep.ok and rep.n_samples == tf.size
    short = write_log(tmp_path / "short.parquet", t[:50], {"x": cols["x"][:50]})
    rep = compare_logs(short, ref, signals=["x"])
    assert not rep.ok and "the run covers t = 0 .. 49 s, the baseline 0 .. 100 s" in rep.text()
    rep = compare_logs(write_log(tmp_path / "less.parquet", t, {"x": cols["x"]}), ref)
    assert rep.missing == ["s", "z", "z.received"] and not rep.ok
    rep = compare_logs(ref, write_log(tmp_path / "less.parquet", t, {"x": cols["x"]}))
    assert rep.ok and rep.extra == ["s", "z", "z.received"]
    assert "note: 3 signals of the run are not in the baseline" in rep.text()


def test_bad_input(base, tmp_path):
    t, cols, flags, ref = base
    with pytest.raises(RegressionInputError, match="run log not found"):
        compare_logs(tmp_path / "nope", ref)
    other = write_log(tmp_path / "other.parquet", t, {"y": t})
    with pytest.raises(RegressionInputError, match="no signals in common"):
        compare_logs(other, ref)
    late = write_log(tmp_path / "late.parquet", t + 500.0, cols, flags)
    with pytest.raises(RegressionInputError, match="does not overlap"):
        compare_logs(late, ref)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "uwcosim", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=300)


def test_cli_exit_status(base, tmp_path):
    t, cols, flags, ref = base
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    write_log(run_dir / "log.parquet", t, {**cols, "x": cols["x"] + 1.0}, flags)
    r = _cli("regress", str(run_dir), str(ref), "--signals", "s*")
    assert r.returncode == 0 and "all 1 signals pass" in r.stdout, r.stdout + r.stderr
    r = _cli("regress", str(run_dir), str(ref))
    assert r.returncode == 1 and "FAILED x" in r.stdout
    assert (run_dir / "regress" / "x.png").is_file()
    r = _cli("regress", str(run_dir), str(tmp_path / "missing.parquet"))
    assert r.returncode == 2 and "baseline not found" in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    r = _cli("regress", str(run_dir), str(ref), "--signals", "nothing*")
    assert r.returncode == 2 and "no signals matching nothing* in common" in r.stderr


def test_pytest_helper(tan, tmp_path, monkeypatch):
    scenario = SCENARIOS / "tan_terrain.toml"
    over = ["run.duration=20", 'estimators={ekf={type="ekf"}}']
    baseline = tmp_path / "b.parquet"
    with pytest.raises(AssertionError, match="baseline missing"):
        assert_matches_baseline(scenario, baseline, over)
    monkeypatch.setenv(UPDATE_ENV, "1")
    assert_matches_baseline(scenario, baseline, over)
    monkeypatch.delenv(UPDATE_ENV)
    assert baseline.is_file()
    rep = assert_matches_baseline(scenario, baseline, over)
    assert rep.ok
    with pytest.raises(AssertionError, match=r"FAILED est\.ekf\.x") as info:
        assert_matches_baseline(scenario, baseline, over, seed=5, out_dir=tmp_path / "o",
                                signals=["vehicle.x", "est.ekf.x"])
    assert "diff plots" in str(info.value) and (tmp_path / "o" / "diff").is_dir()


def test_a_baseline_that_covers_less_than_the_run_fails(base, tmp_path):
    """Issue 24, item 3: a one-row baseline, or a 20 s baseline against a 40 s run, passed
    ("all 35 signals pass"). Different time spans fail; ``allow_shorter`` passes a shorter
    baseline but says so in a warning line."""
    t, cols, flags, ref = base
    one = write_log(tmp_path / "one.parquet", t[:1], {"x": cols["x"][:1]})
    rep = compare_logs(ref, one, signals=["x"])
    assert not rep.ok and "the run covers t = 0 .. 100 s, the baseline 0 .. 0 s" in rep.text()
    half = write_log(tmp_path / "half.parquet", t[:51], {"x": cols["x"][:51]})
    rep = compare_logs(ref, half, signals=["x"])
    assert not rep.ok and "FAILED time" in rep.text()
    rep = compare_logs(ref, half, signals=["x"], allow_shorter=True)
    assert rep.ok
    assert "warning: the baseline covers only t = 0 .. 50 s of the run's 0 .. 100 s" \
        in rep.text()
    # a shorter run is never allowed
    rep = compare_logs(half, ref, signals=["x"], allow_shorter=True)
    assert not rep.ok and "FAILED time" in rep.text()
    r = subprocess.run([sys.executable, "-m", "uwcosim", "regress", str(ref), str(half),
                        "--no-plots"], capture_output=True, text=True)
    assert r.returncode == 1 and "FAILED time" in r.stdout, r.stdout + r.stderr
    r = subprocess.run([sys.executable, "-m", "uwcosim", "regress", str(ref), str(half),
                        "--no-plots", "--allow-shorter", "--signals", "x"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "warning: the baseline covers only" in r.stdout, r.stdout


def test_the_closest_margin_is_measured_against_the_tube(base, tmp_path):
    """Issue 24, item 19: with a time tolerance, a passing signal was reported as "deviation
    100 = 4.8e+04 of its tolerance": the margin is the distance outside the tube's band."""
    t, cols, flags, ref = base
    step = np.where(t < 50, 0.0, 100.0)
    a = write_log(tmp_path / "a.parquet", t, {"x": step})
    b = write_log(tmp_path / "b.parquet", t + 0.0, {"x": np.where(t < 51, 0.0, 100.0)})
    rep = compare_logs(a, b, ttol=2.0, signals=["x"])
    assert rep.ok, rep.text()
    assert "of its tolerance" not in rep.text() or "= 0 of" in rep.text(), rep.text()
    line = rep.text().splitlines()[-1]
    assert "4.8e+04" not in line and "100 =" not in line, line
