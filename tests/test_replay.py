"""Replay of recorded data (``[replay]``): replay equals simulation, irregular time stamps
against the exact Kalman filter, lost measurements, units, control files with step
discontinuities, and bad inputs as one-line errors."""

from __future__ import annotations

import textwrap

import numpy as np
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.export import export_csv
from uwcosim.models.linear import cv_noise_gain, cv_transition
from uwcosim.run.simulate import run_scenario, simulate
from uwcosim.runlog import columns, read_log
from uwcosim.scenario import load_scenario

ESTIMATORS = ("dead_reckoning", "ekf", "ukf", "pf", "pfm_psi", "point_mass")

#: the filters' side of scenarios/tan_terrain.toml, fed from its exported log
TAN_REPLAY = """\
name = "tan_replay"
[run]
seed = 1
[replay]
file = "log.csv"
control_row = "same"        # a uwcosim log: row k holds the controls of the step ending at k
[replay.measurements]
"dvl.vx_m" = "z.dvl.vx_m"
"dvl.vy_m" = "z.dvl.vy_m"
"sounder.depth_m" = "z.sounder.depth_m"
[replay.controls]
psi = "controls.psi"
a = "controls.a"
[replay.reference]
"vehicle.x" = "vehicle.x"
"vehicle.y" = "vehicle.y"
"vehicle.vx" = "vehicle.vx"
"vehicle.vy" = "vehicle.vy"
[sensors.dvl]
outputs = ["dvl.vx_m", "dvl.vy_m"]
sigma = [0.05, 0.05]
[sensors.depth]
outputs = ["sounder.depth_m"]
sigma = [1.0]
[map]
kind = "synthetic"
seed = 7
extent = [0.0, 25000.0, 0.0, 25000.0]
resolution = 50.0
[model]
kind = "tan"
truth = ["vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy"]
controls = ["psi", "a"]
sensors = ["dvl", "depth"]
q_psd = [0.05, 0.05, 1e-5, 1e-5]
[estimation]
initial_std = [30.0, 30.0, 0.05, 0.05]
[estimators.dead_reckoning]
type = "dead_reckoning"
[estimators.ekf]
type = "ekf"
[estimators.ukf]
type = "ukf"
[estimators.pf]
type = "pf"
n_particles = 1000
[estimators.pfm_psi]
type = "pfm_psi"
K = 10
[estimators.point_mass]
type = "point_mass"
"""


@pytest.fixture(scope="module")
def tan_run(tmp_path_factory, project_fmus):
    """A 120 s simulated TAN run (scenarios/tan_terrain.toml) and its log exported as CSV."""
    from tests.conftest import SCENARIOS

    d = tmp_path_factory.mktemp("tan")
    loaded = load_scenario(SCENARIOS / "tan_terrain.toml", ["run.duration=120"])
    run = simulate(loaded, d / "sim")
    csv = export_csv(run, d / "log.csv")
    return run, csv


def _replay(tmp_path, text: str, csv=None, name="replay.toml"):
    if csv is not None:
        (tmp_path / "log.csv").write_bytes(csv.read_bytes())
    path = tmp_path / name
    path.write_text(text)
    return path


def test_replay_equals_simulation(tmp_path, tan_run, cli):
    """The measurements and controls a simulated run logged, exported with ``uwcosim export
    --csv`` and replayed, give the run's estimates bit for bit (every filter: the
    deterministic ones, and the particle filter with the same seed), and the same log."""
    sim, csv = tan_run
    scen = _replay(tmp_path, TAN_REPLAY, csv)
    code, out, err = cli("run", scen, "--out", tmp_path / "rep")
    assert code == 0, err
    assert "pfm_psi" in out and "run directory" in out
    a, meta_a = read_log(sim / "log.parquet")
    b, meta_b = read_log(tmp_path / "rep" / "log.parquet")
    assert meta_b["replay"]["rows"] == 121 and meta_b["estimators"] == meta_a["estimators"]
    common = [c for c in b if c in a]
    assert len(common) == len(b) - 0 and set(a) - set(b) == {"vehicle.psi_out"}
    for c in common:  # estimates, NIS, NEES, truth, measurements, controls, time, flags
        np.testing.assert_array_equal(b[c], a[c], err_msg=c)
    for e in ESTIMATORS:
        assert np.isfinite(b[columns.estimate(e, "x")]).all()
    # regress agrees: identical values
    code, out, _ = cli("regress", tmp_path / "rep", sim / "log.parquet", "--rtol", "0",
                       "--atol", "0", "--ttol", "0", "--no-plots", "--signals", "est.*")
    assert code == 0 and "identical values" in out
    # the same seed gives the same estimates; another seed another initial error and PF
    code, _, err = cli("run", scen, "--out", tmp_path / "rep7", "--seed", "7")
    c7, _ = read_log(tmp_path / "rep7" / "log.parquet")
    assert not np.array_equal(c7[columns.estimate("pf", "x")], b[columns.estimate("pf", "x")])
    # the other stages work on it: summary, figures, report, export, check
    rep = tmp_path / "rep"
    for f in ("summary.json", "report.md", "trajectory.png", "position_error.png"):
        assert (rep / f).is_file(), f
    assert "Replay of `log.csv`" in (rep / "report.md").read_text()
    code, out, _ = cli("report", rep, "--html")
    assert code == 0 and (rep / "report.html").is_file()
    code, out, _ = cli("export", rep, "--csv")
    assert code == 0 and (rep / "log.csv").is_file()
    code, out, err = cli("check", scen)
    assert code == 0 and "replay file" in out, err


