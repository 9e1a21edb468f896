"""The event test FMUs (tests/data/event_fmus) checked with fmpy against closed forms.

These tests prove the FMUs right (FMI 2.0 and 3.0, co-simulation and model exchange, run by
``fmpy.simulate_fmu``), so the master's tests can compare against fmpy on them.
"""

from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

try:
    from event_fmus import (
        MODELS,
        VERSIONS,
        ball_exact,
        declared_start_values,
        event_fmu,
        event_fmus,
        typed_expected,
    )
except ImportError:  # tests/ imported as a package
    from tests.event_fmus import (
        MODELS,
        VERSIONS,
        ball_exact,
        declared_start_values,
        event_fmu,
        event_fmus,
        typed_expected,
    )

__all__ = ["event_fmus"]  # fixture

BOTH = [(v, i) for v in VERSIONS for i in ("CoSimulation", "ModelExchange")]


def _ids(params):
    return [f"fmi{v[0]}-{'cs' if i == 'CoSimulation' else 'me'}" for v, i in params]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("version", VERSIONS)
def test_fmus_are_valid(event_fmus, model, version):
    path = event_fmus[(model, version)]
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path), validate=True)
    assert md.fmiVersion == version
    assert md.coSimulation.modelIdentifier == model == md.modelExchange.modelIdentifier
    assert md.defaultExperiment is not None and float(md.defaultExperiment.stopTime) > 0
    assert event_fmu(model, version) == path


def _instantiate(path, fmi_type, tmp_path, messages=None):
    """An fmpy instance of an event FMU whose log messages go to ``messages``.

    FMI 2 without fmpy's logger proxy: the proxy keeps one process-wide logger, which crashes
    later FMI 2 instances once this callback is gone (as uwcosim's adapter does)."""
    from fmpy import fmi2, fmi3

    md = fmpy.read_model_description(str(path))
    unzipdir = fmpy.extract(str(path), str(tmp_path / "fmu"))
    messages = [] if messages is None else messages
    cs = fmi_type == "CoSimulation"
    args = dict(guid=md.guid, unzipDirectory=unzipdir,
                modelIdentifier=md.coSimulation.modelIdentifier)
    if md.fmiVersion == "2.0":
        def log2(env, name, status, category, message):
            messages.append(message.decode())

        cb = fmi2.fmi2CallbackFunctions()
        cb.logger = fmi2.fmi2CallbackLoggerTYPE(log2)
        cb.allocateMemory = fmi2.fmi2CallbackAllocateMemoryTYPE(fmi2.calloc)
        cb.freeMemory = fmi2.fmi2CallbackFreeMemoryTYPE(fmi2.free)
        fmu = (fmi2.FMU2Slave if cs else fmi2.FMU2Model)(**args)
        fmu.instantiate(callbacks=cb)  # fmu.callbacks keeps cb alive
    else:
        def log3(env, status, category, message):
            messages.append(message.decode())

        fmu = (fmi3.FMU3Slave if cs else fmi3.FMU3Model)(**args)
        fmu.instantiate(logMessage=log3)
    return md, fmu


# ---- BouncingBall ---------------------------------------------------------------------------


def _simulate(path, fmi_type, **kw):
    return fmpy.simulate_fmu(str(path), fmi_type=fmi_type, **kw)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("start", [{}, {"h": 2.0, "e": 0.5, "g": 3.7}], ids=["default", "set"])
