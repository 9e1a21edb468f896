"""Value references and value buffers ready for the get and set calls of one FMU.

A :class:`Binding` is made once per group of variables (an FMU's inputs, its outputs) by
:meth:`~uwcosim.fmi.adapter.FMUAdapter.bind`; a step then costs only the FMI calls. Values
are exchanged with the master in ``view``, a float64 array in our units (the master's bus).

- Fast path: every member is Real/Float64 (and, for model exchange, a continuous input):
  ``vr``/``buf`` hold one ``GetReal``/``GetFloat64`` call and ``view`` is a numpy view on
  ``buf`` (no copy).
- Typed path: the members are split into :class:`Group` s of one FMI type (one
  ``fmi3GetInt8``, ``fmi2GetBoolean``... call each) with their own ctypes buffers; values are
  converted to and from ``view`` (integers rounded, booleans as 0/1, strings are NaN in
  ``view`` and their text is in ``text``). :meth:`Binding.native` gives the exact native values
  (an Int64 beyond 2**53 included) of the last get or set.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from uwcosim.fmi.vartypes import FLOAT64, kind, type_info


@dataclass
class Group:
    """Members of one FMI type (and, for model exchange, one input mode)."""

    idx: np.ndarray  # positions in the binding
    vr: ctypes.Array
    buf: ctypes.Array
    arr: np.ndarray | None  # numpy view on buf; None for strings
    kind: str  # float/int/bool/string
    get: Callable
    set: Callable
    discrete: bool = False  # model exchange: set in event mode only
    last: object = None  # model exchange discrete inputs: the values last set

    @property
    def n(self) -> int:
        return len(self.idx)


@dataclass
class Binding:
    """Value references and a value buffer ready for one get or set call.

    ``view`` holds the values in our units, ``raw`` (on the fast path a numpy view on the
    ctypes buffer) in the FMU's. Without a unit conversion they are the same array; with one (a
    variable map), ``ours = scale * theirs + offset`` is applied to the whole vector in one numpy
    operation.
    """

    names: tuple[str, ...]
    vr: ctypes.Array | None
    buf: ctypes.Array | None
    view: np.ndarray  # values in our units
    raw: np.ndarray | None = None  # values in FMU units; None: same as view
    scale: np.ndarray | None = None  # None: identity conversion
    offset: np.ndarray | None = None
    groups: tuple[Group, ...] = ()  # empty: the fast path (vr/buf)
    kinds: tuple[str, ...] = ()  # float/int/bool/string per member
    types: tuple[str, ...] = ()  # declared FMI type per member
    text: dict[int, str] = field(default_factory=dict)  # String members: index -> value
    n: int = field(init=False)  # number of members (an attribute: read on every call)

    def __post_init__(self) -> None:
        self.n = len(self.names)

    @property
    def discrete_groups(self) -> tuple[Group, ...]:
        return tuple(g for g in self.groups if g.discrete)

    @property
    def continuous_groups(self) -> tuple[Group, ...]:
        return tuple(g for g in self.groups if not g.discrete)

    @classmethod
    def plain(cls, names, kinds=None, types=None) -> Binding:
        """A binding without FMU buffers (values only), e.g. for an out-of-process FMU."""
        names = tuple(names)
        return cls(names, None, None, np.zeros(len(names)),
                   kinds=tuple(kinds or ("float",) * len(names)),
                   types=tuple(types or ("Real",) * len(names)))

    def to_fmu(self) -> None:
        if self.scale is not None:
            np.subtract(self.view, self.offset, out=self.raw)
            np.divide(self.raw, self.scale, out=self.raw)

    def from_fmu(self) -> None:
        if self.scale is not None:
            np.multiply(self.raw, self.scale, out=self.view)
            np.add(self.view, self.offset, out=self.view)

    def native(self) -> list:
        """The values of the last get/set as Python ``float``/``int``/``bool``/``str``."""
        out: list = [float(v) for v in self.view]
        if self.groups:
            for g in self.groups:
                for j, i in enumerate(g.idx):
                    if g.kind == "int":
                        out[i] = int(g.arr[j])
                    elif g.kind == "bool":
                        out[i] = bool(g.arr[j])
                    elif g.kind == "string":
                        out[i] = self.text.get(int(i), "")
            return out
        for i, k in enumerate(self.kinds):
            if k == "int":
                out[i] = int(self.view[i])
            elif k == "bool":
                out[i] = bool(self.view[i])
            elif k == "string":
                out[i] = self.text.get(i, "")
        return out

    # -- typed path: view <-> group buffers ---------------------------------------------------
    def groups_to_raw(self) -> None:
        """After the get calls: group buffers -> ``raw`` -> ``view``."""
        raw = self.view if self.raw is None else self.raw
        for g in self.groups:
            if g.kind == "string":
                for j, i in enumerate(g.idx):
                    v = g.buf[j]
                    self.text[int(i)] = v.decode("utf-8", "replace") if v is not None else ""
                    raw[i] = np.nan
            else:
                raw[g.idx] = g.arr
        self.from_fmu()

    def raw_to_group(self, g: Group) -> None:
        """Before a set call: ``view`` -> ``raw`` -> the group's buffer."""
        raw = self.view if self.raw is None else self.raw
        vals = raw[g.idx]
        if g.kind == "float":
            g.arr[:] = vals
        elif g.kind == "int":
            g.arr[:] = np.rint(vals)
        elif g.kind == "bool":
            g.arr[:] = vals != 0
        else:
            for j, i in enumerate(g.idx):
                g.buf[j] = self.text.get(int(i), "").encode("utf-8")