def _cv_scenario(file: str, extra: str = "", meas: str = "") -> str:
    return textwrap.dedent(f"""\
        name = "cv_replay"
        [replay]
        file = "{file}"
        time = "t"
        {extra}
        [replay.measurements]
        {meas or '"gps.px_m" = "x"' + chr(10) + '"gps.py_m" = "y"'}
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
        initial_state = {{px = 1.0, vx = 0.5, py = -2.0, vy = 0.25}}
        [estimators.kf]
        type = "kf"
        """)


def _exact_kf(t, Z, R, q, x0, P0):
    """The Kalman filter of the constant-velocity model with the gaps ``diff(t)``
    (``F(dt)``, ``Q = G diag(q/dt) G'``), skipping NaN components."""
    x, P = x0.copy(), P0.copy()
    H = np.zeros((2, 4))
    H[0, 0] = H[1, 2] = 1.0
    out = [x.copy()]
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        F, G = cv_transition(dt), cv_noise_gain(dt)
        x = F @ x
        P = F @ P @ F.T + (G * (q / dt)) @ G.T
        ok = np.isfinite(Z[k])
        if ok.any():
            Hk, Rk = H[ok], R[np.ix_(ok, ok)]
            S = Hk @ P @ Hk.T + Rk
            K = P @ Hk.T @ np.linalg.inv(S)
            x = x + K @ (Z[k][ok] - Hk @ x)
            P = (np.eye(4) - K @ Hk) @ P
        out.append(x.copy())
    return np.array(out)


def test_irregular_time_stamps_against_the_exact_kalman_filter(tmp_path, cli):
    rng = np.random.default_rng(4)
    dt = rng.choice([0.1, 0.35, 1.0, 2.5], size=80)  # irregular gaps
    t = 1000.0 + np.concatenate([[0.0], np.cumsum(dt)])
    x = 1.0 + 0.5 * (t - t[0])
    y = -2.0 + 0.25 * (t - t[0])
    zx = x + rng.normal(0, 2.0, t.size)
    zy = y + rng.normal(0, 3.0, t.size)
    zy[::7] = np.nan  # lost
    pcsv.write_csv(pa.table({"t": t, "x": zx, "y": zy}), tmp_path / "fixes.csv")
    scen = _replay(tmp_path, _cv_scenario("fixes.csv"))
    code, _, err = cli("run", scen, "--out", tmp_path / "run", "--no-figures")
    assert code == 0, err
    cols, meta = read_log(tmp_path / "run" / "log.parquet")
    np.testing.assert_array_equal(cols["time"], t)  # as the file gives it
    est = np.stack([cols[columns.estimate("kf", s)] for s in ("px", "vx", "py", "vy")], 1)
    Z = np.stack([zx, zy], 1)
    ref = _exact_kf(t, Z, np.diag([4.0, 9.0]), np.array([0.0, 0.01, 0.0, 0.02]),
                    np.array([1.0, 0.5, -2.0, 0.25]), np.diag([100.0, 1.0, 100.0, 1.0]))
    np.testing.assert_allclose(est, ref, rtol=1e-10, atol=1e-9)
    assert not cols["z.gps.py_m.received"][7] and cols["z.gps.py_m.received"][8]
    assert meta["replay"]["dt_min_s"] == pytest.approx(0.1)
    s = (tmp_path / "run" / "summary.json").read_text()
    assert "no value at any step" in s  # no reference mapped: no accuracy metrics


