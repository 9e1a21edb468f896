"""Every FMI variable type through the adapter (uwcosim.fmi.vartypes, binding, adapter).

The TypedBlock test FMU (tests/data/event_fmus) has inputs and outputs of every FMI 3 type
(FMI 2: Real/Integer/Boolean/String/Enumeration), a discrete Float64 input, a String parameter
and a Float64 array parameter. Values go in through a binding (set_inputs / do_step) and come
back through the outputs with their native Python types; start values and parameters are
checked against the declared types at load time with one-line errors.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.fmi.adapter import FMUAdapter
from uwcosim.fmi.vartypes import (
    arrow_type,
    coerce,
    connection_problem,
    describe,
    kind,
    numpy_dtype,
)

try:
    from event_fmus import VERSIONS, event_fmus
except ImportError:  # tests/ imported as a package
    from tests.event_fmus import VERSIONS, event_fmus

__all__ = ["event_fmus"]  # fixture

INPUTS = ["f32_in", "i8_in", "u16_in", "i32_in", "i64_in", "u64_in", "b_in", "mode_in", "d_in"]
OUTPUTS = ["f32_out", "i8_out", "u16_out", "i32_out", "i64_out", "u64_out", "b_out",
           "mode_out", "d_out", "y", "label_len", "gain_sum", "wraps"]


def var(type_, name="v", **kw):
    return SimpleNamespace(name=name, type=type_, declaredType=kw.pop("declaredType", None),
                           variability=kw.pop("variability", "continuous"),
                           dimensions=kw.pop("dimensions", []), shape=kw.pop("shape", ()), **kw)


# ---- vartypes: kinds, dtypes, values, connections ---------------------------------------------

def test_kinds_and_dtypes():
    assert [kind(var(t)) for t in ("Real", "Float32", "Integer", "UInt64", "Enumeration",
                                   "Boolean", "String", "Binary", "Clock")] == \
        ["float", "float", "int", "int", "int", "bool", "string", "unsupported", "unsupported"]
    assert numpy_dtype(var("Float32")) == np.float32 and numpy_dtype(var("Int8")) == np.int8
    assert numpy_dtype(var("Integer")) == np.int32 and numpy_dtype(var("UInt64")) == np.uint64
    assert numpy_dtype(var("Enumeration"), fmi3=False) == np.int32
    assert numpy_dtype(var("Enumeration"), fmi3=True) == np.int64
    assert str(arrow_type(var("Boolean"))) == "bool" and str(arrow_type(var("String"))) == \
        "string"
    assert str(arrow_type(var("UInt16"))) == "uint16"


@pytest.mark.parametrize(("type_", "value", "expected"), [
    ("Float64", 3, 3.0), ("Float32", 2.5, 2.5), ("Int8", -128, -128), ("UInt64", 2**64 - 1,
                                                                        2**64 - 1),
    ("Integer", 4.0, 4), ("Boolean", True, True), ("Boolean", 0, False), ("String", "a", "a"),
])
def test_values_are_coerced_to_the_declared_type(type_, value, expected):
    out = coerce(var(type_), value, "s.toml: key 'fmus.x.start'")
    assert out == expected and type(out) is type(expected)


@pytest.mark.parametrize(("type_", "value", "message"), [
    ("Integer", "three", "variable 'v' expects an integer (Integer), got 'three'"),
    ("Int8", 300, "out of the range -128..127 of Int8"),
    ("UInt16", -1, "out of the range 0..65535 of UInt16"),
    ("Int32", 1.5, "not a whole number"),
    ("Float64", "1.0", "expects a number (Float64)"),
    ("Float64", True, "expects a number (Float64)"),
    ("Boolean", 2, "expects true or false (Boolean)"),
    ("String", 3, "expects a string (String)"),
    ("Float64", [1.0, 2.0], "got a list"),
])
def test_wrong_kinds_are_one_line_errors(type_, value, message):
    with pytest.raises(ScenarioError, match="^s.toml: key 'fmus.x.start': ") as info:
        coerce(var(type_), value, "s.toml: key 'fmus.x.start'")
    assert message in str(info.value) and "\n" not in str(info.value)


def test_enumerations_take_item_names_and_arrays_their_shape():
    items = [SimpleNamespace(name="off", value="1"), SimpleNamespace(name="fast", value="3")]
    mode = var("Enumeration", "mode", declaredType=SimpleNamespace(name="Mode", items=items))
    assert coerce(mode, "fast", "w") == 3 and describe(mode) == "Enumeration(Mode)"
    with pytest.raises(ScenarioError, match="one of off, fast"):
        coerce(mode, "slow", "w")
    gains = var("Float64", "gains", dimensions=[SimpleNamespace(start=3)], shape=(3,))
    assert coerce(gains, [1, 2, 3], "w") == [1.0, 2.0, 3.0] and describe(gains) == "Float64[3]"
    with pytest.raises(ScenarioError, match=r"array of shape \[3\] \(3 values\), got 2"):
        coerce(gains, [1, 2], "w")


@pytest.mark.parametrize(("src", "dst", "ok"), [
    ("Float64", "Float32", True), ("Int32", "Float64", True), ("Boolean", "Int8", True),
    ("Boolean", "Real", True), ("Int64", "Int8", True), ("String", "String", True),
    ("Float64", "Int32", False), ("Real", "Boolean", False), ("Integer", "Boolean", False),
    ("String", "Real", False), ("Int32", "String", False), ("Binary", "Binary", False),
])
def test_connection_type_rules(src, dst, ok):
    problem = connection_problem(var(src, "a.y"), var(dst, "b.u"))
    assert (problem is None) == ok
    if not ok:
        assert "'a.y'" in problem or "'b.u'" in problem


# ---- TypedBlock through the adapter ---------------------------------------------------------

def _expected(v: dict, fmi3: bool) -> dict:
    """TypedBlock's outputs for the inputs ``v`` (README of tests/data/event_fmus)."""
    f32 = np.float32(2) * np.float32(v["f32_in"]) + np.float32(0.5) if fmi3 else \
        2 * v["f32_in"] + 0.5
    return {"f32_out": float(f32), "i8_out": v["i8_in"], "u16_out": (v["u16_in"] + 1) % 65536,
            "i32_out": v["i32_in"] + 1, "i64_out": 2 * v["i64_in"], "u64_out": v["u64_in"] + 1,
            "b_out": not v["b_in"], "mode_out": v["mode_in"], "d_out": v["d_in"]}


