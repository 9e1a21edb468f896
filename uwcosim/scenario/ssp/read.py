"""Read an SSP file (System Structure and Parameterization, 1.0 or 2.0) into one flat FMU
network.

The XML is read into plain records by :mod:`uwcosim.scenario.ssp.tree` (checked against the
schemas fmpy ships, :mod:`uwcosim.scenario.ssp.schema`); the FMUs of the components are
extracted and their model descriptions read; then the system is flattened here.

Flattening: components of sub-systems get the name ``sub_comp`` (the master splits signal names
``fmu.variable`` at the first dot, so the dot cannot join them); every FMU input is traced back
through system connectors to the one FMU output that drives it, composing on the way the unit
conversions and linear transformations of every connection crossed (the source value is
converted to the target unit first, then ``target = factor * source + offset``). Real,
integer, Boolean, String and Enumeration connectors connect (unit conversions and linear
transformations on Real ones only). The parameter bindings (values, mappings, propagation
along connections, precedence) are applied by :class:`~uwcosim.scenario.ssp.params.
ParameterBinder`; ignored names are listed in :attr:`FlatSystem.ignored`. Every unsupported
element is one :class:`~uwcosim.core.errors.ScenarioError` line naming it.
"""

from __future__ import annotations

import zipfile
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from urllib.parse import unquote

from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.fmi.archive import archive_size_problem, open_description
from uwcosim.fmi.varmap import UNITS, canonical_unit, fmu_unit
from uwcosim.scenario.ssp.params import ParameterBinder
from uwcosim.scenario.ssp.tree import Component, Connector, System, read_document
from uwcosim.scenario.ssp.xml import (
    BASE_UNITS,
    FMU_TYPE,
    INTERFACES,
    NS,
    REAL_TYPES,
    SI_EXPONENTS,
    SSP2_KINDS,
    as_float,
    end_name,
    step_size,
)


@dataclass
class FlatComponent:
    """One FMU of the flattened system."""

    name: str  # flat name used in the scenario (sub_comp)
    path: str  # hierarchical name in the SSP (sub.comp)
    source: str  # archive member of the FMU
    fmu: Path  # extracted FMU
    interface: str | None = None  # "cs", "me", or None for "any"
    parameters: dict = field(default_factory=dict)
    start: dict = field(default_factory=dict)


@dataclass
class FlatConnection:
    """``dst = factor * src + offset`` (unit conversions and linear transformations composed)."""

    src: str
    dst: str
    factor: float = 1.0
    offset: float = 0.0


@dataclass
class FlatSystem:
    name: str
    components: dict[str, FlatComponent]
    connections: list[FlatConnection]
    start_time: float | None = None
    stop_time: float | None = None
    step: float | None = None
    description: str = ""
    #: bound parameters that match no variable (SSP: ignored), as "source: name"
    ignored: list[str] = field(default_factory=list)
    #: the SSD's version attribute ("1.0", "2.0")
    version: str = "1.0"
    #: what the schema check could not validate (SSP 2.0 elements unknown to SSP 1.0)
    not_validated: list[str] = field(default_factory=list)


@dataclass
class _Edge:
    factor: float
    offset: float
    suppress: bool
    text: str


@dataclass
class _Comp:
    flat: FlatComponent
    md: object
    variables: dict
    connectors: dict[str, Connector]
    obj: Component


