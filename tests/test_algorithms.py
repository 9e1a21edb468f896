"""The master algorithms by name (issue 21, item 7): Gauss-Seidel and Jacobi.

Two co-simulation SpringMass FMUs coupled through their positions (inputs without direct
feedthrough: no ordering edge between them) are the case where the order of the FMUs in the
file matters for Gauss-Seidel (the second one steps with the first one's new position), and
does not for Jacobi (both step from the positions of the previous communication point). The
input timing conventions of both are checked on a chain of Feedthrough FMUs.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from test_system import run, scenario

from uwcosim.cli import main
from uwcosim.master import FMU, Master, System
from uwcosim.master.observer import Callback

try:
    from event_fmus import VERSIONS, event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover - run from the repository root
    from tests.event_fmus import VERSIONS, event_fmus  # noqa: F401

MASSES = {"a": {"m": 1.0, "c": 1.0, "c_wall": 1.0}, "b": {"m": 2.0, "c": 1.0, "c_wall": 0.5}}
X0 = {"a": 1.0, "b": 0.0}


def masses(event_fmus, version, order, interface="cs", **keys):
    path = event_fmus[("SpringMass", version)]
    return {n: {"path": path, "interface": interface, "parameters": MASSES[n],
                "start": {"x": X0[n]}, **keys} for n in order}


SPRING = [("a.x", "b.x_other"), ("b.x", "a.x_other")]


def exact_masses(t):
    """The two masses in closed form: expm(A t) x0, state (xa, va, xb, vb)."""
    a, b = MASSES["a"], MASSES["b"]
    A = np.array([[0, 1, 0, 0],
                  [-(a["c"] + a["c_wall"]) / a["m"], 0, a["c"] / a["m"], 0],
                  [0, 0, 0, 1],
                  [b["c"] / b["m"], 0, -(b["c"] + b["c_wall"]) / b["m"], 0]])
    x0 = np.array([X0["a"], 0.0, X0["b"], 0.0])
    return np.array([expm(A * tk) @ x0 for tk in np.atleast_1d(t)])


def run_order(tmp_path, event_fmus, order, algorithm, version="3.0"):
    sc = scenario(tmp_path, masses(event_fmus, version, order), 5.0, 0.01,
                  connections=SPRING, run_extra={"algorithm": algorithm},
                  name=f"{algorithm}-{''.join(order)}.toml")
    rc, cols, summary = run(sc, tmp_path / f"{algorithm}-{''.join(order)}")
    assert rc == 0 and summary["status"] == "ok"
    return cols


@pytest.mark.parametrize("version", VERSIONS)
def test_jacobi_does_not_depend_on_the_order_of_the_fmus(event_fmus, tmp_path, version):
    ab = run_order(tmp_path, event_fmus, ("a", "b"), "jacobi", version)
    ba = run_order(tmp_path, event_fmus, ("b", "a"), "jacobi", version)
    for name in ("a.x", "a.v", "b.x", "b.v"):
        np.testing.assert_array_equal(ab[name], ba[name], err_msg=name)  # bit for bit
    # each mass sees the other's position held from the last point: O(h) from the exact one
    exact = exact_masses(ab["time"])
    err = np.abs(ab["a.x"] - exact[:, 0]).max()
    assert 1e-4 < err < 2e-2


@pytest.mark.parametrize("version", VERSIONS)
def test_gauss_seidel_depends_on_the_order_of_independent_fmus(event_fmus, tmp_path, version):
    """Documented (README, "The master algorithm"): with no feedthrough between them, the FMU
    first in the file steps from the other's old position, the second from the first's new one;
    swapping them changes the result (by O(h)), Jacobi's does not."""
    ab = run_order(tmp_path, event_fmus, ("a", "b"), "gauss-seidel", version)
    ba = run_order(tmp_path, event_fmus, ("b", "a"), "gauss-seidel", version)
    diff = np.abs(ab["a.x"] - ba["a.x"]).max()
    assert 1e-4 < diff < 2e-2
    exact = exact_masses(ab["time"])
    for cols in (ab, ba):
        assert np.abs(cols["a.x"] - exact[:, 0]).max() < 2e-2


