"""Algebraic loops between FMUs solved by Newton's method (issue 21, item 3).

Against closed forms: a linear loop of two Polynomial FMUs (fixed point ``(b + a d)/(1 - a c)``),
the structure of OMSimulator's ``equationPair`` (its figure x1 = 4.557175; the root
``(-5 + sqrt(13081))/24``), a P controller around a first-order plant with feed-through (the
discrete recursion of a zero-order hold in co-simulation, the exponential in model exchange);
and the failures: ``algebraic_loops = "error"``, a loop without a solution, a loop through an
Integer input, FMUs of different periods.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_system import run, scenario

from uwcosim.cli import main
from uwcosim.master import FMU, Master, System
from uwcosim.runlog import read_log

try:
    from event_fmus import VERSIONS, event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover - run from the repository root
    from tests.event_fmus import VERSIONS, event_fmus  # noqa: F401
try:
    from conftest import without_progress
except ImportError:  # tests/ imported as a package
    from tests.conftest import without_progress
X1_EQUATION_PAIR = (-5.0 + math.sqrt(13081.0)) / 24.0  # 12 x1^2 + 5 x1 - 272 = 0
LINEAR = {"a": 0.5, "b": 1.0, "c": -2.0, "d": 3.0}


def linear_pair(event_fmus, version, ifaces=("cs", "cs")):
    path = event_fmus[("Polynomial", version)]
    a, b, c, d = (LINEAR[k] for k in "abcd")
    return {"p1": {"path": path, "interface": ifaces[0], "parameters": {"c0": b, "c1": a}},
            "p2": {"path": path, "interface": ifaces[1], "parameters": {"c0": d, "c1": c}}}


LOOP = [("p1.y", "p2.u"), ("p2.y", "p1.u")]


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("ifaces", [("cs", "cs"), ("me", "cs"), ("me", "me")],
                         ids=["cs-cs", "me-cs", "me-me"])
def test_linear_loop_gives_its_fixed_point(event_fmus, tmp_path, version, ifaces):
    """y1 = a u1 + b, y2 = c u2 + d, u1 = y2, u2 = y1: y1 = (b + a d)/(1 - a c), at every row
    from initialization on (CS, ME standalone in a loop with CS, two ME integrated together)."""
    sc = scenario(tmp_path, linear_pair(event_fmus, version, ifaces), 1.0, 0.1,
                  connections=LOOP)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    a, b, c, d = (LINEAR[k] for k in "abcd")
    y1 = (b + a * d) / (1 - a * c)
    np.testing.assert_allclose(cols["p1.y"], y1, rtol=1e-12, atol=0)
    np.testing.assert_allclose(cols["p2.y"], c * y1 + d, rtol=1e-12, atol=1e-15)
    assert cols["time"].size == 11


def test_loop_through_a_linear_transformation(event_fmus, tmp_path):
    """A connection's factor and offset are part of the coupling equations:
    u1 = 2 y2 + 1 gives y1 = (b + a (2 d + 1))/(1 - 2 a c)."""
    conns = [("p1.y", "p2.u"), ("p2.y", "p1.u", {"factor": 2.0, "offset": 1.0})]
    sc = scenario(tmp_path, linear_pair(event_fmus, "3.0"), 0.5, 0.1, connections=conns)
    rc, cols, _ = run(sc, tmp_path / "r")
    a, b, c, d = (LINEAR[k] for k in "abcd")
    assert rc == 0
    np.testing.assert_allclose(cols["p1.y"], (b + a * (2 * d + 1)) / (1 - 2 * a * c),
                               rtol=1e-12)


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_a_one_way_link_beside_a_loop_is_passed_on(event_fmus, tmp_path, interface):
    """Two Feedthrough FMUs in a Real loop (a.yk = k a.u, b.y = b.u, a.u = b.y + 1: x = 1 for
    k = 0.5) and, between the same two, a one-way Integer feedthrough a.iy -> b.iu: not an
    unknown of the loop, passed on after it is solved (same row as a.iy)."""
    ft = event_fmus[("Feedthrough", "3.0")]
    fmus = {"a": {"path": ft, "interface": interface, "parameters": {"k": 0.5}},
            "b": {"path": ft, "interface": interface}}
    conns = [("a.yk", "b.u"), ("b.y", "a.u", {"offset": 1.0}), ("a.iy", "b.iu")]
    controls = {"i": {"target": "a.iu", "table": [[0.0, 0.0], [0.25, 3.0]],
                      "interpolation": "hold"}}
    sc = scenario(tmp_path, fmus, 0.5, 0.1, connections=conns, controls=controls)
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    np.testing.assert_allclose(cols["b.y"], 1.0, rtol=1e-10)
    np.testing.assert_array_equal(cols["b.iy"], cols["a.iy"])
    assert cols["a.iy"][-1] == 3


def equation_pair(event_fmus, version, interface="cs"):
    """OMSimulator's equationPair: 2 x1^2 + 5 x2 = 42 (equation1: x1 in, x2 out) and
    x1 - 6 x2 = 4 (equation2: x2 in, x1 out), as two of our Polynomial FMUs."""
    path = event_fmus[("Polynomial", version)]
    return {"equation1": {"path": path, "interface": interface,
                          "parameters": {"c0": 8.4, "c1": 0.0, "c2": -0.4}},
            "equation2": {"path": path, "interface": interface,
                          "parameters": {"c0": 4.0, "c1": 6.0}}}


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("interface", ["cs", "me"])
def test_equation_pair_gives_omsimulators_figure(event_fmus, tmp_path, version, interface):
    sc = scenario(tmp_path, equation_pair(event_fmus, version, interface), 0.2, 0.1,
                  connections=[("equation1.y", "equation2.u"), ("equation2.y", "equation1.u")])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    x1, x2 = cols["equation2.y"], cols["equation1.y"]
    # to the loop's tolerance (1e-10 on the residual)
    np.testing.assert_allclose(x1, X1_EQUATION_PAIR, rtol=1e-10)
    np.testing.assert_allclose(x2, (X1_EQUATION_PAIR - 4.0) / 6.0, rtol=1e-8)
    assert abs(x1[0] - 4.557175) < 5e-7  # OMSimulator (KINSOL): x1 = 4.557175
    np.testing.assert_allclose(2 * x1**2 + 5 * x2, 42.0, rtol=1e-10)


@pytest.mark.parametrize("version", VERSIONS)
def test_directional_derivatives_and_finite_differences_agree(event_fmus, version):
    """Polynomial provides directional derivatives; without them (finite differences) the
    solution is the same to the tolerance and Newton takes as many iterations."""
    fmus = {n: FMU(f["path"], parameters=f["parameters"])
            for n, f in equation_pair(event_fmus, version).items()}
    system = System(fmus=fmus, connections=[("equation1.y", "equation2.u"),
                                            ("equation2.y", "equation1.u")],
                    step=0.1, duration=0.1)
    results = []
    for exact in (True, False):
        m = Master(system)
        try:
            assert all(ad.provides_derivatives for ad in m.adapters.values())
            for ad in m.adapters.values():
                ad.provides_derivatives = exact
            m.initialize()
            stage = m.units[0].init_exchange.loops[0]
            results.append((m.signal("equation2.y"), stage.iterations))
        finally:
            m.close()
    (x_dd, it_dd), (x_fd, it_fd) = results
    assert x_dd == pytest.approx(X1_EQUATION_PAIR, rel=1e-10)
    assert x_fd == pytest.approx(X1_EQUATION_PAIR, rel=1e-10)
    assert 2 <= it_dd <= 8 and abs(it_dd - it_fd) <= 1


# -- a P controller around a plant with feed-through -------------------------------------------
KP, T, K, D, R = 2.0, 0.5, 1.5, 0.4, 1.0


def control_loop(event_fmus, version, plant="cs", ctl="cs", **plant_keys):
    return {"plant": {"path": event_fmus[("Lag", version)], "interface": plant,
                      "parameters": {"T": T, "K": K, "D": D}, **plant_keys},
            "ctl": {"path": event_fmus[("PController", version)], "interface": ctl,
                    "parameters": {"kp": KP}}}


CONTROL = [("plant.y", "ctl.y"), ("ctl.u", "plant.u")]
SETPOINT = {"r": {"target": "ctl.r", "table": [[0.0, R]], "interpolation": "hold"}}


def held_recursion(n, h):
    """The plant under u held over each step at the loop's solution at its start (zero-order
    hold): x_{k+1} = e^{-h/T} x_k + K (1 - e^{-h/T}) u_k, u_k = kp (r - x_k)/(1 + kp D)."""
    x = np.zeros(n + 1)
    a = math.exp(-h / T)
    for k in range(n):
        u = KP * (R - x[k]) / (1 + KP * D)
        x[k + 1] = a * x[k] + K * (1 - a) * u
    u = KP * (R - x) / (1 + KP * D)
    return x, u, x + D * u


def continuous(t):
    """The closed loop in continuous time: x = x_inf (1 - exp(-t/tau))."""
    s = 1 + KP * D
    tau, x_inf = T * s / (s + K * KP), K * KP * R / (s + K * KP)
    x = x_inf * (1 - np.exp(-t / tau))
    u = KP * (R - x) / s
    return x, u, x + D * u


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("plant", ["cs", "me"])
def test_controller_around_a_plant_held_over_the_step(event_fmus, tmp_path, version, plant):
    """Co-simulation controller: the loop is solved at every communication point, the plant
    (co-simulation, or model exchange on its own) integrates with u held over the step."""
    extra = {"substeps": 10} if plant == "me" else {}
    sc = scenario(tmp_path, control_loop(event_fmus, version, plant, "cs", **extra), 2.0, 0.01,
                  connections=CONTROL, controls=SETPOINT)
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    x, u, y = held_recursion(200, 0.01)  # to the loop's tolerance (1e-10 on the residual)
    np.testing.assert_allclose(cols["plant.x"], x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cols["ctl.u"], u, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cols["plant.y"], y, rtol=0, atol=1e-9)
    # the sampled loop approaches the continuous one to O(h)
    assert np.abs(cols["plant.x"] - continuous(cols["time"])[0]).max() < 1e-2


@pytest.mark.parametrize("version", VERSIONS)
def test_controller_around_a_plant_integrated_together(event_fmus, tmp_path, version):
    """Both model exchange: integrated as one system, the loop solved at every stage of CVode:
    the continuous closed form."""
    sc = scenario(tmp_path, control_loop(event_fmus, version, "me", "me", solver="cvode",
                                         rtol=1e-10), 2.0, 0.01,
                  connections=CONTROL, controls=SETPOINT)
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    x, u, y = continuous(cols["time"])
    for name, exact in (("plant.x", x), ("ctl.u", u), ("plant.y", y)):
        np.testing.assert_allclose(cols[name], exact, rtol=0, atol=1e-8, err_msg=name)
    sim = json.loads((tmp_path / "r" / "simulation.json").read_text())
    assert sim["fmus"]["plant"]["solver"] == "cvode (integrated with ctl)"


# -- failures -------------------------------------------------------------------------------
def test_loops_as_errors_name_the_loop_along_the_flow(event_fmus, tmp_path, capsys):
    sc = scenario(tmp_path, linear_pair(event_fmus, "2.0"), 1.0, 0.1, connections=LOOP,
                  run_extra={"algebraic_loops": "error"})
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "key 'connections': algebraic loop between FMUs: " in err
    assert err.endswith('(run.algebraic_loops = "error")')
    loop = err.split("algebraic loop between FMUs: ")[1].split(" (")[0].split(" -> ")
    flow = set(LOOP) | {("p1.u", "p1.y"), ("p2.u", "p2.y")}
    assert all(edge in flow for edge in zip(loop, loop[1:])), loop


def test_a_loop_without_solution_ends_the_run_with_its_variables(event_fmus, tmp_path, capsys):
    """u = kp (r - y), y = u^2: a root while 1 + 4 r kp^2 >= 0; r = -1 from t = 0.5 has none."""
    fmus = {"ctl": {"path": event_fmus[("PController", "3.0")], "parameters": {"kp": 1.0}},
            "sq": {"path": event_fmus[("Polynomial", "2.0")],
                   "parameters": {"c1": 0.0, "c2": 1.0}}}
    controls = {"r": {"target": "ctl.r", "table": [[0.0, 1.0], [0.5, -1.0]],
                      "interpolation": "hold"}}
    sc = scenario(tmp_path, fmus, 1.0, 0.1, connections=[("ctl.u", "sq.u"), ("sq.y", "ctl.y")],
                  controls=controls)
    out = tmp_path / "r"
    assert main(["run", str(sc), "--out", str(out)]) == 3
    err = without_progress(capsys.readouterr().err).strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "algebraic loop ctl.u -> sq.u -> sq.y -> ctl.y -> ctl.u" in err
    assert "did not converge at t=0.6" in err and "run.loop_tolerance" in err
    cols, _ = read_log(out / "log.parquet")  # the log up to the failure stays readable
    assert cols["time"][-1] == pytest.approx(0.5)
    u = cols["ctl.u"]
    np.testing.assert_allclose(u + u**2, 1.0, rtol=1e-12)  # u = r - u^2 with r = 1
    assert json.loads((out / "summary.json").read_text())["status"] == "failed"


def test_a_loop_through_an_integer_input_is_refused_at_load(event_fmus, tmp_path, capsys):
    ft = event_fmus[("Feedthrough", "3.0")]
    sc = scenario(tmp_path, {"a": {"path": ft}, "b": {"path": ft}}, 1.0, 0.1,
                  connections=[("a.iy", "b.iu"), ("b.iy", "a.iu")])
    assert main(["check", str(sc)]) == 2
    err = capsys.readouterr()
    text = (err.out + err.err).strip()
    assert "key 'run.algebraic_loops'" in text and "only continuous Real inputs" in text
    assert "Int32" in text


def test_a_loop_between_fmus_of_different_periods_is_refused(event_fmus, tmp_path, capsys):
    fmus = linear_pair(event_fmus, "3.0")
    fmus["p2"]["period"] = 2
    sc = scenario(tmp_path, fmus, 1.0, 0.1, connections=LOOP)
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "different periods (p1: 1, p2: 2)" in err


def test_unknown_loop_setting_is_a_scenario_error(event_fmus, tmp_path, capsys):
    sc = scenario(tmp_path, linear_pair(event_fmus, "3.0"), 1.0, 0.1, connections=LOOP,
                  run_extra={"algebraic_loops": "ignore"})
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "algebraic_loops" in err and "solve" in err