def test_lost_measurements_flags_units_and_a_sparse_reference(tmp_path, cli):
    n = 30
    t = np.arange(n) * 2.0
    x, y = 5.0 + 1.5 * t, 3.0 - 0.5 * t
    knots = 1852.0 / 3600.0
    vx = np.where(np.arange(n) % 5 == 3, np.nan, 1.5 / knots)  # knots, some NaN
    flag = np.ones(n, dtype=bool)
    flag[10] = False  # a value present but flagged lost
    ref_x = np.full(n, np.nan)
    ref_x[::6] = x[::6] / 1000.0  # sparse fixes, in km
    ref_y = np.full(n, np.nan)
    ref_y[::6] = y[::6] / 0.3048  # in ft
    table = pa.table({"t": t, "px": x, "ve": vx, "ok": flag, "py": pa.array(
        [None if i == 4 else v for i, v in enumerate(y * 100.0)]),  # cm, one empty cell
        "rx": ref_x, "ry": ref_y, "vy_cms": np.full(n, -50.0)})
    pq.write_table(table, tmp_path / "mission.parquet")
    meas = textwrap.dedent('''\
        "gps.px_m" = "px"
        "gps.py_m" = {column = "py", unit = "cm"}
        "dvl.vx_m" = {column = "ve", unit = "knots", received = "ok"}
        "dvl.vy_m" = {column = "vy_cms", unit = "cm/s"}
        ''')
    text = _cv_scenario("mission.parquet", meas=meas).replace(
        '[sensors.gps]', '[sensors.dvl]\noutputs = ["dvl.vx_m", "dvl.vy_m"]\n'
        'sigma = [0.1, 0.1]\n[sensors.gps]').replace('sensors = ["gps"]',
                                                      'sensors = ["gps", "dvl"]')
    text = text.replace("[estimation]", '[replay.reference]\n"ref.px" = {column = "rx", '
                        'unit = "km"}\n"ref.py" = {column = "ry", unit = "ft"}\n[estimation]')
    scen = _replay(tmp_path, text)
    code, _, err = cli("run", scen, "--out", tmp_path / "run")
    assert code == 0, err
    cols, _ = read_log(tmp_path / "run" / "log.parquet")
    rec = cols["z.dvl.vx_m.received"]
    assert not rec[3] and not rec[10] and rec[4] and np.isnan(cols["z.dvl.vx_m"][10])
    np.testing.assert_allclose(cols["z.dvl.vx_m"][4], 1.5, rtol=1e-12)
    np.testing.assert_allclose(cols["z.dvl.vy_m"], -0.5, rtol=1e-12)
    assert not cols["z.gps.py_m.received"][4]
    np.testing.assert_allclose(cols["z.gps.py_m"][5], y[5], rtol=1e-12)
    np.testing.assert_allclose(cols["ref.px"][::6], x[::6], rtol=1e-12)
    np.testing.assert_allclose(cols["ref.py"][::6], y[::6], rtol=1e-12)
    assert np.isnan(cols["ref.px"][1:6]).all() and np.isnan(cols["ref.vx"]).all()
    import json
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    kf = s["estimators"]["kf"]
    assert kf["reference_steps"] == 4  # rows 6, 12, 18, 24 (row 0 is the start)
    assert np.isfinite(kf["rmse_position_m"]) and kf["rmse_position_m"] < 5.0
    assert any("position at 4 of the 29 filtered steps" in n for n in s["notes"])
    assert (tmp_path / "run" / "trajectory.png").is_file()


