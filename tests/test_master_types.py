"""Every FMI variable type at the master level, through `uwcosim run` of plain scenarios.

TypedBlock (tests/data/event_fmus) has an input and an output of every FMI 2.0 / 3.0 type, a
String parameter, an FMI 3 Float64 array parameter and a discrete Real input. Start values come
from TOML (ints, bools, strings, floats, arrays), outputs are logged as Parquet columns of the
matching Arrow type and compared with fmpy.simulate_fmu on the same FMU.
"""

from __future__ import annotations

import fmpy
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_system import run, scenario

from uwcosim.cli import main

try:
    from event_fmus import event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover
    from tests.event_fmus import event_fmus  # noqa: F401

OUTPUTS = ["f32_out", "i8_out", "u16_out", "i32_out", "i64_out", "u64_out", "b_out", "mode_out",
           "d_out", "label_len", "gain_sum"]
#: inputs at the ends of their ranges (FMI 2 Integers are 32 bits)
START = {
    "2.0": {"f32_in": 0.1, "i8_in": -128, "u16_in": 65535, "i32_in": 2**31 - 1,
            "i64_in": 2**30, "u64_in": 2**31 - 1, "b_in": True, "mode_in": 3, "d_in": -2.0},
    "3.0": {"f32_in": 0.1, "i8_in": -128, "u16_in": 65535, "i32_in": 2**31 - 1,
            "i64_in": -(2**62) - 1, "u64_in": 2**64 - 1, "b_in": True, "mode_in": 3,
            "d_in": -2.0},
}
PARAMS = {"2.0": {"label": "abcdef", "gains[2]": -0.5},
          "3.0": {"label": "abcdef", "gains": [0.5, 0.25, 4.0]}}
ARROW = {  # Arrow type of each output column
    "2.0": dict(f32_out=pa.float64(), i8_out=pa.int32(), u16_out=pa.int32(), i32_out=pa.int32(),
                i64_out=pa.int32(), u64_out=pa.int32(), b_out=pa.bool_(), mode_out=pa.int64(),
                d_out=pa.float64(), label_len=pa.int32(), gain_sum=pa.float64()),
    "3.0": dict(f32_out=pa.float32(), i8_out=pa.int8(), u16_out=pa.uint16(),
                i32_out=pa.int32(), i64_out=pa.int64(), u64_out=pa.uint64(), b_out=pa.bool_(),
                mode_out=pa.int64(), d_out=pa.float64(), label_len=pa.int32(),
                gain_sum=pa.float64()),
}


def _wrap(x: int, bits: int) -> int:
    return (x + 2 ** (bits - 1)) % 2**bits - 2 ** (bits - 1)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("interface", ["cs", "me"])