class FlatReader:
    """Reads one archive and flattens it (see the module docstring); :meth:`read`."""

    def __init__(self, path: Path, fmu_dir: Path) -> None:
        self.path = Path(path)
        self.where = f"{self.path}"
        self.fmu_dir = Path(fmu_dir)
        self.comps: dict[tuple, _Comp] = {}
        #: path -> (tree System, its connectors by name)
        self.systems: dict[tuple, tuple[System, dict[str, Connector]]] = {}
        self.adj: dict[tuple, list[tuple[tuple, _Edge]]] = {}
        self.extracted: dict[str, Path] = {}
        self.units: dict[str, tuple[tuple, float, float]] = {}

    def fail(self, msg: str) -> ScenarioError:
        return ScenarioError(f"{self.where}: {msg}")

    # -- reading ----------------------------------------------------------------------------
    def read(self) -> FlatSystem:
        try:
            zf = zipfile.ZipFile(self.path)
        except (OSError, zipfile.BadZipFile) as exc:
            raise self.fail(f"not an SSP archive (a zip file): {exc}") from None
        with zf:
            too_big = archive_size_problem(self.path, zf, "SSP archive")
            if too_big:  # before a member is read (a zip bomb)
                raise FMUError(too_big)
            self.members = set(zf.namelist())
            doc = read_document(zf, self.fail)
            for u in doc.units.values():
                self.units[u.name] = (u.exponents, u.factor, u.offset)
            self._walk(doc.system, (), zf)
        flat_names: dict[str, str] = {}
        for c in self.comps.values():
            other = flat_names.setdefault(c.flat.name, c.flat.path)
            if other != c.flat.path:
                raise self.fail(f"components {other!r} and {c.flat.path!r} both flatten to the "
                                f"name {c.flat.name!r}; rename one")
        connections = self._connections()
        binder = ParameterBinder(self)
        binder.apply()
        exp = doc.root.find("ssd:DefaultExperiment", NS)
        start = stop = None
        if exp is not None:
            start = as_float(exp.get("startTime"))
            stop = as_float(exp.get("stopTime"))
        comps = {c.flat.name: c.flat for c in self.comps.values()}
        return FlatSystem(name=doc.name or self.path.stem, components=comps,
                          connections=connections, start_time=start, stop_time=stop,
                          step=step_size(doc.root), ignored=binder.ignored,
                          description=doc.system.description, version=doc.version,
                          not_validated=doc.not_validated)

    def _extract(self, zf: zipfile.ZipFile, source: str | None, comp: str) -> Path:
        if source is None:
            raise self.fail(f"component {comp!r}: no source (a component without an "
                            f"implementation cannot be run)")
        src = PurePosixPath(unquote(source))
        if ":" in source or src.is_absolute() or ".." in src.parts:
            raise self.fail(f"component {comp!r}: source {source!r} is not supported (only "
                            f"FMUs inside the .ssp archive, by a relative path)")
        member = str(src)
        if member not in self.members:
            raise self.fail(f"component {comp!r}: source {source!r} is not in the archive")
        if member not in self.extracted:
            out = self.fmu_dir / src.name
            if out.exists():  # same file name in another folder of the archive
                out = self.fmu_dir / f"{len(self.extracted)}_{src.name}"
            out.write_bytes(zf.read(member))
            self.extracted[member] = out
        return self.extracted[member]

    def _connectors(self, connectors: list[Connector], owner: str,
                    variables: dict | None) -> dict[str, Connector]:
        out = {}
        for c in connectors:
            if c.kind == "inout":
                raise self.fail(f"{owner}: <ssd:Connector name={c.name!r} kind='inout'> is not "
                                f"supported")
            if variables is not None and c.name not in variables:
                raise self.fail(f"{owner}: connector {c.name!r} is not a variable of the FMU")
            out[c.name] = Connector(c.name, SSP2_KINDS.get(c.kind, c.kind)
                                    if c.kind == "constant" else c.kind, c.type, c.unit)
        return out

    def _walk(self, system: System, path: tuple, zf) -> None:
        """Collect components, system connectors and connection edges of ``system``."""
        label = ".".join(path) or system.name
        self.systems[path] = (system, self._connectors(system.connectors, f"system {label!r}",
                                                       None))
        for el in system.elements:
            p = (*path, el.name)
            if not isinstance(el, Component):
                self._walk(el, p, zf)
                continue
            hname = ".".join(p)
            if el.type != FMU_TYPE:
                raise self.fail(f"component {hname!r}: type {el.type!r} is not supported (only "
                                f"FMUs, {FMU_TYPE!r})")
            fmu = self._extract(zf, el.source, hname)
            try:
                md = open_description(fmu)
            except FMUError as exc:  # named by the .ssp and its member, not the temp copy
                raise FMUError(str(exc).replace(str(fmu), f"{self.where}: component "
                                                f"{hname!r} ({el.source})")) from None
            variables = {v.name: v for v in md.modelVariables}
            interface = INTERFACES.get(el.implementation)
            if interface is None and md.coSimulation is None:
                interface = "me"  # "any" and the FMU has model exchange only
            flat = FlatComponent(name="_".join(p), path=hname, source=el.source, fmu=fmu,
                                 interface=interface)
            conns = self._connectors(el.connectors, f"component {hname!r}", variables)
            self.comps[p] = _Comp(flat, md, variables, conns, el)
        for c in system.connections:
            a = ((*path, c.start_element) if c.start_element else path, c.start_connector)
            b = ((*path, c.end_element) if c.end_element else path, c.end_connector)
            text = (f"connection {end_name(c.start_element, c.start_connector)} -> "
                    f"{end_name(c.end_element, c.end_connector)} in system {label!r}")
            edge = _Edge(c.factor, c.offset, c.suppress_units, text)
            for node in (a, b):
                self.connector(node, text)
            if a == b:  # it would vanish from the flattened system, leaving the input undriven
                raise self.fail(f"{text}: connects {end_name(c.start_element, c.start_connector)}"
                                f" to itself; expected an output and an input")
            self.adj.setdefault(a, []).append((b, edge))
            self.adj.setdefault(b, []).append((a, edge))

    def connector(self, node: tuple, text: str) -> Connector:
        path, name = node
        if path in self.comps:
            comp = self.comps[path]
            if name in comp.connectors:
                return comp.connectors[name]
            v = comp.variables.get(name)
            if v is None:
                raise self.fail(f"{text}: component {'.'.join(path)!r} has no connector or "
                                f"FMU variable {name!r}")
            return Connector(name, v.causality)
        if path in self.systems:
            conn = self.systems[path][1].get(name)
            if conn is None:
                raise self.fail(f"{text}: system {'.'.join(path) or 'root'!r} has no "
                                f"connector {name!r}")
            return conn
        raise self.fail(f"{text}: no element {'.'.join(path)!r}")

    # -- connections ------------------------------------------------------------------------
    def reach(self, start: tuple) -> list[tuple[tuple, list[tuple[tuple, tuple, _Edge]]]]:
        """Component connectors reachable from ``start`` through system connectors, each with
        its hops ``(from, to, edge)`` from ``start``."""
        prev: dict[tuple, tuple[tuple, _Edge] | None] = {start: None}
        queue, leaves = deque([start]), []
        while queue:
            node = queue.popleft()
            for nxt, edge in self.adj.get(node, []):
                if nxt in prev:
                    continue
                prev[nxt] = (node, edge)
                if nxt[0] in self.comps:
                    leaves.append(nxt)
                else:
                    queue.append(nxt)
        out = []
        for leaf in leaves:
            hops, n = [], leaf
            while prev[n] is not None:
                p, e = prev[n]
                hops.append((p, n, e))
                n = p
            out.append((leaf, hops[::-1]))
        return out

    def _unit(self, node: tuple) -> str | None:
        path, name = node
        if path in self.comps:
            comp = self.comps[path]
            c = comp.connectors.get(name)
            if c is not None and c.unit:
                return c.unit
            return fmu_unit(comp.variables[name])
        c = self.systems[path][1].get(name)
        return c.unit if c is not None else None

    def _unit_def(self, unit: str, node: tuple) -> tuple[tuple, float, float] | None:
        if unit in self.units:
            return self.units[unit]
        if node[0] in self.comps:
            for u in getattr(self.comps[node[0]].md, "unitDefinitions", None) or []:
                base = getattr(u, "baseUnit", None)
                if u.name == unit and base is not None:
                    return (tuple(int(getattr(base, k, 0) or 0) for k in BASE_UNITS),
                            float(base.factor), float(base.offset))
        known = UNITS.get(canonical_unit(unit))
        if known is not None:
            exps = SI_EXPONENTS[known[1]]
            return tuple(exps.get(k, 0) for k in BASE_UNITS), known[0], 0.0
        return None

    def convert(self, u_from: str, n_from: tuple, u_to: str, n_to: tuple,
                 text: str) -> tuple[float, float]:
        """``(a, b)``: value in ``u_to`` = a * value in ``u_from`` + b."""
        if u_from == u_to:
            return 1.0, 0.0
        d_from, d_to = self._unit_def(u_from, n_from), self._unit_def(u_to, n_to)
        for u, d in ((u_from, d_from), (u_to, d_to)):
            if d is None:
                raise self.fail(f"{text}: unknown unit {u!r} (define it in the SSD's "
                                f"<ssd:Units> or set suppressUnitConversion='true')")
        if d_from[0] != d_to[0]:
            raise self.fail(f"{text}: cannot convert unit {u_from!r} to {u_to!r} (different "
                            f"base units; set suppressUnitConversion='true' to connect as is)")
        return d_from[1] / d_to[1], (d_from[2] - d_to[2]) / d_to[1]

    def compose(self, hops: list, unit: str | None, node0: tuple) -> tuple[float, float]:
        """Affine map ``(F, O)`` of the value along ``hops`` (in the direction of flow)."""
        F, O = 1.0, 0.0
        for _, b, e in hops:
            u_b = self._unit(b)
            if u_b and unit and not e.suppress:
                ca, cb = self.convert(unit, node0, u_b, b, e.text)
                F, O = ca * F, ca * O + cb
            unit = u_b or unit
            F, O = e.factor * F, e.factor * O + e.offset
        return F, O

    def _connections(self) -> list[FlatConnection]:
        out = []
        for path, comp in self.comps.items():
            for name in sorted({n for p, n in self.adj if p == path}):
                node = (path, name)
                kind = self.connector(node, f"component {comp.flat.path!r}").kind
                if kind == "calculatedParameter":
                    raise self.fail(f"connector {comp.flat.path}.{name}: parameter "
                                    f"connections (calculatedParameter -> parameter) are not "
                                    f"supported")
                if kind != "input":
                    continue
                sources = [(leaf, hops) for leaf, hops in self.reach(node)
                           if self.connector(leaf, "").kind == "output"]
                if len(sources) > 1:
                    names = ", ".join(f"{'.'.join(s[0])}.{s[1]}" for s, _ in sources)
                    raise self.fail(f"input {comp.flat.path}.{name} is driven by more than "
                                    f"one output ({names})")
                if not sources:
                    continue
                leaf, hops = sources[0]
                flow = [(b, a, e) for a, b, e in reversed(hops)]
                src = self.comps[leaf[0]]
                F, O = self.compose(flow, self._unit(leaf), leaf)
                for n, c in ((leaf, src), (node, comp)):
                    v = c.variables[n[1]]
                    if v.type not in REAL_TYPES and (F, O) != (1.0, 0.0):
                        raise self.fail(f"{flow[0][2].text}: {c.flat.path}.{n[1]} has type "
                                        f"{v.type}; a unit conversion or linear "
                                        f"transformation applies to Real connections only")
                out.append(FlatConnection(f"{src.flat.name}.{leaf[1]}",
                                          f"{comp.flat.name}.{name}", F, O))
        return out


def read_ssp(path: str | Path, fmu_dir: str | Path) -> FlatSystem:
    """Read and flatten an ``.ssp`` file; its FMUs are extracted into ``fmu_dir``."""
    Path(fmu_dir).mkdir(parents=True, exist_ok=True)
    return FlatReader(Path(path), Path(fmu_dir)).read()
