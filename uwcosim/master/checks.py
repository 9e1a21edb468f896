"""The checks that wire a system to its FMUs: variables, causalities, types, ranges, drivers.

:class:`SystemChecks` is a mixin of :class:`~uwcosim.master.master.Master`: each check raises a
one-line :class:`~uwcosim.core.errors.ScenarioError` naming the key, and
:meth:`SystemChecks._collect` records it and goes on, so that ``uwcosim check`` reports every
problem at once. A check about an FMU that could not be opened is skipped (that FMU's problem is
already reported).

What the checks build is the master's bus layout and wiring:

- every output of every FMU (an FMI 3 array: one slot per element, row-major; its first slot
  under the array's name, :attr:`shapes` its shape) and every source of the master has a bus
  slot; a 64-bit integer output has an exact copy on the integer side bus
  (:attr:`exact`: bus slot -> side bus position, unsigned);
- variables named in the system's ``observe`` (locals, states, parameters: not outputs) get
  slots too, read after every step like outputs;
- every driven input value has one :class:`~uwcosim.master.node.Feed` (:attr:`wiring`: FMU ->
  input variable -> one feed per value). An array input is driven whole (by an array output of
  the same shape) or element by element (``b.u[1]``; then every element must be driven).

A signal name is ``fmu.variable``; an element of an FMI 3 array is ``fmu.variable[i]``
(``[i,j]`` for more dimensions; 0-based). A variable whose own name has brackets (FMI 2
structured names such as ``gains[1]``) is found by that name first.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from uwcosim.core.errors import ScenarioError, UwcosimError
from uwcosim.fmi import vartypes
from uwcosim.fmi.varmap import connection_affine
from uwcosim.master.node import Feed, RangeCheck

#: causalities of the variables that can be observed by name (besides outputs)
OBSERVABLE = ("local", "parameter", "calculatedParameter", "structuralParameter")


class _Skipped(Exception):
    """A check that refers to an FMU that could not be opened (already reported)."""


class SystemChecks:
    """Wiring checks of a master (needs ``system``, ``adapters``, ``problems`` and ``_broken``;
    builds ``slots``, ``shapes``, ``out_vars``, ``exact``, ``wiring``)."""

    def _where(self, key: str) -> str:
        return f"{self.system.where}: key '{key}'"

    @contextmanager
    def _collect(self) -> Iterator[None]:
        """Record a problem of the block in :attr:`problems` and go on with the next check."""
        try:
            yield
        except _Skipped:
            pass
        except UwcosimError as exc:
            self.problems.append(exc)

    # -- the bus layout -------------------------------------------------------------------------
    def _init_layout(self) -> None:
        #: signal name -> its (first) bus slot
        self.slots: dict[str, int] = {}
        #: FMU signal -> its model variable (outputs and observed variables)
        self.out_vars: dict[str, object] = {}
        #: array signals -> their shape
        self.shapes: dict[str, tuple[int, ...]] = {}
        #: bus slot of an exact 64-bit integer -> (side bus position, unsigned)
        self.exact: dict[int, tuple[int, bool]] = {}
        #: FMU -> input variable -> one feed per value (None: not driven yet)
        self.wiring: dict[str, dict[str, list]] = {}
        self._wired_by: dict[tuple[str, str], list[str | None]] = {}
        self._wired_key: dict[tuple[str, str], str] = {}
        self.n_slots = 0

    def _new_slot(self, name: str, n: int = 1) -> int:
        slot = self.n_slots
        self.slots[name] = slot
        self.n_slots += n
        return slot

    def _add_output(self, fmu: str, var_name: str) -> None:
        v = self.adapters[fmu].variables[var_name]
        signal = f"{fmu}.{var_name}"
        n = vartypes.size(v)
        slot = self._new_slot(signal, n)
        self.out_vars[signal] = v
        if vartypes.is_array(v):
            self.shapes[signal] = vartypes.shape(v)
        if vartypes.kind(v) != "string" and \
                vartypes.numpy_dtype(v, self.adapters[fmu].fmi3).name in ("int64", "uint64"):
            unsigned = v.type == "UInt64"
            for i in range(n):
                self.exact[slot + i] = (len(self.exact), unsigned)

    def _observe(self, signal: str) -> None:
        """A variable named in ``observe``: read each step if it is not an output already."""
        fmu, _, var = signal.partition(".")
        ad = self.adapters.get(fmu)
        if ad is None or fmu in self._broken:
            return  # not an FMU signal (a source), or reported already
        v = ad.variables.get(var)
        if v is None:
            el = vartypes.split_element(var)
            v = ad.variables.get(el[0]) if el is not None else None
        if v is None or f"{fmu}.{v.name}" in self.slots:
            return  # unknown (the caller reports it) or an output already
        if v.causality in OBSERVABLE and vartypes.bindable(v):
            name = next(n for n, x in ad.variables.items() if x is v)
            self._add_output(fmu, name)

    # -- looking signals up -----------------------------------------------------------------------
    def _variable(self, signal: str, key: str):
        """The FMU variable named by ``fmu.variable``, or a one-line ScenarioError."""
        fmu, _, var = signal.partition(".")
        if fmu in self._broken:
            raise _Skipped(signal)
        if fmu not in self.adapters:
            raise ScenarioError(f"{self._where(key)}: unknown FMU {fmu!r} in {signal!r} "
                                f"(FMUs: {', '.join(self.adapters)})")
        v = self.adapters[fmu].variables.get(var)
        if v is None:
            raise ScenarioError(self._no_variable(fmu, var, key))
        return v

    def _element(self, signal: str, key: str) -> tuple[str, object, int | None]:
        """``(variable signal, variable, flat element index or None)`` of ``signal``: a
        variable by its own name first, else an element ``var[i]`` of an array variable."""
        fmu, _, var = signal.partition(".")
        if fmu in self._broken:
            raise _Skipped(signal)
        ad = self.adapters.get(fmu)
        el = vartypes.split_element(var)
        if ad is not None and var not in ad.variables and el is not None \
                and el[0] in ad.variables:
            v = ad.variables[el[0]]
            if not vartypes.is_array(v):
                raise ScenarioError(f"{self._where(key)}: {f'{fmu}.{el[0]}'!r} is not an "
                                    f"array ({vartypes.describe(v)}); {signal!r} names no "
                                    f"element")
            try:
                return f"{fmu}.{el[0]}", v, vartypes.flat_index(v, el[1])
            except ValueError as exc:
                raise ScenarioError(f"{self._where(key)}: {signal!r}: {exc}") from None
        return signal, self._variable(signal, key), None

    def variable_of(self, signal: str) -> str:
        """The variable signal an element name belongs to (``a.y[1]`` -> ``a.y``); any other
        name as it is."""
        try:
            return self._element(signal, "")[0]
        except (UwcosimError, _Skipped):
            return signal

    def signal_slots(self, signal: str, key: str) -> list[int]:
        """The bus slots of an output, a source, an observed variable, an array (every
        element) or an element; a one-line ScenarioError naming ``key`` otherwise."""
        if signal in self.slots:
            v = self.out_vars.get(signal)
            first = self.slots[signal]
            return list(range(first, first + (vartypes.size(v) if v is not None else 1)))
        base, v, elem = self._element(signal, key)
        if base not in self.slots:
            what = "an output" if v.causality != "output" else "an output of a supported type"
            raise ScenarioError(f"{self._where(key)}: {signal!r} is not {what} "
                                f"(causality {v.causality!r}, type {vartypes.describe(v)})")
        first = self.slots[base]
        return [first + elem] if elem is not None else \
            list(range(first, first + vartypes.size(v)))

    def slot(self, signal: str, key: str) -> int:
        """The bus slot of the scalar output ``signal`` (or array element), or a one-line
        ScenarioError naming ``key``."""
        slots = self.signal_slots(signal, key)
        if len(slots) != 1:
            raise ScenarioError(f"{self._where(key)}: {signal!r} is an array "
                                f"({vartypes.describe(self.out_vars[signal])}); name one "
                                f"element, e.g. '{signal}[0]'")
        return slots[0]

    def _numeric_slot(self, signal: str, key: str) -> int:
        slot = self.slot(signal, key)
        v = self.out_vars.get(signal)
        if v is not None and vartypes.kind(v) == "string":
            raise ScenarioError(f"{self._where(key)}: {signal!r} is a String output; "
                                f"expected a numeric one")
        return slot

    def _no_variable(self, fmu: str, var: str, key: str) -> str:
        vmap = self.adapters[fmu].varmap
        hint = ""
        if vmap.aliases:
            hint = (f" (fmus.{fmu}.map gives roles {', '.join(vmap.aliases)}; "
                    f"map {var!r} there)")
        return f"{self._where(key)}: FMU {fmu!r} has no variable {var!r}{hint}"

    # -- driving inputs ---------------------------------------------------------------------------
    def _input(self, signal: str, key: str) -> tuple[str, object, int | None]:
        base, v, elem = self._element(signal, key)
        if v.causality != "input":
            raise ScenarioError(f"{self._where(key)}: {signal!r} has causality "
                                f"{v.causality!r}, expected 'input'")
        if not vartypes.bindable(v):
            raise ScenarioError(f"{self._where(key)}: {signal!r} has type "
                                f"{vartypes.describe(v)}, which the master does not support")
        return base, v, elem

    def _feed(self, base: str, v, elem: int | None, feeds: list[Feed], key: str,
              source: str, drivers: dict) -> None:
        fmu, _, var = base.partition(".")
        n = vartypes.size(v)
        wired = self.wiring.setdefault(fmu, {}).setdefault(var, [None] * n)
        by = self._wired_by.setdefault((fmu, var), [None] * n)
        self._wired_key.setdefault((fmu, var), key)
        targets = range(n) if elem is None else [elem]
        for e in targets:
            if wired[e] is not None:
                what = base if n == 1 else f"{base}[{e}]" if elem is not None else base
                raise ScenarioError(f"{self._where(key)}: input {what!r} is already driven by "
                                    f"{by[e]!r}")
        for e, f in zip(targets, feeds):
            wired[e], by[e] = f, source
        drivers[base if elem is None else f"{base}[{elem}]"] = source

    def _check_input(self, signal: str, key: str, drivers: dict, source: str,
                     float_only: bool = False) -> None:
        """An input driven by the master's source ``source`` (a control or noise slot)."""
        base, v, elem = self._input(signal, key)
        if vartypes.is_array(v):
            raise ScenarioError(f"{self._where(key)}: {signal!r} is an array input "
                                f"({vartypes.describe(v)}); array inputs are driven by "
                                f"connections only")
        if float_only and vartypes.kind(v) != "float":
            raise ScenarioError(f"{self._where(key)}: {signal!r} is of type {v.type}; noise "
                                f"drives only Real/Float inputs")
        check = None
        if vartypes.kind(v) == "int":
            lo, hi = vartypes.declared_range(v)
            check = RangeCheck(lo, hi, f"{self._where(key)}: {source!r} -> {signal!r} "
                                       f"({v.type}, {lo}..{hi})")
        self._feed(base, v, elem, [Feed(self.slots[source], check=check)], key, source,
                   drivers)

    def _check_connection(self, i: int, conn, drivers: dict) -> None:
        src, dst = conn[0], conn[1]
        key = f"connections[{i}]"
        factor, offset = (connection_affine(conn[2], f"{self._where(key)}") if len(conn) > 2
                          else (1.0, 0.0))
        src_slots = self.signal_slots(src, key)
        if src in self.slots:
            svar = self.out_vars.get(src)  # None: a source of the master (a float)
        else:
            svar = self._element(src, key)[1]  # an element of an array output
        s_desc = "Float64" if svar is None else (
            vartypes.describe(svar) if src in self.slots else f"element of {svar.type} array")
        base, dvar, elem = self._input(dst, key)
        if svar is None:
            problem = None if vartypes.kind(dvar) == "float" else "expected a Real input"
        else:
            problem = vartypes.connection_problem(svar, dvar)
        if problem:
            if problem.startswith("cannot connect") and " (" in problem:
                problem = problem.split(" (", 1)[1].rstrip(")")  # the names are ours
            raise ScenarioError(f"{self._where(key)}: cannot connect {src!r} ({s_desc}) to "
                                f"{dst!r} ({vartypes.describe(dvar)}): {problem}")
        n_dst = 1 if elem is not None else vartypes.size(dvar)
        if len(src_slots) != n_dst:
            d_desc = vartypes.describe(dvar) if elem is None else f"element of {dvar.type} array"
            raise ScenarioError(
                f"{self._where(key)}: cannot connect {src!r} ({s_desc}) to {dst!r} ({d_desc}): "
                f"the shapes differ ({len(src_slots)} and {n_dst} values); connect arrays of "
                f"the same shape, or element by element (e.g. '{src}[0]')")
        rp, checked = vartypes.range_problem(svar, dvar)
        if rp:
            raise ScenarioError(f"{self._where(key)}: cannot connect {src!r} to {dst!r}: {rp}")
        check = None
        if checked:
            lo, hi = vartypes.declared_range(dvar)
            check = RangeCheck(lo, hi, f"{self._where(key)}: {src!r} -> {dst!r} "
                                       f"({dvar.type}, {lo}..{hi})")
        feeds = [Feed(s, factor, offset, self.exact.get(s), check) for s in src_slots]
        self._feed(base, dvar, elem, feeds, key, src, drivers)

    def _complete_arrays(self) -> None:
        """Every element of an array input driven element by element must be driven."""
        for (fmu, var), by in self._wired_by.items():
            if len(by) > 1 and any(b is None for b in by):
                missing = [str(e) for e, b in enumerate(by) if b is None]
                v = self.adapters[fmu].variables[var]
                raise ScenarioError(
                    f"{self._where(self._wired_key[(fmu, var)])}: input array "
                    f"'{fmu}.{var}' ({vartypes.describe(v)}) is driven element by element "
                    f"without element(s) {', '.join(missing)}; drive every element or the "
                    f"whole array")