def test_start_values_of_every_type_and_typed_columns(event_fmus, tmp_path, version, interface):
    path = event_fmus[("TypedBlock", version)]
    # the TOML start values: the inputs are constant (no driver), the FMU holds them
    sc = scenario(tmp_path, {"tb": {"path": path, "interface": interface,
                                    "start": START[version], "parameters": PARAMS[version]}},
                  1.0, 0.1, log=[f"tb.{o}" for o in OUTPUTS] + ["tb.y"])
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    schema = pq.read_schema(tmp_path / "r/log.parquet")
    for name, typ in ARROW[version].items():
        assert schema.field(f"tb.{name}").type == typ, name
    s = START[version]
    v3 = version == "3.0"
    expected = {
        "i8_out": s["i8_in"], "u16_out": (s["u16_in"] + 1) % 65536,
        "i32_out": _wrap(s["i32_in"] + 1, 32), "i64_out": _wrap(2 * s["i64_in"], 64 if v3 else 32),
        "u64_out": (s["u64_in"] + 1) % 2**64 if v3 else _wrap(s["u64_in"] + 1, 32),
        "b_out": False, "mode_out": 3, "d_out": -2.0, "label_len": 6,
        "gain_sum": 4.75 if v3 else 1.0 - 0.5 + 3.0,
    }
    table = pq.read_table(tmp_path / "r/log.parquet")
    for name, value in expected.items():
        # exact, Int64 and UInt64 beyond 2**53 included (they are logged from native values)
        assert table.column(f"tb.{name}").to_pylist() == [value] * 11, name
    f32 = np.float32(2.0) * np.float32(0.1) + np.float32(0.5)
    np.testing.assert_array_equal(cols["tb.f32_out"], f32 if v3 else 2 * 0.1 + 0.5)
    # y integrates d_in = -2
    np.testing.assert_allclose(cols["tb.y"], -2.0 * cols["time"], rtol=0, atol=1e-9)
    # fmpy with the same start values gives the same outputs
    ref = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation" if interface == "cs" else
                            "ModelExchange", stop_time=1.0, output_interval=0.1,
                            start_values={k: np.array(v) if isinstance(v, list) else v
                                          for k, v in {**s, **PARAMS[version]}.items()},
                            output=OUTPUTS)
    for name in OUTPUTS:
        r = ref[name]
        if name in ("i64_out", "u64_out"):  # fmpy's recorder: exact ints too
            assert [int(x) for x in r[-1:]] == [table.column(f"tb.{name}")[-1].as_py()]
        else:
            assert cols[f"tb.{name}"][-1] == r[-1], name


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_controls_drive_integer_boolean_and_discrete_inputs(event_fmus, tmp_path, interface):
    """Held tables into Int8/Boolean/Enumeration and the discrete Real input: in model exchange
    these are set at communication points only (the FMU refuses them otherwise)."""
    path = event_fmus[("TypedBlock", "3.0")]
    controls = {
        "i8": {"target": "tb.i8_in", "table": [[0, 1], [0.5, -7]], "interpolation": "hold"},
        "b": {"target": "tb.b_in", "table": [[0, 0], [0.3, 1]], "interpolation": "hold"},
        "m": {"target": "tb.mode_in", "table": [[0, 1], [0.6, 3]], "interpolation": "hold"},
        # a linear table into a discrete Real input: still set at communication points only
        "d": {"target": "tb.d_in", "table": [[0, 1.0], [0.45, 1.0], [0.5, 3.0]]},
        "f": {"target": "tb.f32_in", "table": [[0, 0.0], [1, 1.0]]},
    }
    sc = scenario(tmp_path, {"tb": {"path": path, "interface": interface}}, 1.0, 0.1,
                  controls=controls,
                  sensors={"s": {"outputs": ["tb.i8_out", "tb.b_out", "tb.f32_out"]}})
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    t = cols["time"]
    tk = np.concatenate([t[:1], t[:-1]])  # the input of the row at t_{k+1} was set at t_k
    np.testing.assert_array_equal(cols["tb.i8_out"], np.where(tk < 0.5 - 1e-9, 1, -7))
    np.testing.assert_array_equal(cols["tb.b_out"], ~(tk >= 0.3 - 1e-9))
    np.testing.assert_array_equal(cols["tb.mode_out"], np.where(tk < 0.6 - 1e-9, 1, 3))
    np.testing.assert_array_equal(cols["tb.d_out"], np.where(tk < 0.5 - 1e-9, 1.0, 3.0))
    # y integrates d_in held over each step: 1 until 0.5 then 3
    np.testing.assert_allclose(cols["tb.y"], np.where(t <= 0.5, t, 0.5 + 3 * (t - 0.5)),
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize(("key", "value", "message"), [
    ("start", {"i8_in": 300}, "'i8_in'"),
    ("start", {"b_in": "yes"}, "'b_in'"),
    ("parameters", {"gains": [1.0, 2.0]}, "'gains'"),
    ("parameters", {"label": 3}, "'label'"),
])
def test_bad_start_values_are_one_line(event_fmus, tmp_path, capsys, key, value, message):
    path = event_fmus[("TypedBlock", "3.0")]
    sc = scenario(tmp_path, {"tb": {"path": path, key: value}}, 1.0, 0.1)
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"key 'fmus.tb.{key}'" in err and message in err


@pytest.mark.parametrize(("section", "entry", "message"), [
    ("controls", {"target": "tb.i8_in", "table": [[0, 1], [1, 2]]},
     "interpolation = \"hold\""),
    ("controls", {"target": "tb.i8_in", "table": [[0, 1.5]], "interpolation": "hold"},
     "whole-number"),
    ("noise", {"targets": ["tb.i32_in"], "psd": [1.0]}, "noise drives only Real"),
])
def test_sources_into_non_real_inputs_are_checked(event_fmus, tmp_path, capsys, section, entry,
                                                  message):
    path = event_fmus[("TypedBlock", "3.0")]
    sc = scenario(tmp_path, {"tb": {"path": path}}, 1.0, 0.1, **{section: {"x": entry}})
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"key '{section}.x" in err and message in err


def test_run_logger_typed_columns(tmp_path):
    """String, UInt64 (beyond 2**53) and the narrow types, written across row groups."""
    from uwcosim.runlog import RunLogger, read_log

    dtypes = {"s": object, "u": np.uint64, "i": np.int8, "b": np.bool_, "f": np.float32}
    log = RunLogger(tmp_path / "l.parquet", ["x", "s", "u", "i", "b", "f"], ["flag"], {}, 2,
                    dtypes)
    assert log.exact_columns == ["s", "u"]
    for k in range(5):
        log.append(np.array([0.1 * k, 1.5, np.nan, np.nan, -k, k % 2, 0.1]), np.array([True]),
                   [f"v{k}", 2**64 - 1 - k])
    log.close()
    table = pq.read_table(tmp_path / "l.parquet")
    assert [str(table.schema.field(c).type) for c in table.column_names] == [
        "double", "double", "string", "uint64", "int8", "bool", "float", "bool"]
    assert table.column("s").to_pylist() == [f"v{k}" for k in range(5)]
    assert table.column("u").to_pylist() == [2**64 - 1 - k for k in range(5)]
    assert table.column("i").to_pylist() == [0, -1, -2, -3, -4]
    cols, _ = read_log(tmp_path / "l.parquet")
    assert cols["f"].dtype == np.float32 and cols["f"][0] == np.float32(0.1)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("interface", ["cs", "me"])
def test_step_events_through_the_master(event_fmus, tmp_path, version, interface):
    """TypedBlock with ``y_wrap``: completedIntegratorStep asks for an event once y >= y_wrap
    (ME; CS handles it inside doStep); the event update wraps y and counts."""
    path = event_fmus[("TypedBlock", version)]
    sc = scenario(tmp_path, {"tb": {"path": path, "interface": interface,
                                    "parameters": {"y_wrap": 0.3}}}, 2.0, 0.01,
                  log=["tb.y", "tb.wraps"])
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    t, y, wraps = cols["time"], cols["tb.y"], cols["tb.wraps"]
    # y integrates d_in = 0.5: y + wraps * y_wrap = 0.5 t; y stays below y_wrap
    np.testing.assert_allclose(y + 0.3 * wraps, 0.5 * t, rtol=0, atol=1e-9)
    assert wraps[-1] == 3 and y.max() < 0.3 + 0.5 * 0.01 and wraps.dtype == np.int32


@pytest.fixture(scope="module")
def shout_fmu(tmp_path_factory):
    """``Shout.fmu``: String input and outputs (pythonfmu, FMI 2.0 co-simulation)."""
    import subprocess
    import sys
    from pathlib import Path

    pytest.importorskip("pythonfmu", reason="pythonfmu is not installed")
    src = Path(__file__).resolve().parent / "data" / "pythonfmu_strings" / "Shout.py"
    out = tmp_path_factory.mktemp("shout")
    r = subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(src), "-d",
                        str(out)], capture_output=True, text=True, cwd=out, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return out / "Shout.fmu"


