"""Value references and value buffers ready for the get and set calls of one FMU.

A :class:`Binding` is made once per group of variables (an FMU's inputs, its outputs) by
:meth:`~uwcosim.fmi.adapter.FMUAdapter.bind`; a step then costs only the FMI calls. Values
are exchanged with the master in ``view``, a float64 array in our units (the master's bus),
one *position* per value: a scalar variable has one, an FMI 3 array variable one per element
(row-major; :attr:`Binding.offsets` and :attr:`Binding.sizes` say where each member starts).

- Fast path: every member is a scalar Real/Float64 (and, for model exchange, a continuous
  input): ``vr``/``buf`` hold one ``GetReal``/``GetFloat64`` call and ``view`` is a numpy view
  on ``buf`` (no copy).
- Typed path: the members are split into :class:`Group` s of one FMI type (one
  ``fmi3GetInt8``, ``fmi2GetBoolean``... call each, arrays included) with their own ctypes
  buffers; values are converted to and from ``view`` (integers rounded, booleans as 0/1,
  strings are NaN in ``view`` and their text is in ``text``). :meth:`Binding.native` gives the
  exact native values (an Int64 beyond 2**53 included) of the last get or set.

**Exact 64-bit integers.** The positions of Int64, UInt64 and (FMI 3) Enumeration members are
:attr:`Binding.wide_pos`; their exact values are in :attr:`Binding.wide` (int64; a UInt64 as
its bit pattern, ``wide.view(np.uint64)``), filled by every get. On a set they are taken from
``wide`` instead of ``view`` when the caller filled it (:attr:`Binding.wide_given`; the
master's nodes do, from its exact side bus), so a value beyond 2**53 reaches the FMU exactly.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from uwcosim.fmi.vartypes import FLOAT64, kind, size, type_info

#: the types whose values are kept exactly in :attr:`Binding.wide`
WIDE_DTYPES = (np.dtype(np.int64), np.dtype(np.uint64))


@dataclass
class Group:
    """Members of one FMI type (and, for model exchange, one input mode)."""

    idx: np.ndarray  # positions in the binding (every element of an array member)
    vr: ctypes.Array  # one value reference per member variable
    buf: ctypes.Array  # one value per position
    arr: np.ndarray | None  # numpy view on buf; None for strings
    kind: str  # float/int/bool/string
    get: Callable
    set: Callable
    discrete: bool = False  # model exchange: set in event mode only
    last: object = None  # model exchange discrete inputs: the values last set
    nvr: int = 0  # number of value references (< n when a member is an array)
    wide_idx: np.ndarray | None = None  # positions in Binding.wide (a 64-bit group)

    @property
    def n(self) -> int:
        """Number of values (positions)."""
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
    view: np.ndarray  # values in our units, one per position
    raw: np.ndarray | None = None  # values in FMU units; None: same as view
    scale: np.ndarray | None = None  # None: identity conversion
    offset: np.ndarray | None = None
    groups: tuple[Group, ...] = ()  # empty: the fast path (vr/buf)
    kinds: tuple[str, ...] = ()  # float/int/bool/string per member
    types: tuple[str, ...] = ()  # declared FMI type per member
    text: dict[int, str] = field(default_factory=dict)  # String members: position -> value
    sizes: tuple[int, ...] = ()  # values per member (1 for a scalar); () : all scalars
    #: positions of the 64-bit integer members' values, and those values (exact)
    wide_pos: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    wide: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: True when the caller fills ``wide`` before each set (otherwise taken from ``view``)
    wide_given: bool = False
    n: int = field(init=False)  # number of positions (an attribute: read on every call)

    def __post_init__(self) -> None:
        if not self.sizes:
            self.sizes = (1,) * len(self.names)
        self.n = int(sum(self.sizes))
        if len(self.wide) != len(self.wide_pos):
            self.wide = np.zeros(len(self.wide_pos), dtype=np.int64)

    @property
    def offsets(self) -> tuple[int, ...]:
        """The first position of each member."""
        return tuple(int(x) for x in np.cumsum((0, *self.sizes[:-1])))

    @property
    def discrete_groups(self) -> tuple[Group, ...]:
        return tuple(g for g in self.groups if g.discrete)

    @property
    def continuous_groups(self) -> tuple[Group, ...]:
        return tuple(g for g in self.groups if not g.discrete)

    @classmethod
    def plain(cls, names, kinds=None, types=None, sizes=(), wide_pos=()) -> Binding:
        """A binding without FMU buffers (values only), e.g. for an out-of-process FMU."""
        names = tuple(names)
        sizes = tuple(sizes) or (1,) * len(names)
        return cls(names, None, None, np.zeros(int(sum(sizes))),
                   kinds=tuple(kinds or ("float",) * len(names)),
                   types=tuple(types or ("Real",) * len(names)), sizes=sizes,
                   wide_pos=np.asarray(wide_pos, dtype=np.intp))

    def to_fmu(self) -> None:
        if self.scale is not None:
            np.subtract(self.view, self.offset, out=self.raw)
            np.divide(self.raw, self.scale, out=self.raw)

    def from_fmu(self) -> None:
        if self.scale is not None:
            np.multiply(self.raw, self.scale, out=self.view)
            np.add(self.view, self.offset, out=self.view)

    def native(self) -> list:
        """The values of the last get/set as Python ``float``/``int``/``bool``/``str``, one per
        position."""
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
        pos = 0
        for k, s in zip(self.kinds, self.sizes):
            for i in range(pos, pos + s):
                if k == "int":
                    out[i] = int(self.view[i])
                elif k == "bool":
                    out[i] = bool(self.view[i])
                elif k == "string":
                    out[i] = self.text.get(i, "")
            pos += s
        return out

    # -- typed path: view <-> group buffers ---------------------------------------------------
    def groups_to_raw(self) -> None:
        """After the get calls: group buffers -> ``raw`` -> ``view`` (and ``wide``)."""
        raw = self.view if self.raw is None else self.raw
        for g in self.groups:
            if g.kind == "string":
                for j, i in enumerate(g.idx):
                    v = g.buf[j]
                    self.text[int(i)] = v.decode("utf-8", "replace") if v is not None else ""
                    raw[i] = np.nan
            else:
                raw[g.idx] = g.arr
                if g.wide_idx is not None:
                    self.wide[g.wide_idx] = g.arr.view(np.int64)
        self.from_fmu()

    def raw_to_group(self, g: Group) -> None:
        """Before a set call: ``view`` -> ``raw`` -> the group's buffer (a 64-bit group: from
        ``wide`` when :attr:`wide_given`)."""
        if g.wide_idx is not None and self.wide_given:
            g.arr.view(np.int64)[:] = self.wide[g.wide_idx]
            return
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
    kinds = tuple(kind(v) for v in variables)
    types = tuple(v.type for v in variables)
    sizes = tuple(size(v) for v in variables)
    n = int(sum(sizes))
    identity = all(a == (1.0, 0.0) for a in affine)
    scale = None if identity else np.repeat([a[0] for a in affine], sizes).astype(float)
    offset = None if identity else np.repeat([a[1] for a in affine], sizes).astype(float)
    vr_t = ctypes.c_uint32
    if all(v.type in FLOAT64 for v in variables) and not any(discrete) and n == len(variables):
        vr = (vr_t * n)(*[v.valueReference for v in variables])
        buf = (ctypes.c_double * n)()
        raw = np.ctypeslib.as_array(buf) if n else np.zeros(0)
        if identity:
            return Binding(names, vr, buf, raw, raw, kinds=kinds, types=types)
        return Binding(names, vr, buf, np.zeros(n), raw, scale, offset, kinds=kinds,
                       types=types)
    starts = np.cumsum((0, *sizes[:-1])) if sizes else np.zeros(0, dtype=int)
    keys: dict[tuple[str, bool], list[int]] = {}
    for i, v in enumerate(variables):
        keys.setdefault((v.type, discrete[i]), []).append(i)
    groups = []
    wide_pos: list[int] = []
    p = "fmi3" if fmi3 else "fmi2"
    for (_, disc), members in keys.items():
        k, ctype, suffix, dtype = type_info(variables[members[0]], fmi3)
        idx = [int(starts[i]) + e for i in members for e in range(sizes[i])]
        vr = (vr_t * len(members))(*[variables[i].valueReference for i in members])
        buf = (ctype * len(idx))()
        arr = None if k == "string" else np.ctypeslib.as_array(buf)
        wide_idx = None
        if np.dtype(dtype) in WIDE_DTYPES:
            wide_idx = np.arange(len(wide_pos), len(wide_pos) + len(idx), dtype=np.intp)
            wide_pos += idx
        groups.append(Group(np.array(idx, dtype=np.intp), vr, buf, arr, k,
                            f"{p}Get{suffix}", f"{p}Set{suffix}", disc, nvr=len(members),
                            wide_idx=wide_idx))
    view = np.zeros(n)
    raw = view if identity else np.zeros(n)
    return Binding(names, None, None, view, raw, scale, offset, tuple(groups), kinds, types,
                   sizes=sizes, wide_pos=np.array(wide_pos, dtype=np.intp))
