"""Adapter-level events and termination on the event test FMUs (tests/data/event_fmus).

Model exchange through :class:`FMUAdapter` (CVode with root finding, time events, the event
iteration, discrete inputs in event mode) against ``fmpy.simulate_fmu`` on the same FMU with
the same tolerance and output grid, and against closed forms; termination requests of
co-simulation and model-exchange FMUs reported as ``adapter.terminated``.
"""

from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest

from uwcosim.core.errors import FMUError
from uwcosim.fmi.adapter import FMUAdapter
from uwcosim.fmi.proxy import ProxyAdapter

try:
    from event_fmus import VERSIONS, ball_exact, event_fmus
except ImportError:  # tests/ imported as a package
    from tests.event_fmus import VERSIONS, ball_exact, event_fmus

__all__ = ["event_fmus"]  # fixture

RTOL = 1e-8
BALL_RTOL = 1e-10  # the 11th bounce is 1e-6 s off the closed form at 1e-8 (errors add up)


def run_adapter(path, interface, outputs, stop, h, parameters=None, inputs=(), values=None,
                rtol=RTOL, solver="rk4", cls=FMUAdapter):
    """Step the FMU from 0 to ``stop`` in steps ``h``; rows of outputs at 0, h, 2h, ..."""
    ad = cls("dut", path, interface, solver, 1, rtol)
    b_out, b_in = ad.bind(outputs), ad.bind(list(inputs))
    try:
        ad.instantiate(parameters or {}, {}, 0.0, stop)
        n = int(round(stop / h))
        if values is not None:
            b_in.view[:] = values(0.0)
            ad.set_inputs(b_in, 0.0)
        rows, times = [ad.get_outputs(b_out, 0.0).copy()], [0.0]
        for k in range(n):
            if values is not None:
                b_in.view[:] = values(k * h)
            # fmpy's grid: t_k = k*h, step t_{k+1} - t_k (not h: the last bit differs)
            reached = ad.do_step(k * h, (k + 1) * h - k * h, b_in, None)
            rows.append(ad.get_outputs(b_out, reached).copy())
            times.append(reached)
            if ad.terminated is not None:
                break
        return ad, np.array(times), np.array(rows)
    except BaseException:
        ad.close()
        raise


def fmpy_grid(result, times):
    """fmpy's rows at the grid ``times``: the last row of each time (after its events)."""
    t = result["time"]
    idx = [np.nonzero(np.isclose(t, g, rtol=0, atol=1e-9))[0][-1] for g in times]
    return result[idx]


def fmpy_event_times(result):
    t = result["time"]
    return t[1:][np.diff(t) == 0]


# ---- BouncingBall: state events -------------------------------------------------------------

@pytest.mark.parametrize("version", VERSIONS)
def test_bouncing_ball_me_matches_fmpy_and_the_closed_form(event_fmus, version):
    path = event_fmus[("BouncingBall", version)]
    h, stop = 0.01, 3.0
    ad, times, rows = run_adapter(path, "me", ["h", "v", "bounces"], stop, h, rtol=BALL_RTOL)
    try:
        assert ad.solver_used == "cvode"  # event indicators: never the RK4 fast path
        events = np.array(ad.event_times)
    finally:
        ad.close()
    ref = fmpy.simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=stop,
                            output_interval=h, relative_tolerance=BALL_RTOL,
                            output=["h", "v", "bounces"])
    grid = fmpy_grid(ref, times)
    np.testing.assert_allclose(rows[:, 0], grid["h"], atol=1e-9)
    np.testing.assert_allclose(rows[:, 1], grid["v"], atol=1e-8)
    assert np.array_equal(rows[:, 2], grid["bounces"])
    # bounce times: as fmpy's and the closed form's, to 1e-6 s
    ref_events = fmpy_event_times(ref)
    assert len(events) == len(ref_events) == 11
    np.testing.assert_allclose(events, ref_events, rtol=0, atol=1e-6)
    assert abs(events[0] - math.sqrt(2 * 1.0 / 9.81)) < 1e-6
    *_, t_bounce = ball_exact(0.0)
    np.testing.assert_allclose(events, t_bounce, rtol=0, atol=1e-6)
    assert rows[-1, 0] == pytest.approx(0.0, abs=1e-9)  # at rest on the floor, not below


