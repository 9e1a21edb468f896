"""FMI variable types: what kind of value each declared type holds, and how to check values.

Works on fmpy's model-description variables (``var.type`` is the declared FMI type name), so
it needs no FMU instance: the scenario loader and the master use it for load-time checks.

========================  =========  ==================================  ==================
FMI 2.0 / FMI 3.0 type    kind       C type (fmpy get/set function)      numpy / Arrow type
========================  =========  ==================================  ==================
Real / Float64            float      double (GetReal / GetFloat64)       float64
Float32 (FMI 3)           float      float (GetFloat32)                  float32
Integer (FMI 2)           int        int (GetInteger)                    int32
Int8 ... UInt64 (FMI 3)   int        int8_t ... uint64_t (GetInt8 ...)   int8 ... uint64
Enumeration               int        FMI 2 int, FMI 3 int64              int32 / int64
Boolean                   bool       FMI 2 int, FMI 3 bool               bool
String                    string     char* (GetString)                   string
Binary, Clock (FMI 3)     -          not supported                       -
========================  =========  ==================================  ==================

Connections: a value may go to a variable of the same kind or a wider one (bool -> int ->
float); float to int or bool, and anything to or from a string, is refused
(:func:`connection_problem`). Between integer types the ranges are checked too
(:func:`range_problem`): the source's range (its declared ``min``/``max``, else its type's)
must fit the destination's, and when only the declaration makes it fit (an Int64 output
declared ``-100..100`` into an Int8 input) the values are checked at run time.

FMI 3 arrays: :func:`size` values per variable, row-major; an element is named
``var[i]`` (``var[i,j]`` for more dimensions, 0-based) in signal names (:func:`split_element`,
:func:`flat_index`; the log's column names are built by :mod:`uwcosim.runlog.columns`).
"""

from __future__ import annotations

import ctypes
import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pyarrow as pa
    from fmpy.model_description import ModelVariable

import numpy as np

from uwcosim.core.errors import ScenarioError

#: FMI 3 type -> (kind, ctypes type, fmpy function suffix, numpy dtype)
FMI3_TYPES: dict[str, tuple[str, object, str, str]] = {
    "Float64": ("float", ctypes.c_double, "Float64", "float64"),
    "Float32": ("float", ctypes.c_float, "Float32", "float32"),
    "Int8": ("int", ctypes.c_int8, "Int8", "int8"),
    "UInt8": ("int", ctypes.c_uint8, "UInt8", "uint8"),
    "Int16": ("int", ctypes.c_int16, "Int16", "int16"),
    "UInt16": ("int", ctypes.c_uint16, "UInt16", "uint16"),
    "Int32": ("int", ctypes.c_int32, "Int32", "int32"),
    "UInt32": ("int", ctypes.c_uint32, "UInt32", "uint32"),
    "Int64": ("int", ctypes.c_int64, "Int64", "int64"),
    "UInt64": ("int", ctypes.c_uint64, "UInt64", "uint64"),
    "Enumeration": ("int", ctypes.c_int64, "Int64", "int64"),
    "Boolean": ("bool", ctypes.c_bool, "Boolean", "bool"),
    "String": ("string", ctypes.c_char_p, "String", "object"),
}
#: FMI 2 type -> (kind, ctypes type, fmpy function suffix, numpy dtype)
FMI2_TYPES: dict[str, tuple[str, object, str, str]] = {
    "Real": ("float", ctypes.c_double, "Real", "float64"),
    "Integer": ("int", ctypes.c_int, "Integer", "int32"),
    "Enumeration": ("int", ctypes.c_int, "Integer", "int32"),
    "Boolean": ("bool", ctypes.c_int, "Boolean", "bool"),
    "String": ("string", ctypes.c_char_p, "String", "object"),
}
FLOAT64 = ("Real", "Float64")
_RANK = {"bool": 0, "int": 1, "float": 2}


def type_info(var: ModelVariable, fmi3: bool) -> tuple[str, object, str, str] | None:
    """``(kind, ctypes type, fmpy suffix, numpy dtype)`` of ``var`` or None (unsupported)."""
    return (FMI3_TYPES if fmi3 else FMI2_TYPES).get(var.type)


def kind(var: ModelVariable) -> str:
    """``"float"``, ``"int"`` (Enumeration too), ``"bool"``, ``"string"`` or
    ``"unsupported"`` (FMI 3 Binary and Clock)."""
    info = FMI3_TYPES.get(var.type) or FMI2_TYPES.get(var.type)
    return info[0] if info else "unsupported"