def test_string_connections_and_columns(shout_fmu, tmp_path):
    fmus = {"a": {"path": shout_fmu, "parameters": {"prefix": "hey "}},
            "b": {"path": shout_fmu, "start": {"s_in": "unused"}}}
    sc = scenario(tmp_path, fmus, 0.3, 0.1, connections=[("a.s_out", "b.s_in")])
    rc, _, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    table = pq.read_table(tmp_path / "r/log.parquet")
    assert table.schema.field("a.s_out").type == pa.string()
    assert table.schema.field("a.n").type == pa.int32()
    assert table.column("a.s_out").to_pylist() == ["HEY ABC"] * 4
    # Gauss-Seidel: b reads a's String output of the same communication point
    assert table.column("b.s_out").to_pylist() == ["HEY ABC"] * 4
    assert table.column("b.n").to_pylist() == [7] * 4
    assert table.column("a.t_str").to_pylist() == ["t=0.00", "t=0.10", "t=0.20", "t=0.30"]


@pytest.mark.parametrize(("extra", "message"), [
    ({"connections": [("a.s_out", "b.prefix")]}, "has causality 'parameter'"),
    ({"connections": [("a.n", "b.s_in")]}, "a String connects only to a String"),
    ({"sensors": {"s": {"outputs": ["a.s_out"]}}}, "is a String output"),
])
def test_string_misuse_is_one_line(shout_fmu, tmp_path, capsys, extra, message):
    fmus = {"a": {"path": shout_fmu}, "b": {"path": shout_fmu}}
    sc = scenario(tmp_path, fmus, 0.3, 0.1, **extra)
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_boolean_and_enumeration_connections(event_fmus, tmp_path, interface):
    """Feedthrough (FMI 2) Boolean and Integer outputs into TypedBlock (FMI 3) Boolean and
    Enumeration inputs; the Boolean also into a Float64 input (allowed)."""
    fmus = {"ft": {"path": event_fmus[("Feedthrough", "2.0")]},
            "tb": {"path": event_fmus[("TypedBlock", "3.0")], "interface": interface}}
    controls = {"b": {"target": "ft.bu", "table": [[0, 0], [0.25, 1], [0.55, 0]],
                      "interpolation": "hold"},
                "i": {"target": "ft.iu", "table": [[0, 1], [0.45, 3]], "interpolation": "hold"}}
    conns = [("ft.by", "tb.b_in"), ("ft.iy", "tb.mode_in"), ("ft.by", "tb.d_in")]
    sc = scenario(tmp_path, fmus, 1.0, 0.1, connections=conns, controls=controls)
    rc, cols, _ = run(sc, tmp_path / "r")
    assert rc == 0
    np.testing.assert_array_equal(cols["tb.b_out"], ~cols["ft.by"])
    np.testing.assert_array_equal(cols["tb.mode_out"], cols["ft.iy"])
    np.testing.assert_array_equal(cols["tb.d_out"], cols["ft.by"].astype(float))
    assert cols["ft.by"].any() and not cols["ft.by"].all()