@pytest.mark.parametrize("version", VERSIONS)
def test_bouncing_ball_co_simulation_equals_fmpy(event_fmus, version):
    path = event_fmus[("BouncingBall", version)]
    ad, times, rows = run_adapter(path, "cs", ["h", "v", "bounces"], 3.0, 0.01)
    ad.close()
    ref = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=3.0,
                            output_interval=0.01, output=["h", "v", "bounces"])
    assert len(ref) == len(rows)
    assert np.array_equal(rows[:, 0], ref["h"]) and np.array_equal(rows[:, 1], ref["v"])
    assert np.array_equal(rows[:, 2], ref["bounces"])


# ---- Stair: time events, termination ----------------------------------------------------------

@pytest.mark.parametrize("h", [0.25, 0.3], ids=["events-on-the-grid", "events-inside-steps"])
@pytest.mark.parametrize("version", VERSIONS)
def test_stair_time_events_fire_at_their_times(event_fmus, version, h):
    path = event_fmus[("Stair", version)]
    ad, times, rows = run_adapter(path, "me", ["counter"], 6.0, h, {"period": 1.0})
    try:
        assert ad.solver_used == "cvode"
        np.testing.assert_allclose(ad.event_times, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], atol=1e-12)
    finally:
        ad.close()
    expected = 1 + np.floor(times + 1e-9)
    assert np.array_equal(rows[:, 0], expected)


@pytest.mark.parametrize("version", VERSIONS)
def test_a_time_event_at_every_communication_point(event_fmus, version):
    """period 0.1 on a 0.1 s grid: every step ends with a time event, handled at the grid
    time; the counter is fmpy's."""
    path = event_fmus[("Stair", version)]
    ad, times, rows = run_adapter(path, "me", ["counter"], 2.0, 0.1, {"period": 0.1})
    try:
        assert len(ad.event_times) == 20
        assert all(e in set(times) for e in ad.event_times)
    finally:
        ad.close()
    assert np.array_equal(rows[:, 0], 1 + np.arange(21))
    ref = fmpy.simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=2.0,
                            output_interval=0.1, start_values={"period": 0.1},
                            output=["counter"])
    assert np.array_equal(rows[:, 0], fmpy_grid(ref, times)["counter"])


@pytest.mark.parametrize("t_term", [2.5, 2.25], ids=["at-a-step", "mid-step"])
@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("version", VERSIONS)
def test_termination_is_reported_not_raised(event_fmus, version, interface, t_term):
    path = event_fmus[("Stair", version)]
    params = {"period": 1.0, "t_terminate": t_term}
    ad, times, rows = run_adapter(path, interface, ["counter"], 6.0, 0.5, params)
    try:
        t_stop, reason = ad.terminated
        assert t_stop == pytest.approx(t_term, abs=1e-12)
        assert times[-1] == pytest.approx(t_term, abs=1e-12) and rows[-1, 0] == 3
        assert reason.startswith("fmi2Terminated" if version == "2.0" and interface == "cs"
                                 else "terminateSimulation")
        with pytest.raises(FMUError, match=f"after the FMU asked to stop at t={t_term:g}"):
            ad.do_step(t_term, 0.5, ad.bind([]), None)
    finally:
        ad.close()


def test_termination_through_a_worker_process(event_fmus):
    path = event_fmus[("Stair", "2.0")]
    ad, times, _ = run_adapter(path, "cs", ["counter"], 6.0, 0.5,
                               {"period": 1.0, "t_terminate": 1.5}, cls=_Proxy)
    try:
        assert ad.terminated[0] == pytest.approx(1.5) and times[-1] == pytest.approx(1.5)
    finally:
        ad.close()


class _Proxy(ProxyAdapter):
    def __init__(self, name, path, interface, solver, substeps, rtol):
        super().__init__(name, path, interface, solver, substeps, rtol, timeout_s=30.0)


# ---- Feedthrough: discrete inputs -----------------------------------------------------------

def _feed_values(t):
    return [math.sin(t), float(int(3 * t) - 2), float(int(2 * t) % 2)]


@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("version", VERSIONS)
def test_discrete_inputs_are_accepted_and_passed_through(event_fmus, version, interface):
    path = event_fmus[("Feedthrough", version)]
    ad, times, rows = run_adapter(path, interface, ["y", "yk", "iy", "by"], 2.0, 0.1,
                                  inputs=["u", "iu", "bu"], values=_feed_values)
    try:
        native = ad.bind(["iy", "by"])
        ad.get_outputs(native, times[-1])
        iy, by = native.native()
        assert type(iy) is int and type(by) is bool
    finally:
        ad.close()
    # outputs at t_{k+1} follow the inputs held over the step (set at t_k)
    held = np.array([_feed_values(t) for t in times[:-1]])
    np.testing.assert_allclose(rows[1:, 0], held[:, 0], atol=1e-12)
    np.testing.assert_allclose(rows[1:, 1], 2 * held[:, 0], atol=1e-12)
    assert np.array_equal(rows[1:, 2], held[:, 1]) and np.array_equal(rows[1:, 3], held[:, 2])
    assert iy == int(held[-1, 1]) and by == bool(held[-1, 2])