def test_default_algorithm_is_gauss_seidel(event_fmus, tmp_path):
    default = run_order(tmp_path, event_fmus, ("a", "b"), "gauss-seidel")
    sc = scenario(tmp_path, masses(event_fmus, "3.0", ("a", "b")), 5.0, 0.01,
                  connections=SPRING, name="default.toml")
    rc, cols, _ = run(sc, tmp_path / "default")
    assert rc == 0
    np.testing.assert_array_equal(cols["a.x"], default["a.x"])


CHAIN = {"u": {"target": "f1.u", "table": [[0.0, 0.0], [1.0, 10.0]]}}


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_input_timing_conventions(event_fmus, tmp_path, algorithm):
    """A table input set at t_k shows in the row of t_{k+1} (held over the step, as in fmpy;
    OMSimulator shows it in the row of t_k). Along a connection into a feedthrough input,
    Gauss-Seidel passes the upstream output of t_{k+1} into the step t_k -> t_{k+1}; Jacobi
    the one of t_k (one step more per FMU)."""
    ft = event_fmus[("Feedthrough", "2.0")]
    sc = scenario(tmp_path, {"f1": {"path": ft}, "f2": {"path": ft}}, 0.5, 0.1,
                  connections=[("f1.y", "f2.u")], controls=CHAIN,
                  run_extra={"algorithm": algorithm})
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    t = cols["time"]
    u = 10.0 * t  # the table at the grid times

    def held(x, n):  # x delayed by n rows (the first value kept: set in initialization)
        return np.concatenate([np.repeat(x[:1], n), x[:-n]])

    np.testing.assert_allclose(cols["f1.y"], held(u, 1), rtol=0, atol=1e-12)
    np.testing.assert_allclose(cols["f2.y"], held(u, 1 if algorithm == "gauss-seidel" else 2),
                               rtol=0, atol=1e-12)


def test_jacobi_with_a_loop_does_not_depend_on_the_order(event_fmus):
    """An algebraic loop (two Polynomials) and an FMU fed by it without feedthrough (a mass
    pulled by the loop's output): Jacobi's result is the same for both file orders."""
    poly, mass = event_fmus[("Polynomial", "2.0")], event_fmus[("SpringMass", "3.0")]
    fmus = {"p1": FMU(poly, parameters={"c0": 1.0, "c1": 0.5}),
            "p2": FMU(poly, parameters={"c0": 3.0, "c1": -2.0}),
            "m": FMU(mass, parameters={"c": 1.0})}
    conns = [("p1.y", "p2.u"), ("p2.y", "p1.u"), ("p1.y", "m.x_other")]
    results = []
    for order in (("p1", "p2", "m"), ("m", "p2", "p1")):
        system = System(fmus={n: fmus[n] for n in order}, connections=conns, step=0.1,
                        duration=2.0, algorithm="jacobi")
        m = Master(system)
        rows = []
        m.observers.append(Callback(lambda k, v, rows=rows: rows.append(
            (v.signal("p1.y"), v.signal("m.x")))))
        try:
            m.initialize()
            m.run_until(2.0)
        finally:
            m.close()
        results.append(np.array(rows))
    np.testing.assert_array_equal(results[0], results[1])
    np.testing.assert_allclose(results[0][:, 0], 1.25, rtol=1e-12)


def test_unknown_algorithm_is_a_scenario_error(event_fmus, tmp_path, capsys):
    sc = scenario(tmp_path, masses(event_fmus, "3.0", ("a", "b")), 1.0, 0.1,
                  connections=SPRING, run_extra={"algorithm": "newton"})
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "algorithm" in err and "jacobi" in err
