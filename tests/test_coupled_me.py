"""Strongly coupled model exchange (issue 21, item 6): ME FMUs connected to each other are
integrated as one system (one integrator over all their states, a joint event loop).

Two SpringMass FMUs joined by their spring are a linear system: compared with its exact
solution ``expm(A t) x0``, with the same equations in one FMU (TwoMasses) run by
``fmpy.simulate_fmu``, and with the same pair in co-simulation (inputs held over the step).
"""

from __future__ import annotations

import json

import fmpy
import numpy as np
import pytest
from test_algorithms import MASSES, SPRING, X0, exact_masses, masses
from test_system import run, scenario

from uwcosim.master import FMU, Master, System

try:
    from event_fmus import VERSIONS, ball_exact, event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover - run from the repository root
    from tests.event_fmus import VERSIONS, ball_exact, event_fmus  # noqa: F401


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("solver, atol", [("cvode", 1e-7), ("rk4", 1e-8), ("adaptive", 1e-8)])
def test_two_masses_integrated_together_match_the_closed_form(event_fmus, tmp_path, version,
                                                              solver, atol):
    keys = {"solver": solver, "rtol": 1e-10} if solver != "rk4" else {"substeps": 4}
    sc = scenario(tmp_path, masses(event_fmus, version, ("a", "b"), "me", **keys), 10.0, 0.01,
                  connections=SPRING)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    exact = exact_masses(cols["time"])
    for j, name in enumerate(("a.x", "a.v", "b.x", "b.v")):
        np.testing.assert_allclose(cols[name], exact[:, j], rtol=0, atol=atol, err_msg=name)
    sim = json.loads((tmp_path / "r" / "simulation.json").read_text())
    assert sim["fmus"]["a"]["solver"] == f"{solver} (integrated with b)"


def test_held_inputs_are_what_coupling_removes(event_fmus, tmp_path):
    """The same pair in co-simulation (each mass sees the other's position held over the
    step) is O(h) away from the closed form; integrated together, to the solver's tolerance."""
    errs = {}
    for interface in ("cs", "me"):
        keys = {"solver": "cvode", "rtol": 1e-10} if interface == "me" else {}
        sc = scenario(tmp_path, masses(event_fmus, "3.0", ("a", "b"), interface, **keys), 10.0,
                      0.01, connections=SPRING, name=f"{interface}.toml")
        rc, cols, _ = run(sc, tmp_path / interface)
        assert rc == 0
        errs[interface] = np.abs(cols["a.x"] - exact_masses(cols["time"])[:, 0]).max()
    assert errs["cs"] > 1e-3 and errs["me"] < 1e-7


@pytest.mark.parametrize("version", VERSIONS)
def test_the_pair_equals_both_masses_in_one_fmu(event_fmus, tmp_path, version):
    """The coupled pair and TwoMasses (same equations, one FMU) by fmpy.simulate_fmu with CVode
    at the same tolerance agree to that tolerance."""
    sc = scenario(tmp_path, masses(event_fmus, version, ("a", "b"), "me", solver="cvode",
                                   rtol=1e-10), 10.0, 0.01, connections=SPRING)
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    a, b = MASSES["a"], MASSES["b"]
    ref = fmpy.simulate_fmu(str(event_fmus[("TwoMasses", version)]), fmi_type="ModelExchange",
                            stop_time=10.0, output_interval=0.01, relative_tolerance=1e-10,
                            start_values={"m1": a["m"], "m2": b["m"], "c": a["c"],
                                          "c1": a["c_wall"], "c2": b["c_wall"],
                                          "x1": X0["a"], "x2": X0["b"]})
    np.testing.assert_allclose(cols["a.x"], ref["x1"], rtol=0, atol=1e-7)
    np.testing.assert_allclose(cols["b.v"], ref["v2"], rtol=0, atol=1e-7)


@pytest.mark.parametrize("version", VERSIONS)
def test_events_of_one_member_in_the_joint_event_loop(event_fmus, tmp_path, version):
    """A BouncingBall (state events) drives a SpringMass (x_other = h): integrated together,
    the bounces are located by the joint CVode's root finding as when the ball is alone."""
    fmus = {"ball": {"path": event_fmus[("BouncingBall", version)], "interface": "me",
                     "rtol": 1e-10},
            "m": {"path": event_fmus[("SpringMass", version)], "interface": "me"}}
    sc = scenario(tmp_path, fmus, 3.0, 0.01, connections=[("ball.h", "m.x_other")])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    h, _, bounces, _ = ball_exact(cols["time"])
    np.testing.assert_allclose(cols["ball.h"], h, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(cols["ball.bounces"], bounces)
    sim = json.loads((tmp_path / "r" / "simulation.json").read_text())
    assert sim["fmus"]["m"]["solver"] == "cvode (integrated with ball)"
    assert np.ptp(cols["m.x"]) > 0.05  # the mass is pulled along


def test_a_time_event_reaches_a_coupled_fmus_discrete_input(event_fmus, tmp_path):
    """Stair (time events, ME) -> Feedthrough (ME) discrete input: in the joint event loop the
    counter reaches the Feedthrough at the event, not one step later."""
    fmus = {"stair": {"path": event_fmus[("Stair", "3.0")], "interface": "me"},
            "ft": {"path": event_fmus[("Feedthrough", "2.0")], "interface": "me"}}
    sc = scenario(tmp_path, fmus, 3.0, 0.1, connections=[("stair.counter", "ft.iu")])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    np.testing.assert_array_equal(cols["ft.iy"], cols["stair.counter"])
    np.testing.assert_array_equal(cols["stair.counter"], 1 + np.floor(cols["time"] + 1e-9))


def test_me_fmus_of_different_periods_keep_their_own_solvers(event_fmus):
    path = event_fmus[("SpringMass", "3.0")]
    system = System(fmus={"a": FMU(path, interface="me"), "b": FMU(path, interface="me",
                                                                   period=2)},
                    connections=SPRING, step=0.01, duration=0.1)
    m = Master(system)
    try:
        m.initialize()
        m.run_until(0.1)
        assert m.me_solvers() == {"a": "rk4", "b": "rk4"}
        assert all(not u.coupled for u in m.units)
    finally:
        m.close()
