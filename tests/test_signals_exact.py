"""Logs without gaps and exact integers (issue 21, items 4 and 5), on the test FMU Signals
(tests/data/event_fmus: ``y = k u`` on Float64[3] arrays, ``M = [u; y]`` Float64[2,3], the
local ``energy`` and the local state ``x`` with ``der(x) = ysum``, Int64/UInt64/Int8 passed
through, ``small`` declared -100..100 but not kept, the structural parameter ``k``).

- FMI 3 array outputs are logged one column per element (``y[0]``...), connected whole or
  element by element, with one-line errors for shapes that differ or elements left undriven;
- locals and states are logged by their exact names; a ``[log] signals`` pattern that matches
  nothing is a scenario error (one line, exit 2) naming the nearest names, from ``run`` and
  ``check``;
- a UInt64 -> UInt64 connection carries 2^64 - 1 and an Int64 one 2^62 + 1 exactly (bus,
  connection, log); a narrowing connection is refused at load unless the declared range fits,
  and a value out of range at run time ends the run with the log kept;
- a structural parameter is set in configuration mode (FMI 3).
Closed forms of the model, and fmpy.simulate_fmu on the single FMU, are the references.
"""

from __future__ import annotations

import fmpy
import numpy as np
import pyarrow.parquet as pq
import pytest

try:
    from conftest import without_progress
except ImportError:  # tests/ imported as a package
    from tests.conftest import without_progress
from test_system import run, scenario

from uwcosim.cli import main
from uwcosim.master import FMU, Master, System

try:
    from event_fmus import event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover
    from tests.event_fmus import event_fmus  # noqa: F401


def sig(event_fmus, version="3.0", **keys):
    return {"path": event_fmus[("Signals", version)], **keys}


# ---- arrays -----------------------------------------------------------------------------------

@pytest.mark.parametrize("interface", ["cs", "me"])
def test_array_outputs_are_logged_one_column_per_element(event_fmus, tmp_path, interface):
    fmus = {"a": sig(event_fmus, interface=interface, start={"u": [1.0, -2.0, 0.5]})}
    sc = scenario(tmp_path, fmus, 1.0, 0.1, log=["a.*"])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    y = [f"a.y[{i}]" for i in range(3)]
    M = [f"a.M[{i},{j}]" for i in range(2) for j in range(3)]
    assert [c for c in cols if c.startswith(("a.y[", "a.M["))] == y + M
    for i, u in enumerate([1.0, -2.0, 0.5]):
        np.testing.assert_array_equal(cols[f"a.y[{i}]"], 2.0 * u)
        np.testing.assert_array_equal(cols[f"a.M[0,{i}]"], u)
        np.testing.assert_array_equal(cols[f"a.M[1,{i}]"], 2.0 * u)
    # the same columns as fmpy's result (its array fields flattened row-major)
    ref = fmpy.simulate_fmu(str(event_fmus[("Signals", "3.0")]), stop_time=1.0,
                            output_interval=0.1, start_values={"u": [1.0, -2.0, 0.5]},
                            fmi_type="CoSimulation" if interface == "cs" else "ModelExchange")
    np.testing.assert_allclose(np.stack([cols[c] for c in y], 1), ref["y"], rtol=1e-12)
    np.testing.assert_allclose(np.stack([cols[c] for c in M], 1).reshape(-1, 2, 3), ref["M"],
                               rtol=1e-12)


def test_arrays_connect_whole_or_element_by_element(event_fmus, tmp_path):
    fmus = {"a": sig(event_fmus, start={"u": [1.0, 2.0, 3.0]}), "b": sig(event_fmus),
            "c": sig(event_fmus), "ft": {"path": event_fmus[("Feedthrough", "3.0")]}}
    conns = [("a.y", "b.u"),  # whole: Float64[3] -> Float64[3]
             ("a.M[1,2]", "c.u[0]"), ("a.ysum", "c.u[1]"), ("b.y[2]", "c.u[2]"),  # elements
             ("b.y[1]", "ft.u")]  # an element into a scalar
    sc = scenario(tmp_path, fmus, 0.5, 0.1, conns, log=["a.y", "b.y", "c.y[*]", "ft.y"])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    np.testing.assert_array_equal(cols["b.y[0]"], 4.0)  # 2 * (2 * 1)
    np.testing.assert_array_equal(cols["ft.y"], 8.0)  # b.y[1] = 2 * (2 * 2)
    np.testing.assert_array_equal(cols["c.y[0]"], 12.0)  # 2 * a.M[1,2] = 2 * 6
    np.testing.assert_array_equal(cols["c.y[1]"], 24.0)  # 2 * a.ysum = 2 * 12
    np.testing.assert_array_equal(cols["c.y[2]"], 24.0)  # 2 * b.y[2] = 2 * 12


