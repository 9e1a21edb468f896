"""One FMU in the master's network: its inputs and outputs bound to the bus, with their types.

A :class:`Node` holds an FMU's adapter, its communication period, the ctypes bindings of its
driven inputs and of its outputs with the bus slots they read and write (one slot per value: an
FMI 3 array has one per element), and what the float64 bus alone cannot carry: String inputs and
outputs (their text), the exact values of 64-bit integer outputs and inputs (the master's
integer side bus, :attr:`~uwcosim.master.master.Master.xbus`), the linear transformations of
its incoming connections and the range checks of its narrowing ones. :func:`build_node` makes
one from the master's wiring (:class:`Feed`, one per input value); the master steps the nodes
(:mod:`uwcosim.master.master`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from uwcosim.core.errors import FMUError
from uwcosim.fmi import vartypes
from uwcosim.fmi.adapter import Binding, FMUAdapter


@dataclass(frozen=True)
class RangeCheck:
    """The values an integer input may take, checked each time it is set."""

    lo: int
    hi: int
    what: str  # "connections[3]: 'a.y' -> 'b.u' (Int8, -128..127)"


@dataclass(frozen=True)
class Feed:
    """Where one input value comes from: a bus slot (and, for an exact 64-bit integer, its
    position on the integer side bus), with the connection's linear transformation and range
    check."""

    slot: int
    factor: float = 1.0
    offset: float = 0.0
    exact: tuple[int, bool] | None = None  # (side bus index, unsigned) of an exact source
    check: RangeCheck | None = None


@dataclass
class Node:
    adapter: FMUAdapter
    period: int
    inputs: Binding
    in_slots: np.ndarray
    outputs: Binding
    out_slots: np.ndarray
    input_fn: Callable | None = None
    time_s: float = 0.0
    #: String inputs: (position, bus slot of the String source)
    str_inputs: list[tuple[int, int]] = field(default_factory=list)
    #: String outputs: (position, bus slot)
    str_out: list[tuple[int, int]] = field(default_factory=list)
    #: 64-bit integer outputs: their positions in ``outputs.wide`` and on the side bus
    wide_out: tuple[np.ndarray, np.ndarray] | None = None
    #: 64-bit integer inputs: (wide positions, side bus indices) of exact sources, and
    #: (wide positions, view positions) of the others
    wide_in: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
    #: (position, source signedness or None for a float source, side bus index, check)
    checks: list[tuple[int, bool | None, int, RangeCheck]] = field(default_factory=list)
    #: indices of the numeric outputs when some are Strings (None: all numeric)
    numeric: np.ndarray | None = None
    #: per-input ``(factor, offset)`` of connections with a linear transformation, or None
    in_affine: tuple[np.ndarray, np.ndarray] | None = None

    def gather(self, bus: np.ndarray, xbus: np.ndarray | None = None, t: float = 0.0) -> None:
        """Copy this FMU's inputs from the bus (``factor * value + offset`` where given; exact
        64-bit integers from the side bus ``xbus``); a value outside its input's range is an
        :class:`FMUError`."""
        bus.take(self.in_slots, out=self.inputs.view)  # the method: no dispatch wrapper
        if self.in_affine is not None:
            self.inputs.view *= self.in_affine[0]
            self.inputs.view += self.in_affine[1]
        if self.checks:
            self._check(xbus, t)
        if self.wide_in is not None:
            w = self.inputs.wide
            pos_x, xi, pos_f, view_pos = self.wide_in
            if len(pos_x):
                w[pos_x] = xbus[xi]
            if len(pos_f):
                w[pos_f] = np.rint(self.inputs.view[view_pos])

    def _check(self, xbus: np.ndarray | None, t: float) -> None:
        for pos, unsigned, xi, c in self.checks:
            if unsigned is None:
                x = float(self.inputs.view[pos])
                v = int(round(x)) if np.isfinite(x) else x
            else:
                raw = xbus[xi]
                v = int(raw.view(np.uint64)) if unsigned else int(raw)
            if not (np.isfinite(v) and c.lo <= v <= c.hi):
                raise FMUError(f"{c.what}: the value {v} at t={t:g} is outside the input's "
                               f"range {c.lo}..{c.hi} (the run stops here)")

    def set_text(self, text: dict[int, str]) -> None:
        """The text of the String inputs from ``text`` (by bus slot of their source)."""
        for j, slot in self.str_inputs:
            self.inputs.text[j] = text.get(slot, "")

    def input_values(self) -> dict:
        """The driven inputs as native values (for initialization mode)."""
        out = {}
        b = self.inputs
        wide = dict(zip(b.wide_pos.tolist(), range(len(b.wide_pos))))
        for name, pos, n in zip(b.names, b.offsets, b.sizes):
            var = self.adapter.variables[name]
            if self.adapter.varmap.aliases.get(name) is not None:
                continue  # a role with a unit conversion: set by set_inputs after initialization
            kind = vartypes.kind(var)
            vals = []
            for p in range(pos, pos + n):
                x = b.view[p]
                if p in wide and b.wide_given:
                    raw = b.wide[wide[p]]
                    vals.append(int(raw.view(np.uint64)) if var.type == "UInt64" else int(raw))
                else:
                    vals.append(b.text.get(p, "") if kind == "string" else
                                int(round(x)) if kind == "int" else bool(x) if kind == "bool"
                                else float(x))
            out[name] = vals if vartypes.is_array(var) else vals[0]
        return out

    def read(self, t: float, bus: np.ndarray, xbus: np.ndarray, text: dict,
             fresh: bool = False) -> None:
        """Read the outputs at ``t`` onto the bus (64-bit integers exactly onto the side bus
        ``xbus``, the text of String outputs into ``text``); a non-finite numeric output is an
        :class:`FMUError`. ``fresh``: the outputs binding was just read at ``t`` (by an
        exchange): no FMI call."""
        out = self.outputs.view if fresh else self.adapter.get_outputs(self.outputs, t)
        num = out if self.numeric is None else out[self.numeric]
        # one sum is cheaper than an elementwise test; a NaN or an infinity shows in it (an
        # overflow of finite values too: then the elementwise test finds nothing)
        if not math.isfinite(num.sum()) and not np.all(np.isfinite(num)):
            self._not_finite(num, t)
        bus[self.out_slots] = out
        if self.wide_out is not None:
            xbus[self.wide_out[1]] = self.outputs.wide[self.wide_out[0]]
        for p, slot in self.str_out:
            text[slot] = self.outputs.text.get(p, "")

    def _not_finite(self, num: np.ndarray, t: float) -> None:
        labels = _labels(self.outputs)
        if self.numeric is not None:
            labels = [labels[j] for j in self.numeric]
        bad = [n for n, v in zip(labels, num) if not np.isfinite(v)]
        raise FMUError(f"FMU '{self.adapter.name}' returned a non-finite value for "
                       f"{', '.join(bad)} at t={t:g}")


def _labels(b: Binding) -> list[str]:
    """One label per position: the member's name (``name (element i)`` in an array)."""
    out = []
    for name, n in zip(b.names, b.sizes):
        out += [name] if n == 1 else [f"{name} (element {i})" for i in range(n)]
    return out


