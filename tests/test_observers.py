"""The master's observers: the one notification point, its order, and the run layer's estimator
bank and log recorder on a system built in code (no scenario)."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.filters.policies import POLICIES
from uwcosim.master import FMU, Callback, Control, Master, Sensor, System
from uwcosim.models.tan import tan_model
from uwcosim.run.bank import EstimatorBank, EstimatorPlan
from uwcosim.run.divergence import DivergenceCheck
from uwcosim.run.recorder import LogRecorder, logged_signals
from uwcosim.runlog import RunLogger, columns, read_log
from uwcosim.runlog.columns import LogLayout


def _system(project_fmus, duration=20.0):
    return System(
        fmus={"vehicle": FMU(project_fmus / "AUVKinematics.fmu",
                             start={"x": 100.0, "y": 200.0, "vx": 1.0}),
              "dvl": FMU(project_fmus / "DVL.fmu")},
        connections=[("vehicle.vx", "dvl.vx"), ("vehicle.vy", "dvl.vy")],
        controls={"psi": Control(target="vehicle.psi", table=[[0, 0.0], [20, 0.5]]),
                  "a": Control(target="vehicle.a", table=[[0, 0.0]])},
        sensors={"dvl": Sensor(outputs=["dvl.vx_m", "dvl.vy_m"], sigma=[0.05, 0.05])},
        step=1.0, duration=duration)


def test_observers_are_called_at_the_start_and_after_every_step_in_order(project_fmus):
    m = Master(_system(project_fmus, duration=5.0), seed=2)
    calls = []
    try:
        m.observers += [Callback(lambda k, v: calls.append(("a", k, v.t))),
                        Callback(lambda k, v: calls.append(("b", k, v.t)))]
        m.initialize()
        m.run_until(5.0)
    finally:
        m.close()
    assert calls == [(name, k, float(k)) for k in range(6) for name in "ab"]


def test_the_view_is_read_only(project_fmus):
    m = Master(_system(project_fmus, duration=2.0), seed=2)
    seen = []

    def poke(k, view):
        seen.append(view.signal("vehicle.x"))
        with pytest.raises(ValueError, match="read-only"):
            view.bus[0] = 1.0
        with pytest.raises(TypeError):
            view.slots["new"] = 0  # a mapping proxy

    try:
        m.observers.append(Callback(poke))
        m.initialize()
        m.run_until(2.0)
    finally:
        m.close()
    assert seen[0] == 100.0 and len(seen) == 3


def test_bank_and_recorder_on_a_plain_system(project_fmus, tmp_path):
    """The run layer's estimator bank and log recorder need no scenario: an EKF on the DVL of
    a system built in code, its estimates logged row by row with the truth."""
    m = Master(_system(project_fmus), seed=4)
    model = tan_model([1e-6] * 4, [0.05, 0.05], measurement_names=("dvl.vx_m", "dvl.vy_m"))
    truth = [m.slot(f"vehicle.{s}", "truth") for s in ("x", "y", "vx", "vy")]
    plan = EstimatorPlan("ekf", "ekf", {}, "skip", np.ones(2, dtype=bool), np.full(4, 1.0))
    assert "skip" in POLICIES
    bank = EstimatorBank(model, [plan], truth_slots=truth,
                         control_slots=[m.slots["controls.psi"], m.slots["controls.a"]],
                         seed=4, where="system", check=DivergenceCheck((0, 1)), block=8)
    signals = logged_signals(m.slots, ["vehicle.*"])
    layout = LogLayout(tuple(signals), tuple(m.sensors.names), ("ekf",), model.state_names)
    logger = RunLogger(tmp_path / "log.parquet", layout.columns, layout.flags, {}, chunk=7)
    recorder = LogRecorder(layout, logger, [m.slots[s] for s in signals])
    bank.sink = recorder.estimates
    try:
        m.observers += [bank, recorder]
        m.initialize()
        m.run_until(20.0)
        bank.flush()
        recorder.flush()
    finally:
        logger.close()
        m.close()
    cols, _ = read_log(tmp_path / "log.parquet")
    assert cols["time"].tolist() == [float(k) for k in range(21)]
    x = cols[columns.estimate("ekf", "x")]
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(cols[columns.nees("ekf")][1:]))
    # the estimate follows the truth (the DVL makes the velocity known: the position drifts
    # only by the initial error and the integrated measurement noise)
    y = cols[columns.estimate("ekf", "y")]
    err = np.hypot(x - cols["vehicle.x"], y - cols["vehicle.y"])
    assert err[-1] < 10.0
    assert cols[columns.received("dvl.vx_m")][1:].all()  # every step after the start
    assert np.all(np.isfinite(cols[columns.measurement("dvl.vx_m")][1:]))