def test_ball_me_bounce_times_match_the_closed_form(event_fmus, version, start):
    path = event_fmus[("BouncingBall", version)]
    r = _simulate(path, "ModelExchange", stop_time=3.0, output_interval=1e-3,
                  relative_tolerance=1e-10, start_values=start)
    p = {"h0": start.get("h", 1.0), "e": start.get("e", 0.7), "g": start.get("g", 9.81)}
    h, v, k, t_b = ball_exact(r["time"], **p)
    n = int(np.sum(t_b <= 3.0))
    # the time of the first row with bounces == j is the j-th bounce
    seen = np.array([r["time"][np.argmax(r["bounces"] >= j)] for j in range(1, n + 1)])
    assert r["bounces"][-1] == n
    np.testing.assert_allclose(seen, t_b[:n], rtol=0, atol=1e-6)
    np.testing.assert_allclose(seen[0], math.sqrt(2 * p["h0"] / p["g"]), rtol=0, atol=1e-6)
    np.testing.assert_allclose(r["h"], h, rtol=0, atol=1e-6)
    assert r["h"].min() > -1e-8  # never through the floor
    away = np.min(np.abs(r["time"][:, None] - t_b[None, :]), axis=1) > 1e-6
    np.testing.assert_allclose(r["v"][away], v[away], rtol=0, atol=1e-5)
    np.testing.assert_array_equal(r["bounces"][away], k[away])


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("step", [0.01, 0.1])
def test_ball_cs_locates_bounces_inside_the_steps(event_fmus, version, step):
    path = event_fmus[("BouncingBall", version)]
    r = _simulate(path, "CoSimulation", stop_time=3.0, output_interval=step)
    h, v, k, _ = ball_exact(r["time"])
    # RK4 is exact for the parabolas and bisection locates each bounce to 1e-13 s
    np.testing.assert_allclose(r["h"], h, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["v"], v, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(r["bounces"], k)
    assert r["bounces"][-1] == 11 and r["h"][-1] == 0.0 and r["v"][-1] == 0.0


# ---- Stair ----------------------------------------------------------------------------------


def _first_times(t, values, levels):
    """Time of the first row where ``values`` reaches each level."""
    return np.array([t[np.argmax(values >= lev)] for lev in levels])


@pytest.mark.parametrize("version,fmi_type", BOTH, ids=_ids(BOTH))
@pytest.mark.parametrize("period", [1.0, 0.25])
def test_stair_counts_time_events(event_fmus, version, fmi_type, period):
    path = event_fmus[("Stair", version)]
    r = _simulate(path, fmi_type, stop_time=10.0, output_interval=0.1,
                  start_values={"period": period}, output=["counter", "even"])
    t, n = r["time"], r["counter"]
    ticks = np.arange(1, int(round(10.0 / period)) + 1) * period
    assert n[0] == 1 and n[-1] == 1 + len(ticks)
    away = np.min(np.abs(t[:, None] - ticks[None, :]), axis=1) > 1e-9
    np.testing.assert_array_equal(n[away], 1 + np.floor(t[away] / period))
    # the value after the tick at every tick time on the output grid (the last row at that time)
    on_grid = [tk for tk in ticks if np.isclose(t, tk, rtol=0, atol=1e-9).any()]
    assert len(on_grid) >= len(ticks) // 2
    for tk in on_grid:
        last = np.flatnonzero(np.isclose(t, tk, rtol=0, atol=1e-9))[-1]
        assert n[last] == 1 + round(tk / period)
    np.testing.assert_array_equal(r["even"], n % 2 == 0)  # fmpy iterates the update
    if fmi_type == "ModelExchange":  # the events themselves are rows, at exactly k*period
        np.testing.assert_allclose(_first_times(t, n, 2 + np.arange(len(ticks))), ticks,
                                   rtol=0, atol=1e-12)


@pytest.mark.parametrize("version,fmi_type", BOTH, ids=_ids(BOTH))
@pytest.mark.parametrize("t_terminate", [2.5, 2.55])
def test_stair_requests_termination(event_fmus, version, fmi_type, t_terminate):
    path = event_fmus[("Stair", version)]
    r = _simulate(path, fmi_type, stop_time=10.0, output_interval=0.1,
                  start_values={"t_terminate": t_terminate}, early_return_allowed=True,
                  output=["counter", "even"])
    # fmpy stops at the request, with the counter of that time
    assert r["time"][-1] == pytest.approx(t_terminate, abs=1e-12)
    assert r["counter"][-1] == 3 and not r["even"][-1]
    assert np.all(r["time"] <= t_terminate + 1e-12)


@pytest.mark.parametrize("version", VERSIONS)
def test_stair_cs_without_early_return_reports_the_termination_time(event_fmus, version,
                                                                     tmp_path):
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import fmi2Discard, fmi2LastSuccessfulTime, fmi2Terminated

    md, fmu = _instantiate(event_fmus[("Stair", version)], "CoSimulation", tmp_path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    if version == "2.0":
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([vr["t_terminate"]], [0.55])
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.doStep(0.0, 0.5)
        with pytest.raises(FMICallException) as err:
            fmu.doStep(0.5, 0.5)
        assert err.value.status == fmi2Discard
        assert fmu.getBooleanStatus(fmi2Terminated)
        assert fmu.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(0.55, abs=1e-12)
    else:
        fmu.setFloat64([vr["t_terminate"]], [0.55])
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        assert fmu.doStep(0.0, 0.5) == (False, False, False, 0.5)
        _, terminate, early, last = fmu.doStep(0.5, 0.5)
        assert terminate and not early  # early return was not allowed
        assert last == pytest.approx(0.55, abs=1e-12)
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("version", VERSIONS)
def test_stair_me_needs_a_second_update_pass_at_a_tick(event_fmus, version, tmp_path):
    _, fmu = _instantiate(event_fmus[("Stair", version)], "ModelExchange", tmp_path)
    v2 = version == "2.0"
    update = fmu.newDiscreteStates if v2 else fmu.updateDiscreteStates
    get_int = fmu.getInteger if v2 else fmu.getInt32
    if v2:
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([3], [2.0])  # t_terminate
        fmu.enterInitializationMode()
    else:
        fmu.setFloat64([3], [2.0])
        fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    assert update() == (False, False, False, False, True, 1.0)
    for t, counter in ((1.0, 2), (2.0, 3)):
        fmu.enterContinuousTimeMode()
        fmu.setTime(t)
        fmu.enterEventMode()
        needed, terminate, _, _, _, _ = update()
        # first pass: the counter ticks, even still describes the previous counter
        assert needed and not terminate
        assert get_int([1]) == [counter] and fmu.getBoolean([4]) == [counter % 2 == 1]
        needed, terminate, _, _, defined, t_next = update()
        assert not needed and fmu.getBoolean([4]) == [counter % 2 == 0]
        assert terminate == (t == 2.0)
        assert (defined, t_next) == ((True, 2.0) if t == 1.0 else (False, 0.0))
    fmu.terminate()
    fmu.freeInstance()


# ---- Feedthrough ----------------------------------------------------------------------------


def _feedthrough_input():
    # u = t (continuous ramp), iu steps 0 -> 3 at 0.5 s, bu false -> true at 1.2 s
    t = np.array([0.0, 0.5, 0.5, 1.2, 1.2, 2.0])
    sig = np.zeros(len(t), dtype=[("time", np.float64), ("u", np.float64), ("iu", np.int32),
                                  ("bu", np.bool_)])
    sig["time"], sig["u"] = t, t
    sig["iu"] = [0, 0, 3, 3, 3, 3]
    sig["bu"] = [False, False, False, False, True, True]
    return sig


@pytest.mark.parametrize("version,fmi_type", BOTH, ids=_ids(BOTH))
def test_feedthrough_outputs_equal_the_inputs(event_fmus, version, fmi_type):
    path = event_fmus[("Feedthrough", version)]
    r = _simulate(path, fmi_type, stop_time=2.0, output_interval=0.1, input=_feedthrough_input(),
                  start_values={"k": -1.5}, output=["y", "yk", "iy", "by"])
    t = r["time"]
    if fmi_type == "ModelExchange":
        # fmpy sets the inputs at every output time before reading the outputs
        t_in = t
        np.testing.assert_allclose(r["y"], t, rtol=0, atol=1e-12)
    else:
        # co-simulation: the outputs after a step see the inputs set at its start
        t_in = np.concatenate([[0.0], t[:-1]])
        np.testing.assert_allclose(r["y"], t_in, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r["yk"], -1.5 * r["y"], rtol=0, atol=1e-12)
    away = (np.abs(t_in - 0.5) > 1e-9) & (np.abs(t_in - 1.2) > 1e-9)
    np.testing.assert_array_equal(r["iy"][away], np.where(t_in[away] > 0.5, 3, 0))
    np.testing.assert_array_equal(r["by"][away], t_in[away] > 1.2)
    assert r["iy"][-1] == 3 and r["by"][-1]


@pytest.mark.parametrize("version", VERSIONS)
def test_discrete_inputs_are_refused_in_continuous_time_mode(event_fmus, version, tmp_path):
    from fmpy.fmi1 import FMICallException

    messages = []
    _, fmu = _instantiate(event_fmus[("Feedthrough", version)], "ModelExchange", tmp_path,
                          messages)
    v2 = version == "2.0"
    set_int = fmu.setInteger if v2 else fmu.setInt32
    get_int = fmu.getInteger if v2 else fmu.getInt32
    set_real = fmu.setReal if v2 else fmu.setFloat64
    get_real = fmu.getReal if v2 else fmu.getFloat64
    update = fmu.newDiscreteStates if v2 else fmu.updateDiscreteStates
    if v2:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    else:
        fmu.enterInitializationMode(startTime=0.0)
    set_int([3], [5])  # initialization mode: allowed
    fmu.exitInitializationMode()
    set_int([3], [6])  # event mode: allowed
    update()
    fmu.enterContinuousTimeMode()
    set_real([1], [1.5])  # a continuous input: allowed
    with pytest.raises(FMICallException):
        set_int([3], [7])
    assert "'iu'" in messages[-1]
    assert "can only be set in initialization mode or event mode" in messages[-1]
    with pytest.raises(FMICallException):
        fmu.setBoolean([5], [True])
    assert "'bu'" in messages[-1]
    with pytest.raises(FMICallException):
        set_real([7], [3.0])  # a fixed parameter after initialization
    assert get_int([4]) == [6] and get_real([2]) == [1.5]
    fmu.enterEventMode()
    set_int([3], [7])
    update()
    assert get_int([4]) == [7]
    fmu.terminate()
    fmu.freeInstance()


# ---- TypedBlock -----------------------------------------------------------------------------

TYPED_OUTPUTS = ["f32_out", "i8_out", "u16_out", "i32_out", "i64_out", "u64_out", "b_out",
                 "mode_out", "d_out", "y", "label_len", "gain_sum"]


EDGES = {  # inputs at the ends of their ranges (FMI 2 Integers are 32 bits)
    "2.0": {"f32_in": 0.1, "i8_in": -128, "u16_in": 65535, "i32_in": 2**31 - 1,
            "i64_in": 2**30, "u64_in": 2**31 - 1, "b_in": True, "mode_in": 3, "d_in": -2.0,
            "label": "abcdef", "gains[2]": -0.5},
    "3.0": {"f32_in": 0.1, "i8_in": -128, "u16_in": 65535, "i32_in": 2**31 - 1,
            "i64_in": -(2**62) - 1, "u64_in": 2**64 - 1, "b_in": True, "mode_in": 3,
            "d_in": -2.0, "label": "abcdef", "gains": [0.5, 0.25, 4.0]},
}


@pytest.mark.parametrize("version,fmi_type", BOTH, ids=_ids(BOTH))
@pytest.mark.parametrize("case", ["defaults", "edges"])
def test_typed_block_outputs_are_the_functions_of_the_inputs(event_fmus, version, fmi_type,
                                                              case):
    path = event_fmus[("TypedBlock", version)]
    md = fmpy.read_model_description(str(path))
    values = declared_start_values(md)
    start = EDGES[version] if case == "edges" else {}
    values.update(start)
    r = _simulate(path, fmi_type, stop_time=2.0, output_interval=0.1, output=TYPED_OUTPUTS,
                  start_values={k: np.array(v) if isinstance(v, list) else v
                                for k, v in start.items()})
    expected = typed_expected(version, values)
    for name, value in expected.items():
        got = r[name]
        if isinstance(value, bool | int) and not isinstance(value, np.floating):
            assert all(int(x) == int(value) for x in got), (name, got[:3], value)
        else:
            assert got.dtype == (np.float32 if isinstance(value, np.float32) else np.float64)
            assert np.all(got == value), (name, got[:3], value)
    # y integrates d_in exactly (RK4 / CVode on a constant derivative)
    np.testing.assert_allclose(r["y"], values["d_in"] * r["time"], rtol=0, atol=1e-9)
    if version == "3.0":  # the sized types reach the importer as such
        assert r["u64_out"].dtype == np.uint64 and r["i8_out"].dtype == np.int8
        assert r["f32_out"].dtype == np.float32 and r["u16_out"].dtype == np.uint16


@pytest.mark.parametrize("version,fmi_type", BOTH, ids=_ids(BOTH))
def test_typed_block_discrete_input_changes_at_an_event(event_fmus, version, fmi_type):
    path = event_fmus[("TypedBlock", version)]
    sig = np.array([(0.0, 0.5), (1.0, 0.5), (1.0, -1.0), (2.0, -1.0)],
                   dtype=[("time", np.float64), ("d_in", np.float64)])
    r = _simulate(path, fmi_type, stop_time=2.0, output_interval=0.1, input=sig,
                  output=["y", "d_out"])
    t = r["time"]
    y = np.where(t <= 1.0, 0.5 * t, 0.5 - (t - 1.0))
    np.testing.assert_allclose(r["y"], y, rtol=0, atol=1e-9)
    # model exchange: d_out switches at the event; co-simulation: in the step starting at 1 s
    t_in = t if fmi_type == "ModelExchange" else np.concatenate([[0.0], t[:-1]])
    away = np.abs(t_in - 1.0) > 1e-9
    np.testing.assert_array_equal(r["d_out"][away], np.where(t_in[away] < 1.0, 0.5, -1.0))
    assert r["d_out"][-1] == -1.0


def test_typed_block_fmi3_refuses_a_wrongly_typed_access(event_fmus, tmp_path):
    from fmpy.fmi1 import FMICallException

    messages = []
    _, fmu = _instantiate(event_fmus[("TypedBlock", "3.0")], "CoSimulation", tmp_path, messages)
    with pytest.raises(FMICallException):
        fmu.setFloat64([1], [2.0])  # f32_in is a Float32
    assert "'f32_in'" in messages[-1] and "Float32" in messages[-1]
    fmu.setFloat32([1], [2.0])
    fmu.setFloat64([24], [1.0, 1.0, 1.0])  # the array parameter gains, all 3 elements
    with pytest.raises(FMICallException):
        fmu.setFloat64([24], [1.0])  # not enough values for the array
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    assert fmu.getFloat32([2]) == [4.5] and fmu.getFloat64([23]) == [3.0]
    assert fmu.getInt64([16]) == [2]  # the enumeration through Int64
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("version,fmi_type", BOTH, ids=_ids(BOTH))
def test_typed_block_step_events_wrap_y_around(event_fmus, version, fmi_type):
    path = event_fmus[("TypedBlock", version)]
    md = fmpy.read_model_description(str(path))
    me = md.modelExchange
    assert me.needsCompletedIntegratorStep
    r = _simulate(path, fmi_type, stop_time=2.0, output_interval=0.1, output=["y", "wraps"],
                  start_values={"y_wrap": 0.3})
    # y + wraps * y_wrap is the integral of d_in = 0.5 whenever the wraps happened
    np.testing.assert_allclose(r["y"] + 0.3 * r["wraps"], 0.5 * r["time"], rtol=0, atol=1e-9)
    assert r["wraps"][-1] == 3
    if fmi_type == "CoSimulation":  # handled inside the step, after an internal step of 0.01 s
        assert r["y"].max() < 0.3 + 0.5 * 0.01
    else:  # handled after the integrator step that crossed y_wrap (steps <= 0.1 s here)
        assert r["y"].max() < 0.3 + 0.5 * 0.1
    # recorded after the events: every wrap-around brought y back below y_wrap
    assert np.all(r["y"][np.flatnonzero(np.diff(r["wraps"])) + 1] < 0.3)


@pytest.mark.parametrize("version", VERSIONS)
def test_stair_cs_terminating_in_initialization_reports_it_at_the_first_step(event_fmus, version,
                                                                            tmp_path):
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import fmi2Discard, fmi2LastSuccessfulTime, fmi2Terminated

    messages = []
    _, fmu = _instantiate(event_fmus[("Stair", version)], "CoSimulation", tmp_path, messages)
    if version == "2.0":
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([3], [0.0])  # t_terminate at the start
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        for _ in range(2):  # and again: no progress, same answer
            with pytest.raises(FMICallException) as err:
                fmu.doStep(0.0, 0.5)
            assert err.value.status == fmi2Discard and fmu.getBooleanStatus(fmi2Terminated)
            assert fmu.getRealStatus(fmi2LastSuccessfulTime) == 0.0
    else:
        fmu.setFloat64([3], [0.0])
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        for _ in range(2):
            assert fmu.doStep(0.0, 0.5)[1:] == (True, False, 0.0)
    assert "requested to terminate at t=0" in messages[-1]
    fmu.terminate()
    fmu.freeInstance()