@pytest.mark.parametrize("change, key, expected", [
    (lambda s: s.replace('"gps.px_m" = "x"', '"gps.px_m" = "xx"'),
     "replay.measurements.gps.px_m", "column 'xx' is not in"),
    (lambda s: s.replace('"gps.px_m" = "x"', '"gps.px_m" = {column = "x", unit = "parsec"}'),
     "replay.measurements.gps.px_m", "unknown unit 'parsec'"),
    (lambda s: s.replace('time = "t"', 'time = "tt"'), "replay.time", "column 'tt'"),
    (lambda s: s.replace('fixes.csv', 'none.csv'), "replay.file", "file not found"),
    (lambda s: s.replace('"gps.px_m" = "x"', '"gps.px_m" = "name"'),
     "replay.measurements.gps.px_m", "expected numbers"),
    (lambda s: s.replace('initial_state = {px = 1.0, vx = 0.5, py = -2.0, vy = 0.25}',
                         'initial_state = {px = 1.0, vx = 0.5}'),
     "estimation.initial_state", "for py, vy"),
    (lambda s: s.replace('[replay]', '[run]\nstep = 1.0\n[replay]'), "run.step",
     "takes its steps from the file"),
    (lambda s: s.replace('"gps.px_m" = "x"\n', ''), "replay.measurements",
     "no column for gps.px_m"),
])
def test_bad_replay_inputs_are_one_line_errors(tmp_path, cli, change, key, expected):
    pcsv.write_csv(pa.table({"t": [0.0, 1.0, 2.0], "x": [0.0, 1.0, 2.0],
                             "y": [0.0, 1.0, 2.0], "name": ["a", "b", "c"]}),
                   tmp_path / "fixes.csv")
    scen = _replay(tmp_path, change(_cv_scenario("fixes.csv")))
    code, _, err = cli("run", scen, "--out", tmp_path / "run")
    assert code == 2 and len(err) == 1, err
    assert str(scen) in err[0] and f"key '{key}" in err[0] and expected in err[0], err[0]


def test_non_monotonic_and_repeated_time_stamps_are_refused(tmp_path, cli):
    for times, what in (([0.0, 2.0, 1.0], "goes back to t=1"), ([0.0, 1.0, 1.0], "repeats")):
        pcsv.write_csv(pa.table({"t": times, "x": [0.0] * 3, "y": [0.0] * 3}),
                       tmp_path / "fixes.csv")
        scen = _replay(tmp_path, _cv_scenario("fixes.csv"))
        code, _, err = cli("run", scen, "--out", tmp_path / "run")
        assert code == 2 and len(err) == 1 and "key 'replay.time'" in err[0]
        assert "fixes.csv" in err[0] and "data row 3" in err[0] and what in err[0], err[0]


def test_a_replay_refuses_fmu_sections(tmp_path):
    pcsv.write_csv(pa.table({"t": [0.0, 1.0], "x": [0.0, 1.0], "y": [0.0, 1.0]}),
                   tmp_path / "fixes.csv")
    text = _cv_scenario("fixes.csv") + '[noise.p]\ntargets = ["v.w"]\npsd = [1.0]\n'
    with pytest.raises(ScenarioError, match=r"key 'noise': a replay has no FMUs"):
        load_scenario(_replay(tmp_path, text))


# -- control files for FMU inputs ------------------------------------------------------------
def test_a_control_file_with_a_step_discontinuity_drives_an_fmu_input(tmp_path, tan):
    """``[controls.a] file = ...``: a repeated time is a jump of the acceleration at that time
    (a = 0.01 until t = 20, then -0.02): the vehicle's speed follows the closed form."""
    pcsv.write_csv(pa.table({"t": [0.0, 20.0, 20.0, 60.0], "acc": [1.0, 1.0, -2.0, -2.0]}),
                   tmp_path / "acc.csv")
    loaded = tan(["run.duration=40", "estimators={}", "noise.process.psd=[0.0, 0.0, 0.0, 0.0]",
                  f'controls.a={{target = "vehicle.a", file = "{tmp_path / "acc.csv"}", '
                  f'time = "t", column = "acc", scale = 0.01, interpolation = "hold"}}',
                  'controls.psi={target = "vehicle.psi", table = [[0, 0.0]]}'])
    run = run_scenario(loaded, tmp_path / "run", figures=False).out_dir
    cols, _ = read_log(run / "log.parquet")
    t, a, vx = cols["time"], cols["controls.a"], cols["vehicle.vx"]
    # the log's row k holds the control held over the step that ended at t_k
    np.testing.assert_array_equal(a[1:21], 0.01)
    np.testing.assert_array_equal(a[21:], -0.02)
    expected = 0.5 + np.where(t <= 20.0, 0.01 * t, 0.2 - 0.02 * (t - 20.0))
    np.testing.assert_allclose(vx, expected, rtol=0, atol=1e-9)


