"""One FMU in the master's network: its inputs and outputs bound to the bus, with their types.

A :class:`Node` holds an FMU's adapter, its communication period, the ctypes bindings of its
driven inputs and of its outputs with the bus slots they read and write, and what the bus alone
cannot carry: String inputs and outputs (their text), Int64/UInt64 outputs kept exactly for the
log, the linear transformations of its incoming connections. :func:`build_node` makes one from
the master's tables; the master steps the nodes (:mod:`uwcosim.master.master`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from uwcosim.core.errors import FMUError
from uwcosim.fmi import vartypes
from uwcosim.fmi.adapter import Binding, FMUAdapter

#: native values kept exactly (not only as float64 on the bus) for logging
EXACT_DTYPES = ("int64", "uint64", "object")


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
    #: String inputs: (member index, bus slot of the String source)
    str_inputs: list[tuple[int, int]] = field(default_factory=list)
    #: outputs kept exactly (String, Int64, UInt64): (member index, bus slot)
    exact_outputs: list[tuple[int, int]] = field(default_factory=list)
    #: indices of the numeric outputs when some are Strings (None: all numeric)
    numeric: np.ndarray | None = None
    #: per-input ``(factor, offset)`` of connections with a linear transformation, or None
    in_affine: tuple[np.ndarray, np.ndarray] | None = None

    def gather(self, bus: np.ndarray) -> None:
        """Copy this FMU's inputs from the bus (``factor * value + offset`` where given)."""
        bus.take(self.in_slots, out=self.inputs.view)  # the method: no dispatch wrapper
        if self.in_affine is not None:
            self.inputs.view *= self.in_affine[0]
            self.inputs.view += self.in_affine[1]

    def set_text(self, text: dict[int, str]) -> None:
        """The text of the String inputs from ``text`` (by bus slot of their source)."""
        for j, slot in self.str_inputs:
            self.inputs.text[j] = text.get(slot, "")

    def input_values(self) -> dict:
        """The driven inputs as native values (for initialization mode)."""
        out = {}
        for j, name in enumerate(self.inputs.names):
            var = self.adapter.variables[name]
            if self.adapter.varmap.aliases.get(name) is not None:
                continue  # a role with a unit conversion: set by set_inputs after initialization
            kind = vartypes.kind(var)
            x = self.inputs.view[j]
            out[name] = (self.inputs.text.get(j, "") if kind == "string" else
                         int(round(x)) if kind == "int" else bool(x) if kind == "bool"
                         else float(x))
        return out

    def read(self, t: float, bus: np.ndarray, native: dict, text: dict,
             fresh: bool = False) -> None:
        """Read the outputs at ``t`` onto the bus (exact values into ``native``, the text of
        String outputs into ``text``); a non-finite numeric output is an :class:`FMUError`.
        ``fresh``: the outputs binding was just read at ``t`` (by an exchange): no FMI call."""
        out = self.outputs.view if fresh else self.adapter.get_outputs(self.outputs, t)
        num = out if self.numeric is None else out[self.numeric]
        # one sum is cheaper than an elementwise test; a NaN or an infinity shows in it (an
        # overflow of finite values too: then the elementwise test finds nothing)
        if not math.isfinite(num.sum()) and not np.all(np.isfinite(num)):
            names = self.outputs.names if self.numeric is None else \
                [self.outputs.names[j] for j in self.numeric]
            bad = [n for n, v in zip(names, num) if not np.isfinite(v)]
            raise FMUError(f"FMU '{self.adapter.name}' returned a non-finite value for "
                           f"{', '.join(bad)} at t={t:g}")
        bus[self.out_slots] = out
        if self.exact_outputs:
            values = self.outputs.native()
            for j, slot in self.exact_outputs:
                native[slot] = values[j]
                if isinstance(values[j], str):
                    text[slot] = values[j]


def build_node(name: str, ad: FMUAdapter, period: int, drivers: dict[str, str],
               slots: dict[str, int], out_vars: dict, transforms: dict) -> Node:
    """The node of FMU ``name``: inputs driven by ``drivers`` (input -> source signal), outputs
    in ``out_vars``, bus ``slots`` by signal name, connection ``transforms`` by input."""
    ins = sorted(k.split(".", 1)[1] for k in drivers if k.split(".", 1)[0] == name)
    outs = [k.split(".", 1)[1] for k in out_vars if k.split(".", 1)[0] == name]
    node = Node(
        adapter=ad, period=period,
        inputs=ad.bind(ins),
        in_slots=np.array([slots[drivers[f"{name}.{i}"]] for i in ins], dtype=np.intp),
        outputs=ad.bind(outs),
        out_slots=np.array([slots[f"{name}.{o}"] for o in outs], dtype=np.intp),
    )
    node.str_inputs = [(j, slots[drivers[f"{name}.{i}"]]) for j, i in enumerate(ins)
                       if vartypes.kind(ad.variables[i]) == "string"]
    exact = [j for j, o in enumerate(outs)
             if np.dtype(vartypes.numpy_dtype(ad.variables[o])).name in EXACT_DTYPES]
    node.exact_outputs = [(j, int(node.out_slots[j])) for j in exact]
    strings = {j for j, o in enumerate(outs) if vartypes.kind(ad.variables[o]) == "string"}
    if strings:
        node.numeric = np.array([j for j in range(len(outs)) if j not in strings],
                                dtype=np.intp)
    if any(f"{name}.{i}" in transforms for i in ins):
        fo = np.array([transforms.get(f"{name}.{i}", (1.0, 0.0)) for i in ins])
        node.in_affine = (fo[:, 0].copy(), fo[:, 1].copy())
    return node