@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("version", VERSIONS)
def test_every_type_round_trips(event_fmus, version, interface):
    fmi3 = version == "3.0"
    ad = FMUAdapter("tb", event_fmus[("TypedBlock", version)], interface)
    try:
        assert ad.outputs() == OUTPUTS
        b_in, b_out = ad.bind(INPUTS), ad.bind(OUTPUTS)
        params = {"label": "abcd", **({"gains": [2, 3, 4.5]} if fmi3 else {"gains[2]": 7})}
        ad.instantiate(params, {"f32_in": 2.25}, 0.0, 2.0)  # a Float32 start value
        ad.get_outputs(b_out, 0.0)
        out = dict(zip(OUTPUTS, b_out.native()))
        assert out["f32_out"] == 5.0 and out["label_len"] == 4
        assert out["gain_sum"] == (9.5 if fmi3 else 1 + 7 + 3)
        if fmi3:  # 64-bit start values beyond 2**53 come back exact
            assert out["u64_out"] == 2**53 + 2 and out["i64_out"] == -10_000_000_000
        values = {"f32_in": -1.75, "i8_in": -7, "u16_in": 65535, "i32_in": 100, "i64_in": -21,
                  "u64_in": 99, "b_in": True, "mode_in": 3, "d_in": 0.25}
        b_in.view[:] = [float(values[n]) for n in INPUTS]
        h = 0.1
        for k in range(5):
            reached = ad.do_step(k * h, (k + 1) * h - k * h, b_in, None)
        ad.get_outputs(b_out, reached)
        out = dict(zip(OUTPUTS, b_out.native()))
        for name, want in _expected(values, fmi3).items():
            assert out[name] == want and type(out[name]) is type(want), name
        assert out["y"] == pytest.approx(0.5 * 0.25 + 0.0, abs=1e-12)  # 0.5 s of d_in
        assert isinstance(out["label_len"], int) and isinstance(out["gain_sum"], float)
        assert b_in.native()[INPUTS.index("b_in")] is True
        got = ad.get_values(["label", "f32_in"] + (["gains"] if fmi3 else []))
        assert got["label"] == "abcd" and got["f32_in"] == -1.75
        if fmi3:
            assert got["gains"] == [2.0, 3.0, 4.5]
    finally:
        ad.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_wrong_start_values_are_refused_before_the_run(event_fmus, version):
    ad = FMUAdapter("tb", event_fmus[("TypedBlock", version)], "cs")
    try:
        with pytest.raises(ScenarioError, match="variable 'label' expects a string"):
            ad.instantiate({"label": 3}, {}, 0.0, 1.0)
        with pytest.raises(ScenarioError, match="variable 'i32_in' expects an integer"):
            ad.check_values({"i32_in": "x"}, "s.toml: key 'fmus.tb.start'")
        with pytest.raises(ScenarioError, match="variable 'b_in' expects true or false"):
            ad.check_values({"b_in": 0.5})
        assert ad.check_values({"mode_in": "fast"}) == {"mode_in": 3}
        if version == "3.0":
            with pytest.raises(ScenarioError, match="out of the range -128..127 of Int8"):
                ad.check_values({"i8_in": 128})
            b = ad.bind(["gains", "label_len"])  # arrays bind: one position per element
            assert (b.n, b.sizes, b.offsets) == (4, (3, 1), (0, 3))
        with pytest.raises(FMUError, match="has no variable 'nope'"):
            ad.check_values({"nope": 1})
    finally:
        ad.close()


def test_fmu_info_shows_every_type(event_fmus):
    from uwcosim.fmu.info import fmu_info

    rows = {line.split()[0]: line.split()[3] for line in
            fmu_info(event_fmus[("TypedBlock", "3.0")]).splitlines()
            if line.startswith("    ") and len(line.split()) > 3}
    assert rows["f32_in"] == "Float32" and rows["u64_out"] == "UInt64"
    assert rows["mode_in"] == "Enumeration(Mode)" and rows["gains"] == "Float64[3]"
    assert rows["label"] == "String" and rows["b_in"] == "Boolean" and rows["i8_in"] == "Int8"