def make_binding(names: tuple[str, ...], variables: list, affine: list[tuple[float, float]],
                 fmi3: bool, discrete: list[bool]) -> Binding:
    """The binding of ``variables`` (exposed as ``names``; ``ours = a*theirs + b`` per member
    from ``affine``; ``discrete``: model-exchange inputs to set in event mode only). Typed
    groups hold the fmpy function *names* (``fmi3GetInt8``...) until the library is loaded."""
    n = len(names)
    kinds = tuple(kind(v) for v in variables)
    types = tuple(v.type for v in variables)
    identity = all(a == (1.0, 0.0) for a in affine)
    scale = None if identity else np.array([a[0] for a in affine])
    offset = None if identity else np.array([a[1] for a in affine])
    vr_t = ctypes.c_uint32
    if all(v.type in FLOAT64 for v in variables) and not any(discrete):
        vr = (vr_t * n)(*[v.valueReference for v in variables])
        buf = (ctypes.c_double * n)()
        raw = np.ctypeslib.as_array(buf) if n else np.zeros(0)
        if identity:
            return Binding(names, vr, buf, raw, raw, kinds=kinds, types=types)
        return Binding(names, vr, buf, np.zeros(n), raw, scale, offset, kinds=kinds,
                       types=types)
    keys: dict[tuple[str, bool], list[int]] = {}
    for i, v in enumerate(variables):
        keys.setdefault((v.type, discrete[i]), []).append(i)
    groups = []
    p = "fmi3" if fmi3 else "fmi2"
    for (_, disc), idx in keys.items():
        k, ctype, suffix, _ = type_info(variables[idx[0]], fmi3)
        vr = (vr_t * len(idx))(*[variables[i].valueReference for i in idx])
        buf = (ctype * len(idx))()
        arr = None if k == "string" else np.ctypeslib.as_array(buf)
        groups.append(Group(np.array(idx, dtype=np.intp), vr, buf, arr, k,
                            f"{p}Get{suffix}", f"{p}Set{suffix}", disc))
    view = np.zeros(n)
    raw = view if identity else np.zeros(n)
    return Binding(names, None, None, view, raw, scale, offset, tuple(groups), kinds, types)