def build_node(name: str, ad: FMUAdapter, period: int, wiring: dict[str, list[Feed]],
               outputs: list[str], out_slots: list[int],
               exact: dict[int, tuple[int, bool]]) -> Node:
    """The node of FMU ``name``: inputs fed by ``wiring`` (input variable -> one :class:`Feed`
    per value), the output variables ``outputs`` written to ``out_slots`` (one per value),
    ``exact`` the side bus position and signedness of each exact 64-bit bus slot."""
    ins = sorted(wiring)
    feeds = [f for i in ins for f in wiring[i]]
    inputs = ad.bind(ins)
    node = Node(
        adapter=ad, period=period, inputs=inputs,
        in_slots=np.array([f.slot for f in feeds], dtype=np.intp),
        outputs=ad.bind(outputs), out_slots=np.array(out_slots, dtype=np.intp),
    )
    pos_of = dict(zip(ins, inputs.offsets))
    node.str_inputs = [(pos_of[i], wiring[i][0].slot) for i in ins
                       if vartypes.kind(ad.variables[i]) == "string"]
    if any((f.factor, f.offset) != (1.0, 0.0) for f in feeds):
        node.in_affine = (np.array([f.factor for f in feeds]),
                          np.array([f.offset for f in feeds]))
    # exact 64-bit inputs: from the side bus when the source is exact and not transformed
    if len(inputs.wide_pos):
        px, xi, pf, vp = [], [], [], []
        for w, p in enumerate(inputs.wide_pos.tolist()):
            f = feeds[p]
            if f.exact is not None and (f.factor, f.offset) == (1.0, 0.0):
                px.append(w)
                xi.append(f.exact[0])
            else:
                pf.append(w)
                vp.append(p)
        node.wide_in = tuple(np.array(a, dtype=np.intp) for a in (px, xi, pf, vp))
        inputs.wide_given = True
    for p, f in enumerate(feeds):
        if f.check is not None:
            exact_src = f.exact is not None and (f.factor, f.offset) == (1.0, 0.0)
            node.checks.append((p, f.exact[1] if exact_src else None,
                                f.exact[0] if exact_src else -1, f.check))
    out_b = node.outputs
    if len(out_b.wide_pos):
        xs = [exact[int(node.out_slots[p])][0] for p in out_b.wide_pos.tolist()]
        node.wide_out = (np.arange(len(xs), dtype=np.intp), np.array(xs, dtype=np.intp))
    strings = {p for o, p0, n in zip(outputs, out_b.offsets, out_b.sizes)
               if vartypes.kind(ad.variables[o]) == "string" for p in range(p0, p0 + n)}
    if strings:
        node.numeric = np.array([j for j in range(out_b.n) if j not in strings],
                                dtype=np.intp)
        node.str_out = [(p, int(node.out_slots[p])) for p in sorted(strings)]
    return node