# ---- fmu check --interface me: which solver -------------------------------------------------

@pytest.mark.parametrize(("model", "expected"), [
    ("BouncingBall", "1 event indicator(s): state events -> the event-aware solver"),
    ("Stair", "a time event after initialization -> the event-aware solver"),
    ("Feedthrough", "no time event at initialization -> fixed-step RK4 fast path"),
])
def test_fmu_check_says_which_me_solver(event_fmus, model, expected):
    from uwcosim.fmu.check import check_fmu

    rep = check_fmu(event_fmus[(model, "3.0")], role=None, interface="me")
    assert rep.ok, rep.text()
    [line] = [x for x in rep.lines if x.startswith("  ME solver")]
    assert expected in line


# ---- TypedBlock: step events (completedIntegratorStep) ----------------------------------------

@pytest.mark.parametrize("solver", ["rk4", "adaptive"])
@pytest.mark.parametrize("version", VERSIONS)
def test_step_events_are_handled_after_the_integrator_step(event_fmus, version, solver):
    path = event_fmus[("TypedBlock", version)]
    params = {"y_wrap": 0.32}  # never hit exactly by y = 0.05 k (no rounding ties)
    ad, times, rows = run_adapter(path, "me", ["y", "wraps"], 2.0, 0.1, params, solver=solver)
    try:
        assert ad.solver_used == solver  # no event indicator, no time event: fast path
        assert len(ad.event_times) == rows[-1, 1] > 0
    finally:
        ad.close()
    ref = fmpy.simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=2.0,
                            output_interval=0.1, relative_tolerance=RTOL,
                            start_values=params, output=["y", "wraps"])
    grid = fmpy_grid(ref, times)
    np.testing.assert_allclose(rows[:, 0], grid["y"], atol=1e-9)
    assert np.array_equal(rows[:, 1], grid["wraps"])
    # y + wraps*y_wrap is the integral of d_in (start 0.5)
    np.testing.assert_allclose(rows[:, 0] + 0.32 * rows[:, 1], 0.5 * times, atol=1e-9)


@pytest.mark.parametrize("version", VERSIONS)
def test_discrete_inputs_are_set_again_after_a_reset(event_fmus, version):
    ad = FMUAdapter("dut", event_fmus[("Feedthrough", version)], "me")
    b_in, b_out = ad.bind(["iu"]), ad.bind(["iy"])
    try:
        for _ in range(2):  # the second instantiate resets the instance (campaign reuse)
            ad.instantiate({}, {}, 0.0, 1.0)
            b_in.view[:] = [5.0]
            ad.do_step(0.0, 0.5, b_in, None)
            assert ad.get_outputs(b_out, 0.5)[0] == 5.0
    finally:
        ad.close()


def test_a_solver_failure_is_an_fmu_error(event_fmus, capfd):
    ad = FMUAdapter("ball", event_fmus[("BouncingBall", "3.0")], "me")
    b = ad.bind([])
    try:
        ad.instantiate({"g": float("nan")}, {}, 0.0, 3.0)  # NaN derivatives
        with pytest.raises(FMUError, match="FMU 'ball' .*CVode failed between t=0 and 0.1"):
            for k in range(10):
                ad.do_step(k * 0.1, 0.1, b, None)
    finally:
        ad.close()
    assert capfd.readouterr().err == ""  # SUNDIALS prints nothing: the CLI error is one line


def test_worker_process_gives_the_same_events_and_types(event_fmus):
    path = event_fmus[("BouncingBall", "2.0")]
    local, _, rows = run_adapter(path, "me", ["h", "v", "bounces"], 3.0, 0.05)
    local.close()
    proxy, _, rows_p = run_adapter(path, "me", ["h", "v", "bounces"], 3.0, 0.05, cls=_Proxy)
    try:
        assert proxy.solver_used == "cvode"
        assert np.array_equal(rows, rows_p)  # bit-identical
        b = proxy.bind(["bounces", "h"])
        proxy.get_outputs(b, 3.0)
        bounces, h = b.native()
        assert bounces == 11 and type(bounces) is int and type(h) is float
    finally:
        proxy.close()
