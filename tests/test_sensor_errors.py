"""Sensor errors as sensors have them (issue 25, section 3): the DVL's bias and scale-factor
random walks and bottom-lock dropouts, the sounder's outliers and multipath returns, all off by
default (the default outputs are eq. 55's, bit for bit), and a sensor's ``valid`` output."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import read_model_description

from uwcosim.master.measurement import SensorBank
from uwcosim.master.system import Sensor

try:
    from fmu_fixtures import CS, Instance, fmu_path
except ImportError:  # run from the repository root
    from tests.fmu_fixtures import CS, Instance, fmu_path


@pytest.fixture
def fmu_dir(project_fmus):
    return project_fmus


def _sounder(fmu_dir, **start) -> Instance:
    inst = Instance(fmu_path(fmu_dir, "DepthSounder"), CS)
    inst.init(**start)
    return inst


def test_dvl_default_output_is_eq55_bit_for_bit(fmu_dir):
    inst = Instance(fmu_path(fmu_dir, "DVL"), CS)
    inst.init()
    rng = np.random.default_rng(3)
    for k in range(50):
        vx, vy, ex, ey = rng.normal(size=4)
        inst.set(vx=vx, vy=vy, e_vx=ex, e_vy=ey, altitude=1e4 * rng.random())
        assert inst.get("vx_m", "vy_m", "bottom_lock") == [vx + ex, vy + ey, 1.0]
        inst.step(1.0 * k, 1.0)
    inst.free()


def test_dvl_bias_and_scale_random_walks(fmu_dir):
    inst = Instance(fmu_path(fmu_dir, "DVL"), CS)
    inst.init()
    h, w = 2.0, [0.01, -0.02, 0.001]  # held white noise: each step adds h*w to the states
    for k in range(5):
        inst.set(vx=1.5, vy=-0.5, w_bvx=w[0], w_bvy=w[1], w_scale=w[2])
        inst.step(h * k, h)
    b_vx, b_vy, s = inst.get("b_vx", "b_vy", "scale")
    assert [b_vx, b_vy, s] == pytest.approx([5 * h * w[0], 5 * h * w[1], 5 * h * w[2]])
    assert inst.get("vx_m", "vy_m") == pytest.approx([(1 + s) * 1.5 + b_vx,
                                                      (1 + s) * -0.5 + b_vy])
    inst.free()


def test_dvl_loses_bottom_lock_above_max_altitude(fmu_dir):
    inst = Instance(fmu_path(fmu_dir, "DVL"), CS)
    inst.init(maxAltitude=200.0)
    out = []
    for k, alt in enumerate([50.0, 199.0, 200.0, 201.0, 900.0, 150.0]):
        inst.set(altitude=alt)
        out.append(inst.get("bottom_lock")[0])
        inst.step(1.0 * k, 1.0)
    assert out == [1.0, 1.0, 1.0, 0.0, 0.0, 1.0]
    inst.free()


def test_sounder_default_output_is_eq55_bit_for_bit(fmu_dir):
    inst = _sounder(fmu_dir)
    rng = np.random.default_rng(4)
    ref = _sounder(fmu_dir)
    for k in range(50):
        x, y = rng.uniform(0, 25_000, size=2)
        e, u, eo = rng.normal(size=3)
        inst.set(x=x, y=y, e_h=e, u_o=u, e_o=eo)
        ref.set(x=x, y=y, e_h=0.0)
        h = ref.get("depth_m")[0]
        assert inst.get("depth_m") == [h + e]  # exactly h_d(x, y) + e_h
        assert inst.get("altitude") == [h]
        inst.step(1.0 * k, 1.0)
        ref.step(1.0 * k, 1.0)
    inst.free()
    ref.free()


def test_sounder_outliers_multipath_and_offset(fmu_dir):
    p_out, p_mp = 0.05, 0.02
    inst = _sounder(fmu_dir, outlierProb=p_out, outlierStd=30.0, multipathProb=p_mp)
    ref = _sounder(fmu_dir)
    x, y = 12_000.0, 9_000.0
    ref.set(x=x, y=y)
    h = ref.get("depth_m")[0]
    phi = lambda u: 0.5 * (1 + math.erf(u / math.sqrt(2)))  # noqa: E731
    cases = {-2.0: h + 0.5 + 0.25 + 30.0 * 1.5,  # Phi(-2) = 0.023 < 0.05: outlier
             -1.6: 2 * h + 0.5 + 0.25,  # 0.05 <= Phi(-1.6) = 0.055 < 0.07: multipath
             0.3: h + 0.5 + 0.25}  # neither
    assert phi(-2.0) < p_out <= phi(-1.6) < p_out + p_mp <= phi(0.3)
    for u, expected in cases.items():
        inst.set(x=x, y=y, e_h=0.5, offset_h=0.25, u_o=u, e_o=1.5)
        assert inst.get("depth_m")[0] == pytest.approx(expected, rel=1e-12)
    inst.free()
    ref.free()


def test_new_inputs_are_in_the_model_descriptions(fmu_dir):
    md = read_model_description(str(fmu_path(fmu_dir, "DepthSounder")))
    names = {v.name: v for v in md.modelVariables}
    for n in ("offset_h", "u_o", "e_o", "outlierProb", "multipathProb", "altitude"):
        assert n in names
    md = read_model_description(str(fmu_path(fmu_dir, "DVL")))
    names = {v.name for v in md.modelVariables}
    assert {"b_vx", "scale", "w_bvx", "maxAltitude", "bottom_lock"} <= names


def test_a_sensor_with_a_valid_output_is_not_received_when_it_is_zero():
    sensors = {"dvl": Sensor(outputs=["dvl.vx_m"], valid="dvl.bottom_lock"),
               "depth": Sensor(outputs=["sounder.depth_m"])}
    bank = SensorBank(sensors, {"dvl": np.array([0]), "depth": np.array([1])},
                      {"dvl": [], "depth": []}, ["dvl", "depth"], seed=1, n=5,
                      valid_slots={"dvl": 2})
    bus = np.array([0.7, 1000.0, 1.0])
    m = bank.measure(1, 1.0, bus)
    assert m.received.tolist() == [True, True] and m.z.tolist() == [0.7, 1000.0]
    bus[2] = 0.0
    m = bank.measure(2, 2.0, bus)
    assert m.received.tolist() == [False, True] and math.isnan(m.z[0])


def test_a_run_with_dvl_drift_and_bottom_lock(tan, tmp_path):
    """The documented set-up (docs/sensor_errors_and_truth_map.md): the bias walks, the DVL
    samples above maxAltitude are not received, the estimators skip them."""
    import pyarrow.parquet as pq

    from uwcosim.run.simulate import simulate

    conns = ('connections=[["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"], '
             '["vehicle.x", "sounder.x"], ["vehicle.y", "sounder.y"], '
             '["sounder.altitude", "dvl.altitude"]]')
    from uwcosim.run.factory import scenario_map

    # a threshold between the depths at the start and 20 m east (the track's first 40 s)
    h0, h1 = scenario_map(tan()).depth(np.array([2000.0, 2020.0]), np.array([18000.0] * 2))
    thr = float(0.5 * (h0 + h1))
    loaded = tan([conns, "run.duration=40", f"fmus.dvl.start={{maxAltitude={thr!r}}}",
                  "sensors.dvl.valid='dvl.bottom_lock'",
                  "sensors.dvl_drift={outputs=['dvl.bottom_lock'], "
                  "noise_inputs=['dvl.w_bvx', 'dvl.w_bvy', 'dvl.w_scale'], "
                  "sigma=[1e-3, 1e-3, 1e-4]}",
                  "log.signals=['vehicle.*', 'dvl.*', 'sounder.*']",
                  "estimators={ekf={type='ekf'}}"])
    out = simulate(loaded, tmp_path / "run", evaluate=False)
    table = pq.read_table(out / "log.parquet")
    log = {n: table.column(n).to_numpy() for n in table.column_names}
    lock = log["dvl.bottom_lock"]
    assert np.array_equal(lock, (log["sounder.altitude"] <= thr).astype(float))
    assert 0 < lock.sum() < lock.size
    assert np.array_equal(log["z.dvl.vx_m.received"][1:], lock[1:] == 1.0)
    assert np.all(np.isnan(log["z.dvl.vx_m"][1:][lock[1:] == 0.0]))
    assert np.all(np.diff(log["dvl.b_vx"]) != 0)  # a random walk