def numpy_dtype(var: ModelVariable, fmi3: bool | None = None) -> np.dtype:
    """The numpy dtype of the variable's values (``object`` for strings)."""
    if fmi3 is None:  # unknown version: Real/Integer are FMI 2, the rest as in FMI 3 (wider)
        fmi3 = var.type not in ("Real", "Integer")
    info = (FMI3_TYPES if fmi3 else FMI2_TYPES).get(var.type)
    if info is None:
        raise ValueError(f"variable {var.name!r}: type {var.type} is not supported")
    return np.dtype(info[3])


def arrow_type(var: ModelVariable, fmi3: bool | None = None) -> pa.DataType:
    """The pyarrow type of a log column for the variable."""
    import pyarrow as pa  # lazy: pyarrow (0.15 s) only for the log's schema

    dt = numpy_dtype(var, fmi3)
    return pa.string() if dt == np.dtype(object) else pa.from_numpy_dtype(dt)


def shape(var: ModelVariable) -> tuple[int, ...]:
    """The array shape of an FMI 3 array variable (``()`` for a scalar)."""
    return tuple(getattr(var, "shape", None) or ())


def is_array(var: ModelVariable) -> bool:
    return bool(getattr(var, "dimensions", None))


def bindable(var: ModelVariable) -> bool:
    """Can the master connect and log the variable (a supported type; an array of one that
    is not String)?"""
    k = kind(var)
    return k != "unsupported" and not (k == "string" and is_array(var))


def size(var: ModelVariable) -> int:
    """The number of values of the variable (1 for a scalar)."""
    return int(np.prod(shape(var))) if is_array(var) else 1


def split_element(name: str) -> tuple[str, tuple[int, ...]] | None:
    """``"y[1]"`` -> ``("y", (1,))``, ``"M[1,2]"`` -> ``("M", (1, 2))``; None if ``name`` does
    not end with an element index."""
    if not name.endswith("]") or "[" not in name:
        return None
    base, _, idx = name[:-1].rpartition("[")
    try:
        index = tuple(int(p) for p in idx.split(","))
    except ValueError:
        return None
    return (base, index) if base else None


def flat_index(var: ModelVariable, index: tuple[int, ...]) -> int:
    """The row-major position of element ``index`` of the array variable ``var``;
    ValueError saying the valid range otherwise."""
    dims = shape(var)
    if len(index) == 1 and len(dims) > 1:  # a flat index into a multi-dimensional array
        dims = (int(np.prod(dims)),)
    if len(index) != len(dims) or any(not 0 <= i < d for i, d in zip(index, dims)):
        raise ValueError(f"index [{','.join(map(str, index))}] is outside the shape "
                         f"{list(shape(var))} (indices start at 0)")
    return int(np.ravel_multi_index(index, dims)) if dims else 0


def describe(var: ModelVariable) -> str:
    """``Float64``, ``Float64[3]``, ``Enumeration(Mode)``: the type as ``fmu info`` shows it."""
    s = var.type
    if var.type == "Enumeration" and var.declaredType is not None:
        s += f"({var.declaredType.name})"
    dims = shape(var)
    if getattr(var, "dimensions", None):
        s += "[" + ",".join(str(d) for d in dims) + "]"
    return s


def connection_problem(src: ModelVariable, dst: ModelVariable) -> str | None:
    """Why the output ``src`` cannot drive the input ``dst`` (None: it can)."""
    ks, kd = kind(src), kind(dst)
    if "unsupported" in (ks, kd):
        bad = src if ks == "unsupported" else dst
        return f"{bad.name!r} has type {bad.type}, which the master does not support"
    if ks == kd:
        return None
    if "string" in (ks, kd):
        return f"cannot connect {src.type} {src.name!r} to {dst.type} {dst.name!r} " \
               f"(a String connects only to a String)"
    if _RANK[ks] < _RANK[kd]:
        return None
    return (f"cannot connect {src.type} {src.name!r} to {dst.type} {dst.name!r} "
            f"({ks} to {kd} would lose information; only bool -> int -> float is allowed)")


def int_range(var: ModelVariable) -> tuple[int, int]:
    """The range of the variable's integer type (Enumeration: Int64's in FMI 3)."""
    t = var.type
    if t in ("Integer", "Int32") or (t == "Enumeration"):
        lo, hi = -(2**31), 2**31 - 1
        if t == "Enumeration":
            lo, hi = -(2**63), 2**63 - 1
        return lo, hi
    bits = int("".join(c for c in t if c.isdigit()))
    if t.startswith("U"):
        return 0, 2**bits - 1
    return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1


