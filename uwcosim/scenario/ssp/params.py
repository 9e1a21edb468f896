"""Parameter bindings of an SSP applied to the FMUs of its flattened system.

Every ``ssd:ParameterBinding`` of a component or a system gives values (a parameter set,
``.ssv`` or inline) to names; a binding with a parameter mapping (``.ssm`` or inline) first
maps the set's names and values to the element's (:class:`~uwcosim.scenario.ssp.tree.
MappingEntry`: ``source`` -> ``target``, the source value converted to the target's unit unless
``suppressUnitConversion``, then a linear or a Boolean/Integer/Enumeration mapping
transformation). What each name means:

- on a component: its FMU variables;
- on a system: ``elem.var`` (``sub.elem.var``...), or a **connector of the system**: the value
  is propagated along the system's connections (through sub-system connectors, with the unit
  conversions and linear transformations on the way) to every component connector of kind
  ``parameter``, ``structuralParameter`` or ``input`` it reaches (an input gets it as its start
  value), as the SSP standard defines for connected parameters.

Precedence (the SSP 1.0 schema's rules for ParameterBinding, made explicit):

1. a binding of a system beats the bindings of the elements inside it (higher in the
   hierarchy wins), so a component's own value never beats a value bound above it;
2. within one element, a value propagated from a bound system connector beats a direct
   binding of the same variable (``elem.var``): the connected system parameter is the one the
   system's designer exposed;
3. otherwise the later binding wins.

Names that match no variable, mapping entries whose source is not in the parameter set, and
bound system connectors that reach no parameter or input are ignored (SSP) and listed as
warnings (:attr:`ParameterBinder.ignored`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.varmap import fmu_unit
from uwcosim.scenario.ssp.tree import Binding, Component, System
from uwcosim.scenario.ssp.xml import REAL_TYPES

#: component connector kinds that take a propagated value
TARGET_KINDS = ("parameter", "input", "structuralParameter")
#: FMU causalities whose bound values are parameters (the others: start values)
PARAMETER_CAUSALITIES = ("parameter", "calculatedParameter", "structuralParameter")


class Network(Protocol):
    """What the binder needs of the flattened network (:class:`uwcosim.scenario.ssp.read.
    FlatReader`)."""

    comps: dict
    systems: dict

    def fail(self, msg: str) -> ScenarioError: ...
    def reach(self, start: tuple) -> list: ...
    def connector(self, node: tuple, text: str): ...
    def compose(self, hops, unit: str | None, node0: tuple) -> tuple[float, float]: ...
    def convert(self, u_from: str, n_from: tuple, u_to: str, n_to: tuple,
                text: str) -> tuple[float, float]: ...


@dataclass
class _Bound:
    value: object
    where: str
    rank: tuple  # (-depth of the binding's owner, propagated, order): the highest wins


class ParameterBinder:
    """Collects every bound value with its rank, then writes the winners into the components'
    ``parameters`` and ``start`` (:meth:`apply`)."""

    def __init__(self, net: Network) -> None:
        self.net = net
        self.values: dict[tuple[tuple, str], _Bound] = {}
        #: ignored names, as "source: name (why)"
        self.ignored: list[str] = []
        self._order = 0

    def apply(self) -> None:
        self._system((), 0)
        for (path, var), b in self.values.items():
            comp = self.net.comps[path]
            v = comp.variables[var]
            target = (comp.flat.parameters if v.causality in PARAMETER_CAUSALITIES
                      or v.type not in REAL_TYPES else comp.flat.start)
            target[var] = b.value

    # -- the hierarchy ------------------------------------------------------------------------
    def _system(self, path: tuple, depth: int) -> None:
        system: System = self.net.systems[path][0]
        for el in system.elements:
            p = (*path, el.name)
            if isinstance(el, Component):
                for name, value, unit, where, fo in self._entries(el.bindings):
                    self._direct(p, name, value, unit, where, (-(depth + 1), 0), fo)
            else:
                self._system(p, depth + 1)
        for name, value, unit, where, fo in self._entries(system.bindings):
            self._name(path, name, value, unit, where, depth, fo)

    def _entries(self, bindings: list[Binding]):
        """``(name, value, unit, where, (factor, offset, value map))`` of every bound value,
        names and values mapped by the binding's parameter mapping."""
        for b in bindings:
            if b.mapping is None:
                for p in b.parameters:
                    yield b.prefix + p.name, p.value, p.unit, b.where, None
                continue
            by_source: dict[str, list] = {}
            for e in b.mapping:
                by_source.setdefault(e.source, []).append(e)
            names = {p.name for p in b.parameters}
            for e in b.mapping:
                if e.source not in names:
                    self.ignored.append(f"{b.where}: mapping entry {e.source!r} -> "
                                        f"{e.target!r} (no parameter {e.source!r} in the set)")
            for p in b.parameters:
                entries = by_source.get(p.name)
                if not entries:  # not mapped: by its own name
                    yield b.prefix + p.name, p.value, p.unit, b.where, None
                    continue
                for e in entries:
                    unit = None if e.suppress_units else p.unit
                    yield (e.target, p.value, unit, f"{b.where} (mapped from {p.name!r})",
                           (e.factor, e.offset, e.values))

    def _name(self, path: tuple, name: str, value, unit, where: str, depth: int, fo) -> None:
        """A name bound on the system at ``path`` by a binding of an owner at ``depth``."""
        system, connectors = self.net.systems[path]
        if name in connectors:
            self._propagate((path, name), value, unit, where, depth, fo)
            return
        for el in sorted(system.elements, key=lambda e: -len(e.name)):
            if name.startswith(el.name + "."):
                rest, p = name[len(el.name) + 1:], (*path, el.name)
                if p in self.net.comps:
                    self._direct(p, rest, value, unit, where, (-depth, 0), fo)
                else:
                    self._name(p, rest, value, unit, where, depth, fo)
                return
        self.ignored.append(f"{where}: {'.'.join((*path, name))}")

    def _propagate(self, node: tuple, value, unit, where: str, depth: int, fo) -> None:
        """A bound system connector: its value (mapped first) to every parameter or input it
        reaches, converted along the way."""
        value = _mapped(value, fo)
        numeric = _numbers(value)
        reached = 0
        for leaf, hops in self.net.reach(node):
            kind = self.net.connector(leaf, "").kind
            if kind not in TARGET_KINDS:
                continue
            along = self.net.compose(hops, unit, node) if numeric else (1.0, 0.0)
            self._direct(leaf[0], leaf[1], value, None, where, (-depth, 1), None, along)
            reached += 1
        if not reached:
            self.ignored.append(f"{where}: {'.'.join(node[0] + (node[1],))} (a system connector "
                                f"connected to no parameter or input)")

    # -- one variable -------------------------------------------------------------------------
    def _direct(self, path: tuple, var: str, value, unit, where: str, rank: tuple, fo,
                along: tuple[float, float] = (1.0, 0.0)) -> None:
        comp = self.net.comps[path]
        v = comp.variables.get(var)
        if v is None:  # SSP: names that match no variable are ignored
            self.ignored.append(f"{where}: {comp.flat.path}.{var}")
            return
        if v.type in REAL_TYPES:
            items = value if isinstance(value, list) else [value]
            if not _numbers(value):
                raise self.net.fail(f"{where}: parameter {var!r}: a {type(items[0]).__name__} "
                                    f"for the Real variable of component {comp.flat.path!r}")
            a, b = 1.0, 0.0
            theirs = fmu_unit(v)
            if unit and theirs and unit != theirs:
                a, b = self.net.convert(unit, (path, var), theirs, (path, var),
                                        f"{where}: parameter {var!r}")
            F, O = along
            conv = [a * (F * float(x) + O) + b for x in items]
            value = _mapped(conv if isinstance(value, list) else conv[0], fo)
        else:
            value = _mapped(value, fo)
            if isinstance(value, float) and value.is_integer() and v.type != "String":
                value = int(value)  # a Real in the parameter set for an Integer variable
        self._order += 1
        key = (path, var)
        new = _Bound(value, where, (*rank, self._order))
        old = self.values.get(key)
        if old is None or new.rank > old.rank:
            self.values[key] = new


def _numbers(value) -> bool:
    items = value if isinstance(value, list) else [value]
    return all(isinstance(x, int | float) and not isinstance(x, bool) for x in items)


def _mapped(value, fo):
    """``value`` through a mapping entry's transformation ``(factor, offset, value map)``."""
    if fo is None:
        return value
    factor, offset, values = fo
    if values is not None:
        return [values.get(x, x) for x in value] if isinstance(value, list) else \
            values.get(value, value)
    if (factor, offset) == (1.0, 0.0) or not _numbers(value):
        return value
    if isinstance(value, list):
        return [factor * float(x) + offset for x in value]
    return factor * float(value) + offset