@pytest.mark.parametrize(("conns", "message"), [
    ([("a.y", "ft.u")], "cannot connect 'a.y' (Float64[3]) to 'ft.u' (Float64): the shapes "
                        "differ (3 and 1 values)"),
    ([("a.M", "b.u")], "'a.M' (Float64[2,3]) to 'b.u' (Float64[3]): the shapes differ"),
    ([("a.y[0]", "b.u[0]"), ("a.y[2]", "b.u[2]")],
     "input array 'b.u' (Float64[3]) is driven element by element without element(s) 1"),
    ([("a.y[3]", "ft.u")], "'a.y[3]': index [3] is outside the shape [3]"),
    ([("a.ysum[0]", "ft.u")], "'a.ysum' is not an array (Float64)"),
    ([("a.y[0]", "b.u[0]"), ("a.ysum", "b.u[0]")], "input 'b.u[0]' is already driven by"),
])
def test_array_connection_errors_are_one_line(event_fmus, tmp_path, capsys, conns, message):
    fmus = {"a": sig(event_fmus), "b": sig(event_fmus),
            "ft": {"path": event_fmus[("Feedthrough", "3.0")]}}
    sc = scenario(tmp_path, fmus, 0.5, 0.1, conns)
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert without_progress(err).count("\n") == 1, err
    assert message in err and "key 'connections[" in err, err
    assert "type Float64)" not in err


# ---- locals, states, patterns -----------------------------------------------------------------

@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("interface", ["cs", "me"])
def test_locals_and_states_are_logged_by_name(event_fmus, tmp_path, version, interface):
    fmus = {"a": sig(event_fmus, version, interface=interface)}
    sc = scenario(tmp_path, fmus, 1.0, 0.1, log=["a.x", "a.energy", "a.der(x)", "a.ysum"])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    assert [c for c in cols if c != "time"] == ["a.ysum", "a.x", "a.energy", "a.der(x)"]
    np.testing.assert_array_equal(cols["a.energy"], 14.0)  # 1 + 4 + 9
    np.testing.assert_array_equal(cols["a.der(x)"], 12.0)
    np.testing.assert_allclose(cols["a.x"], 12.0 * cols["time"], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("pattern", "message"), [
    ("a.ysun", "pattern 'a.ysun' matches no signal (nearest: a.ysum"),
    ("a.y[7]", "pattern 'a.y[7]' matches no signal (nearest: a.y[2], a.y[1], a.y[0])"),
    ("b.*", "pattern 'b.*' matches no signal"),
    ("a.u", "pattern 'a.u' matches no signal: 'a.u' has causality 'input' and type "
            "Float64[3]"),
])
@pytest.mark.parametrize("command", ["run", "check"])
def test_a_log_pattern_that_matches_nothing_is_a_scenario_error(event_fmus, tmp_path, capsys,
                                                                pattern, message, command):
    sc = scenario(tmp_path, {"a": sig(event_fmus)}, 0.5, 0.1, log=["a.y", pattern])
    assert main([command, str(sc), *(["--out", str(tmp_path / "r")] * (command == "run"))]) \
        == 2
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if "error" in x or "key 'log.signals'" in x]
    assert len(lines) == 1 and message in lines[0] and "key 'log.signals'" in lines[0], err
    assert "Traceback" not in err
    assert not (tmp_path / "r" / "log.parquet").exists()


def test_check_reports_log_patterns_with_the_other_problems(event_fmus, tmp_path, capsys):
    sc = scenario(tmp_path, {"a": sig(event_fmus)}, 0.5, 0.1, [("a.y", "a.i8_in")],
                  log=["a.nope"])
    assert main(["check", str(sc)]) == 2
    err = capsys.readouterr().err
    assert "connections[0]" in err and "pattern 'a.nope'" in err


# ---- exact 64-bit integers, narrowing ----------------------------------------------------------

@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("timeout", [None, 30.0])
def test_64_bit_integers_arrive_exactly(event_fmus, tmp_path, interface, timeout):
    """UInt64 2^64 - 1 and Int64 2^62 + 1 through a connection (and a worker process with
    ``timeout_s``): exact on the bus, in the connection and in the log (they came out as
    2^64 and 2^62 through the float64 bus)."""
    extra = {"timeout_s": timeout} if timeout else {}
    fmus = {"a": sig(event_fmus, interface=interface,
                     start={"u64_in": 2**64 - 1, "i64_in": 2**62 + 1}),
            "b": sig(event_fmus, interface=interface, **extra)}
    sc = scenario(tmp_path, fmus, 0.5, 0.1, [("a.u64_out", "b.u64_in"), ("a.i64_out",
                                                                          "b.i64_in")],
                  log=["a.u64_out", "a.i64_out", "b.u64_out", "b.i64_out"])
    rc, _, summary = run(sc, tmp_path / "r")
    assert rc == 0, summary
    t = pq.read_table(tmp_path / "r" / "log.parquet")
    for name in ("a", "b"):
        assert t.column(f"{name}.u64_out").to_pylist() == [2**64 - 1] * 6
        assert t.column(f"{name}.i64_out").to_pylist() == [2**62 + 1] * 6
    assert str(t.schema.field("b.u64_out").type) == "uint64"