def declared_range(var: ModelVariable) -> tuple[int, int] | None:
    """``(lo, hi)`` of an integer variable: its declared ``min``/``max`` within its type's
    range (None for a non-integer)."""
    if kind(var) == "bool":
        return 0, 1
    if kind(var) != "int":
        return None
    lo, hi = int_range(var)
    for attr, pick in (("min", max), ("max", min)):
        text = getattr(var, attr, None)
        if text not in (None, ""):
            try:
                v = int(str(text).strip())
            except ValueError:
                v = int(float(text))
            if attr == "min":
                lo = pick(lo, v)
            else:
                hi = pick(hi, v)
    return lo, hi


def range_problem(src: ModelVariable | None, dst: ModelVariable) -> tuple[str | None, bool]:
    """Whether the values of ``src`` (None: a float source of the master) fit the integer
    input ``dst``: ``(problem, checked)``; ``problem`` says why not (the source's declared range
    does not fit), ``checked`` is True when the values must be checked at run time (a float
    source, or a source whose type's range does not fit but whose declared range does)."""
    d = declared_range(dst)
    if d is None or kind(dst) == "bool":
        return None, False
    if src is None or kind(src) == "float":
        return None, True
    s = declared_range(src)
    if s is None:
        return None, False
    if not (d[0] <= s[0] and s[1] <= d[1]):
        return (f"the values of {src.type} {src.name!r} ({s[0]}..{s[1]}) do not fit "
                f"{dst.type} {dst.name!r} ({d[0]}..{d[1]}); declare min/max on the output "
                f"that fit, or connect it to a wider input"), False
    t = int_range(src) if kind(src) == "int" else (0, 1)
    return None, not (d[0] <= t[0] and t[1] <= d[1])


def _expected(var) -> str:
    k = kind(var)
    if var.type == "Enumeration":
        items = [i.name for i in (var.declaredType.items if var.declaredType else [])]
        return "an integer" + (f" or one of {', '.join(items)}" if items else "") + \
            " (Enumeration)"
    return {"float": f"a number ({var.type})", "int": f"an integer ({var.type})",
            "bool": "true or false (Boolean)", "string": "a string (String)"}.get(k, var.type)


def _scalar(var, value, where: str):
    k = kind(var)

    def bad(reason: str = "") -> ScenarioError:
        return ScenarioError(f"{where}: variable {var.name!r} expects {_expected(var)}, got "
                             f"{value!r}{reason}")

    if k == "float":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise bad()
        return float(value)
    if k == "int":
        if var.type == "Enumeration" and isinstance(value, str) and var.declaredType:
            for item in var.declaredType.items:
                if item.name == value:
                    return int(item.value)
            raise bad()
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise bad()
        if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
            raise bad(" (not a whole number)")
        value_i = int(value)
        lo, hi = int_range(var)
        if not lo <= value_i <= hi:
            raise bad(f" (out of the range {lo}..{hi} of {var.type})")
        return value_i
    if k == "bool":
        if isinstance(value, bool):
            return value
        if isinstance(value, int | float) and value in (0, 1):
            return bool(value)
        raise bad()
    if k == "string":
        if not isinstance(value, str):
            raise bad()
        return value
    raise ScenarioError(f"{where}: variable {var.name!r} has type {var.type}, which the master "
                        f"cannot set")


def coerce(var: ModelVariable, value: object, where: str) -> object:
    """``value`` (from TOML or Python) checked against ``var``'s declared type and converted to
    the native Python value (a list for an FMI 3 array); one-line :class:`ScenarioError`
    naming the variable and the expected type otherwise."""
    dims = shape(var)
    if getattr(var, "dimensions", None):
        if isinstance(value, np.ndarray):
            value = value.ravel().tolist()
        if not isinstance(value, list | tuple):
            value = [value]
        flat = _flatten(value)
        n = int(np.prod(dims)) if dims else len(flat)
        if len(flat) != n:
            raise ScenarioError(f"{where}: variable {var.name!r} is an array of shape "
                                f"{list(dims)} ({n} values), got {len(flat)} values")
        return [_scalar(var, v, where) for v in flat]
    if isinstance(value, list | tuple):
        raise ScenarioError(f"{where}: variable {var.name!r} expects {_expected(var)}, got a "
                            f"list")
    return _scalar(var, value, where)


def _flatten(value) -> list:
    out = []
    for v in value:
        out += _flatten(v) if isinstance(v, list | tuple) else [v]
    return out


def is_continuous_input(var: ModelVariable) -> bool:
    """Model exchange: can the input be set in continuous-time mode (a continuous float)?"""
    return kind(var) == "float" and (var.variability or "continuous") == "continuous"