def test_inline_tables_take_a_repeated_time_as_a_step():
    from uwcosim.master.sources import TableControl
    from uwcosim.master.system import Control

    lin = TableControl(Control(target="v.a", table=[[0, 0.0], [1, 1.0], [1, 5.0], [2, 6.0]]))
    np.testing.assert_array_equal(lin.value(np.array([0.5, 0.999, 1.0, 1.5, 3.0])),
                                  [0.5, 0.999, 5.0, 5.5, 6.0])
    hold = TableControl(Control(target="v.a", table=[[0, 0.0], [1, 1.0], [1, 5.0]],
                                interpolation="hold"))
    np.testing.assert_array_equal(hold.value(np.array([0.5, 1.0, 2.0])), [0.0, 5.0, 5.0])
    with pytest.raises(ValueError, match="given more than twice"):
        Control(target="v.a", table=[[0, 0.0], [0, 1.0], [0, 2.0]])
    with pytest.raises(ValueError, match=r"times must not decrease \(row 2"):
        Control(target="v.a", table=[[1, 0.0], [0, 1.0]])


def test_bad_control_files_are_one_line_errors(tmp_path, tan, cli, project_fmus):
    from tests.conftest import SCENARIOS

    pcsv.write_csv(pa.table({"t": [0.0, 2.0, 1.0], "acc": [1.0, 1.0, 2.0]}),
                   tmp_path / "acc.csv")
    base = ["--set", "run.duration=10", "--out", tmp_path / "r", "--force"]
    for ctl, expected in (
            (f'{{target = "vehicle.a", file = "{tmp_path / "acc.csv"}", time = "t", '
             f'column = "accel"}}', "column 'accel' is not in"),
            (f'{{target = "vehicle.a", file = "{tmp_path / "acc.csv"}", time = "t", '
             f'column = "acc"}}', "times must not decrease (row 3"),
            (f'{{target = "vehicle.a", file = "{tmp_path / "no.csv"}", column = "acc"}}',
             "file not found")):
        code, _, err = cli("run", SCENARIOS / "tan_terrain.toml", *base, "--set",
                           f"controls.a={ctl}")
        assert code == 2 and len(err) == 1 and "key 'controls.a" in err[0], err
        assert expected in err[0], err[0]


def test_missing_columns_lost_and_figures_without_a_reference(tmp_path, cli):
    """``missing_columns = "lost"``: a mapped measurement column the file does not have is
    never received (a note says so); a replay without any reference still draws its
    estimates."""
    t = np.arange(12) * 1.5
    pcsv.write_csv(pa.table({"t": t, "x": 2.0 * t}), tmp_path / "fixes.csv")
    text = _cv_scenario("fixes.csv", extra='missing_columns = "lost"')
    scen = _replay(tmp_path, text)
    code, _, err = cli("run", scen, "--out", tmp_path / "run")
    assert code == 0, err
    cols, _ = read_log(tmp_path / "run" / "log.parquet")
    assert not cols["z.gps.py_m.received"].any() and cols["z.gps.px_m.received"][1:].all()
    import json
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert any("gps.py_m has no column 'y'" in n for n in s["notes"])
    assert (tmp_path / "run" / "trajectory.png").is_file()
    # without the setting, the same file is an error naming the column
    code, _, err = cli("run", _replay(tmp_path, _cv_scenario("fixes.csv"), name="b.toml"),
                       "--out", tmp_path / "run2")
    assert code == 2 and "column 'y' is not in" in err[0]


def test_timestamp_and_integer_columns_are_cast_by_their_methods(tmp_path):
    """The time and value columns are cast by the columns' own methods (pyarrow then imports
    its compute module at a replay only, not at every start): a timestamp column in ms with a
    time zone gives seconds since the epoch, integers and booleans floats, a missing time
    stamp the one-line error naming its row."""
    from uwcosim.scenario import replay

    ms = np.array([1_700_000_000_000, 1_700_000_000_500, 1_700_000_001_000])
    table = pa.table({"time": pa.array(ms, pa.timestamp("ms", tz="UTC")),
                      "n": pa.array([1, 2, 3], pa.int32()),
                      "ok": pa.array([True, False, True])})
    spec = replay.ReplaySpec(file="x.parquet", measurements={})
    t = replay._time(table, spec, "s.toml", tmp_path / "x.parquet")
    np.testing.assert_array_equal(t, ms / 1e3)
    n = replay._floats(table, "n", "replay.measurements.n", "s.toml", tmp_path)
    assert n.dtype == float and n.tolist() == [1.0, 2.0, 3.0]
    ok = replay._floats(table, "ok", "k", "s.toml", tmp_path, allow_bool=True)
    assert ok.tolist() == [1.0, 0.0, 1.0]
    holed = pa.table({"time": pa.array([int(ms[0]), None, int(ms[2])], pa.timestamp("ms"))})
    with pytest.raises(ScenarioError, match="no time at data row 2"):
        replay._time(holed, spec, "s.toml", tmp_path / "x.parquet")