def test_64_bit_values_through_the_python_api(event_fmus):
    system = System(fmus={"a": FMU(str(event_fmus[("Signals", "3.0")]),
                                   start={"u64_in": 2**64 - 2}),
                          "b": FMU(str(event_fmus[("Signals", "3.0")]))},
                    connections=[("a.u64_out", "b.u64_in")], step=0.1, duration=0.2)
    m = Master(system)
    try:
        m.initialize()
        m.run_until(0.2)
        assert m.value("b.u64_out") == 2**64 - 2 and type(m.value("b.u64_out")) is int
        assert m.value("a.y[1]") == 4.0 and m.signal("a.M[1,2]") == 6.0
    finally:
        m.close()


@pytest.mark.parametrize(("conn", "message"), [
    (("a.i64_out", "b.i8_in"), "the values of Int64 'i64_out' (-9223372036854775808.."
                               "9223372036854775807) do not fit Int8 'i8_in' (-100..100)"),
    (("a.u64_out", "b.i64_in"), "UInt64 'u64_out' (0..18446744073709551615) do not fit Int64"),
    (("a.i64_out", "b.u64_in"), "do not fit UInt64 'u64_in' (0..18446744073709551615)"),
])
def test_narrowing_connections_are_refused_at_load(event_fmus, tmp_path, capsys, conn,
                                                   message):
    sc = scenario(tmp_path, {"a": sig(event_fmus), "b": sig(event_fmus)}, 0.5, 0.1, [conn])
    for command in ("check", "run"):
        args = [command, str(sc)] + (["--out", str(tmp_path / "r")] if command == "run" else [])
        assert main(args) == 2
        err = capsys.readouterr().err
        assert message in err and "key 'connections[0]'" in err and "Traceback" not in err
        assert command == "check" or without_progress(err).count("\n") == 1


def test_a_declared_range_that_fits_is_accepted_and_checked_at_run_time(event_fmus, tmp_path,
                                                                       capsys):
    """``small`` (Int64, declared -100..100) may drive the Int8 input ``i8_in`` (declared
    -100..100); when the FMU leaves its declared range (i64_in = 101 from t = 0.3) the run
    ends there with its log kept (exit 3)."""
    fmus = {"a": sig(event_fmus), "b": sig(event_fmus)}
    controls = {"n": {"target": "a.i64_in", "table": [[0, -100], [0.3, 101]],
                      "interpolation": "hold"}}
    sc = scenario(tmp_path, fmus, 1.0, 0.1, [("a.small", "b.i8_in")], controls=controls,
                  log=["a.small", "b.i8_out"])
    rc, cols, summary = run(sc, tmp_path / "r")
    err = capsys.readouterr().err
    assert rc == 3 and summary["status"] == "failed", err
    assert ("key 'connections[0]': 'a.small' -> 'b.i8_in' (Int8, -100..100): the value 101 at "
            "t=0.3 is outside the input's range -100..100") in err
    assert without_progress(err).count("\n") == 1, err
    assert "log up to t=0.3 kept" in err
    assert cols["time"].tolist() == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert cols["b.i8_out"].tolist() == [-100] * 4 and cols["a.small"].tolist() == [-100] * 4


def test_a_control_out_of_an_integer_range_ends_the_run(event_fmus, tmp_path, capsys):
    controls = {"n": {"target": "a.i8_in", "table": [[0, 5], [0.2, 300]],
                      "interpolation": "hold"}}
    sc = scenario(tmp_path, {"a": sig(event_fmus)}, 1.0, 0.1, controls=controls)
    rc, cols, _ = run(sc, tmp_path / "r")
    err = capsys.readouterr().err
    assert rc == 3 and "'controls.n' -> 'a.i8_in' (Int8, -100..100): the value 300" in err
    assert cols["a.i8_out"].tolist() == [5, 5, 5]  # t = 0, 0.1, 0.2: stopped at 0.2


# ---- structural parameters --------------------------------------------------------------------

@pytest.mark.parametrize("interface", ["cs", "me"])
def test_structural_parameters_are_set_in_configuration_mode(event_fmus, tmp_path, interface):
    """FMI 3 ``k`` (structuralParameter) can only be set in configuration mode; it was set in
    the instantiated mode and refused ("can only be set in Configuration Mode")."""
    fmus = {"a": sig(event_fmus, interface=interface, parameters={"k": 3.0})}
    sc = scenario(tmp_path, fmus, 0.5, 0.1, log=["a.y"])
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0, summary
    np.testing.assert_array_equal(cols["a.y[2]"], 9.0)
    # reused instance (reset, configured again): the campaign path
    system = System(fmus={"a": FMU(str(event_fmus[("Signals", "3.0")]), interface=interface,
                                   parameters={"k": 5.0})}, step=0.1, duration=0.1)
    m = Master(system)
    try:
        for _ in range(2):
            m.reset()
            m.initialize()
            assert m.value("a.y[0]") == 5.0
    finally:
        m.close()
