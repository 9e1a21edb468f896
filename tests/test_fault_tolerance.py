"""Fault tolerance: FMUs in a worker process (``timeout_s``) that hang, fail or crash, and a
run that loses every measurement. (Failing doStep, NaN outputs, diverging filters and broken
archives are in test_faults.py.)"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from uwcosim.api import run_scenario
from uwcosim.core import process
from uwcosim.core.errors import FMUError
from uwcosim.fmi.proxy import ProxyAdapter
from uwcosim.master.master import Master
from uwcosim.master.observer import Callback
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.runlog import read_log
from uwcosim.scenario import to_system

FAULT_CHAIN = [
    'connections=[["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"], '
    '["vehicle.x", "fault.u"], ["fault.y", "sounder.x"], ["vehicle.y", "sounder.y"]]',
    "run.duration=50",
]
TWO = ['estimators={dead_reckoning={type="dead_reckoning"}, ekf={type="ekf"}}']


def _fault(**settings) -> str:
    inner = ", ".join(f"{k}={v}" for k, v in settings.items())
    return f'fmus.fault={{path="../fmus/FaultInjector.fmu", {inner}}}'


def test_a_hanging_fmu_is_given_up_after_its_timeout(tan, tmp_path):
    loaded = tan([*FAULT_CHAIN, *TWO,
                  _fault(timeout_s=1.0, parameters="{hang_time=3.0, hang_seconds=3600.0}")])
    t0 = time.perf_counter()
    with pytest.raises(FMUError) as info:
        run_scenario(loaded, tmp_path, figures=False)
    assert time.perf_counter() - t0 < 30.0  # not the hour the FMU would sleep
    msg = str(info.value)
    assert "FMU 'fault' did not answer doStep within 1 s at t=3" in msg
    assert "log up to t=3 kept" in msg
    cols, _ = read_log(tmp_path / "log.parquet")
    assert cols["time"].tolist() == [0.0, 1.0, 2.0, 3.0]
    assert '"status": "failed"' in (tmp_path / "summary.json").read_text()


def test_an_fmu_error_crosses_the_worker_boundary(tan, tmp_path):
    loaded = tan([*FAULT_CHAIN, *TWO, _fault(timeout_s=5.0, parameters="{fail_time=5.0}")])
    with pytest.raises(FMUError) as info:
        run_scenario(loaded, tmp_path, figures=False)
    msg = str(info.value)
    assert "FMU 'fault'" in msg and "injected failure" in msg and "t=4" in msg
    assert read_log(tmp_path / "log.parquet")[0]["time"].size == 5


def test_a_crashing_worker_is_reported(tan, tmp_path):
    def crash(k, view):
        if k == 5:  # the FMU's worker, the only one of this process
            (worker,) = process.workers()
            os.kill(worker.pid, signal.SIGKILL)

    loaded = tan([*FAULT_CHAIN, *TWO, _fault(timeout_s=5.0)])
    with pytest.raises(FMUError, match=r"FMU 'fault' \(FaultInjector.fmu\): worker process died "
                                       r"during doStep at t=5 \(exit status -9\)"):
        run_scenario(loaded, tmp_path, figures=False, progress=Callback(crash))
    assert read_log(tmp_path / "log.parquet")[0]["time"].size == 6


@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    return str(synthetic_bathymetry(7).write_coefficients(tmp_path_factory.mktemp("m") / "m.bin"))


def _states(loaded, map_file):
    m = Master(to_system(loaded))
    rows = []
    names = ["vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy", "sounder.depth_m"]
    m.observers.append(Callback(lambda k, v: k and rows.append([v.signal(n) for n in names])))
    m.initialize({"sounder": {"mapFile": map_file}})
    kinds = {n: type(a) for n, a in m.adapters.items()}
    m.run_until(1e9)
    m.close()
    return kinds, np.array(rows)


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_a_worker_fmu_gives_the_same_results(tan, map_file, interface):
    """Bit for bit, also for model exchange with table controls at the RK4 stages."""
    base = ["estimators={}", "run.duration=60", f'fmus.vehicle.interface="{interface}"',
            "fmus.vehicle.substeps=2", "controls.psi.table=[[0, 0.0], [60, 0.6]]"]
    kinds, here = _states(tan(base), map_file)
    kinds_w, there = _states(tan([*base, "fmus.vehicle.timeout_s=10",
                                  "fmus.sounder.timeout_s=10"]), map_file)
    assert kinds_w["vehicle"] is ProxyAdapter and kinds["vehicle"] is not ProxyAdapter
    assert np.array_equal(here, there)


def test_losing_every_measurement_for_the_whole_run(tan, tmp_path):
    loaded = tan([*TWO, "run.duration=200", 'sensors.dvl.loss={model="bernoulli", p=1.0}',
                  'sensors.depth.loss={model="bernoulli", p=1.0}'])
    res = run_scenario(loaded, tmp_path, figures=False)
    assert res.status == "ok"
    cols, _ = read_log(res.log_path)
    assert not cols["z.dvl.vx_m.received"].any() and np.isnan(cols["z.dvl.vx_m"]).all()
    for name in ("dead_reckoning", "ekf"):
        m = res.summary["estimators"][name]
        assert not m["diverged"]
        for key in ("rmse_position_m", "rmse_velocity_mps", "anees"):
            assert np.isfinite(m[key]), (name, key)
        x = cols[f"est.{name}.x"]
        var = cols[f"est.{name}.var.x"]
        assert np.isfinite(x).all()
        assert np.all(np.diff(var) > 0)  # prediction only: the uncertainty grows every step
    # without measurements the EKF is dead reckoning
    np.testing.assert_allclose(cols["est.ekf.x"], cols["est.dead_reckoning.x"], rtol=1e-12)
