"""The master: FMI 2.0/3.0 x CS/ME, multi-rate sensors, hooks, timing and determinism."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SCENARIOS
from uwcosim.api import run_scenario
from uwcosim.master.master import Master
from uwcosim.master.observer import Callback
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.runlog import read_log
from uwcosim.scenario import to_system

VARIANTS = [
    pytest.param("AUVKinematics_fmi2.fmu", "cs", id="fmi2-cs"),
    pytest.param("AUVKinematics_fmi2.fmu", "me", id="fmi2-me"),
    pytest.param("AUVKinematics.fmu", "cs", id="fmi3-cs"),
    pytest.param("AUVKinematics.fmu", "me", id="fmi3-me"),
]
QUIET = ["noise.process.psd=[0.0, 0.0, 0.0, 0.0]", "estimators={}", "run.duration=60"]


def closed_form(t, x0, v0, psi, a):
    """Eq. (54) with constant psi and a: velocity linear, position quadratic in time."""
    c, s = np.cos(psi), np.sin(psi)
    vx = v0[0] + a * c * t
    vy = v0[1] + a * s * t
    px = v0[0] * t + 0.5 * a * c * t**2
    py = v0[1] * t + 0.5 * a * s * t**2
    return x0[0] + c * px - s * py, x0[1] + c * py + s * px, vx, vy


@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    return str(synthetic_bathymetry(7).write_coefficients(tmp_path_factory.mktemp("m") / "m.bin"))


def _run(loaded, map_file, until=None):
    m = Master(to_system(loaded))
    rows = []
    m.observers.append(Callback(lambda k, v: k and rows.append(
        (v.t, *(v.signal(f"vehicle.{s}") for s in ("x", "y", "vx", "vy"))))))
    m.initialize({"sounder": {"mapFile": map_file}})
    m.run_until(until if until is not None else 1e9)
    m.close()
    return m, np.array(rows)


@pytest.mark.parametrize(("fmu", "interface"), VARIANTS)
def test_vehicle_variants_match_closed_form(tan, map_file, fmu, interface):
    loaded = tan([*QUIET, f'fmus.vehicle.path="../fmus/{fmu}"',
                  f'fmus.vehicle.interface="{interface}"',
                  "controls.psi.table=[[0, 0.3]]", "controls.a.table=[[0, 0.002]]"])
    m, rows = _run(loaded, map_file)
    assert m.k == 60 and rows.shape == (60, 5)
    x, y, vx, vy = closed_form(rows[:, 0], (2000.0, 18000.0), (0.5, 0.0), 0.3, 0.002)
    # RK4 is exact for a quadratic: agreement to rounding on positions of order 1e4 m
    np.testing.assert_allclose(rows[:, 1], x, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rows[:, 2], y, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rows[:, 3], vx, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[:, 4], vy, rtol=0, atol=1e-12)


@pytest.mark.parametrize("fmi", ["", "_fmi2"], ids=["fmi3", "fmi2"])
def test_all_fmus_in_model_exchange(tan, map_file, fmi):
    over = [*QUIET]
    for name, stem in (("vehicle", "AUVKinematics"), ("dvl", "DVL"), ("sounder", "DepthSounder")):
        over += [f'fmus.{name}.path="../fmus/{stem}{fmi}.fmu"', f'fmus.{name}.interface="me"']
    _, me = _run(tan(over), map_file)
    _, cs = _run(tan(QUIET), map_file)
    np.testing.assert_allclose(me, cs, rtol=0, atol=1e-8)


def test_me_continuous_controls_and_adaptive_solver(tan, map_file):
    """ME integration sees the heading ramp at stage times; RK4 and DOP853 agree."""
    base = [*QUIET, "controls.psi.table=[[0, 0.0], [60, 0.6]]",
            'fmus.vehicle.interface="me"', "fmus.vehicle.substeps=4"]
    _, rk4 = _run(tan(base), map_file)
    _, dop = _run(tan([*base, 'fmus.vehicle.solver="adaptive"', "fmus.vehicle.rtol=1e-10"]),
                  map_file)
    np.testing.assert_allclose(rk4[:, 1:3], dop[:, 1:3], rtol=0, atol=1e-6)
    _, cs = _run(tan(base[:-2]), map_file)
    # the CS FMU holds the heading over each step: a visibly different path
    assert np.max(np.abs(cs[:, 2] - rk4[:, 2])) > 1e-3


def test_multi_rate_sensor_and_step_api(tan, map_file):
    loaded = tan([*QUIET, "sensors.depth.period=3", "fmus.sounder.period=3"])
    m = Master(to_system(loaded))
    m.initialize({"sounder": {"mapFile": map_file}})
    seen = []
    m.observers.append(Callback(lambda k, v: seen.append((k, v.signal("sounder.depth_m")))))
    m.step()
    m.step()
    assert m.k == 2 and m.t == pytest.approx(2.0)
    m.run_until(9.0)
    m.close()
    j = m.sensors.names.index("sounder.depth_m")
    rec = [m.sensors.received(k)[j] for k in range(10)]
    assert list(np.flatnonzero(rec)) == [3, 6, 9]
    depth = dict(seen)
    # the sounder is stepped every 3 steps: its output holds in between
    assert depth[4] == depth[5] == depth[3] and depth[6] != depth[5]


def test_waypoint_heading_steers_to_the_waypoint(tan, map_file):
    loaded = tan([*QUIET, "run.duration=2000",
                  "controls.psi={target=\"vehicle.psi\", waypoints=[[2300.0, 18400.0]]}"])
    _, rows = _run(loaded, map_file)
    d = np.hypot(rows[:, 1] - 2300.0, rows[:, 2] - 18400.0)
    assert d.min() < 60.0


def test_same_seed_same_log_bytes(tan, tmp_path):
    over = ["run.duration=200"]
    a = run_scenario(tan(over), tmp_path / "a", figures=False)
    b = run_scenario(tan(over), tmp_path / "b", figures=False)
    c = run_scenario(tan(over), tmp_path / "c", seed=99, figures=False)
    assert (tmp_path / "a/log.parquet").read_bytes() == (tmp_path / "b/log.parquet").read_bytes()
    ca, meta = read_log(a.log_path)
    cc, _ = read_log(c.log_path)
    assert not np.array_equal(ca["vehicle.x"], cc["vehicle.x"])
    assert meta["seed"] == 1 and len(meta["scenario_sha256"]) == 64
    assert set(meta["fmus"]) == {"vehicle", "dvl", "sounder"}
    assert {"fmpy", "numpy", "casadi"} <= set(meta["versions"])
    assert b.summary["estimators"] == a.summary["estimators"] or _same_but_timing(a, b)


def _same_but_timing(a, b) -> bool:
    strip = {"time_per_step_s", "time_per_step_p95_s", "total_time_s"}
    return all({k: v for k, v in a.summary["estimators"][n].items() if k not in strip}
               == {k: v for k, v in b.summary["estimators"][n].items() if k not in strip}
               for n in a.summary["estimators"])


def test_summary_and_timing(tan, tmp_path):
    res = run_scenario(tan(["run.duration=300"]), tmp_path, figures=True)
    s = res.summary
    assert s["status"] == "ok" and s["steps"] == 300
    for name in ("dead_reckoning", "ekf"):
        m = s["estimators"][name]
        for key in ("rmse_position_m", "rmse_velocity_mps", "anees", "time_per_step_s"):
            assert np.isfinite(m[key]), key
    assert s["estimators"]["ekf"]["rmse_position_m"] < s["estimators"]["dead_reckoning"][
        "rmse_position_m"]
    assert {"fmu.vehicle_s", "fmu.dvl_s", "fmu.sounder_s", "master_s"} <= set(s["timing"])
    for f in ("trajectory.png", "position_error.png", "report.md", "summary.json"):
        assert (tmp_path / f).is_file()
    assert (f"uwcosim run {SCENARIOS / 'tan_terrain.toml'} --seed 1 --set run.duration=300"
            in (tmp_path / "report.md").read_text())


def test_lost_measurement_scenario_through_the_cv_fmu(project_fmus, tmp_path):
    from uwcosim.scenario import load_scenario

    loaded = load_scenario(Path(__file__).resolve().parents[1] / "scenarios"
                           / "lost_measurements.toml", ["run.duration=300"])
    res = run_scenario(loaded, tmp_path, figures=False)
    est = res.summary["estimators"]
    cols, _ = read_log(res.log_path)
    rec = cols["z.cv.px.received"][1:]
    # Bernoulli loss with a = 0.3 over 300 steps: 3.4 binomial sd is about 0.09
    assert abs((~rec).mean() - 0.3) < 0.09
    assert np.isnan(cols["z.cv.px"][1:][~rec]).all()
    # the standard KF skipping lost measurements beats the KF fed zeros (seed 001 eq. 2)
    assert est["kf_skip"]["rmse_position_m"] < 0.1 * est["kf_zero"]["rmse_position_m"]
    assert 0.5 < est["kf_skip"]["anees"] < 1.5


def test_reused_master_gives_the_same_log_as_a_fresh_one(tan, tmp_path):
    """Campaign workers reset FMU instances between runs instead of instantiating again."""
    loaded = tan(["run.duration=100"])
    m = Master(to_system(loaded))
    try:
        run_scenario(loaded, tmp_path / "r1", seed=5, figures=False, master=m)
        first = m.adapters["vehicle"].instance.fmu
        run_scenario(loaded, tmp_path / "r2", seed=6, figures=False, master=m)
        assert m.adapters["vehicle"].instance.fmu is first  # the same instance, reset
    finally:
        m.close()
    run_scenario(loaded, tmp_path / "fresh", seed=6, figures=False)
    assert ((tmp_path / "r2/log.parquet").read_bytes()
            == (tmp_path / "fresh/log.parquet").read_bytes())
