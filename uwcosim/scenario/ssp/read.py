"""Read an SSP 1.0 file (System Structure and Parameterization) into one flat FMU network.

fmpy's reader (:func:`fmpy.ssp.ssd.read_ssd`) validates ``SystemStructure.ssd`` against the
SSP 1.0 schema, walks the element tree and reads the parameter sets (``.ssv``, also validated).
What it does not read is read here from the same XML: the ``DefaultExperiment``, connector types
and units, the transformation on a connection (fmpy 0.3 looks for ``ssd:LinearTransformation``;
the schema puts it in the ``ssc`` namespace), ``suppressUnitConversion`` and the component's
``implementation``.

Flattening: components of sub-systems get the name ``sub_comp`` (the master splits signal names
``fmu.variable`` at the first dot, so the dot cannot join them); every FMU input is traced back
through system connectors to the one FMU output that drives it, composing on the way the unit
conversions and linear transformations of every connection crossed (SSP 1.0: the source value is
converted to the target unit first, then ``target = factor * source + offset``). Parameter
bindings: on a component the names are its variables; on a system they are ``elem.var``
(``sub.elem.var`` ...) or a parameter connector of the system, followed through its
connections. A binding higher in the hierarchy overrides a lower one; within one element, a
later binding overrides an earlier one; names that match no variable are ignored (all three as
the SSP 1.0 schema documents ParameterBinding) and listed in :attr:`FlatSystem.ignored`.
Every unsupported element is one :class:`~uwcosim.core.errors.ScenarioError` line naming it.
"""

from __future__ import annotations

import zipfile
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from urllib.parse import unquote

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.archive import open_description
from uwcosim.fmi.varmap import UNITS, canonical_unit, fmu_unit
from uwcosim.scenario.ssp.xml import (
    BASE_UNITS,
    FMU_TYPE,
    INTERFACES,
    NS,
    PARAMETER_SET_TYPE,
    REAL_TYPES,
    SI_EXPONENTS,
    as_float,
    end_name,
    parameter_value,
    step_size,
    unsupported_element,
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
    #: bound parameters that match no variable (SSP 1.0: ignored), as "source: name"
    ignored: list[str] = field(default_factory=list)


@dataclass
class _Connector:
    kind: str
    type: str | None
    unit: str | None


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
    connectors: dict[str, _Connector]
    obj: object  # fmpy Component


class _Reader:
    def __init__(self, path: Path, fmu_dir: Path) -> None:
        self.path = Path(path)
        self.where = f"{self.path}"
        self.fmu_dir = Path(fmu_dir)
        self.comps: dict[tuple, _Comp] = {}
        self.systems: dict[tuple, tuple[object, dict[str, _Connector]]] = {}
        self.adj: dict[tuple, list[tuple[tuple, _Edge]]] = {}
        self.extracted: dict[str, Path] = {}
        self.units: dict[str, tuple[tuple, float, float]] = {}
        self.ignored: list[str] = []

    def fail(self, msg: str) -> ScenarioError:
        return ScenarioError(f"{self.where}: {msg}")

    # -- reading ----------------------------------------------------------------------------
    def read(self) -> FlatSystem:
        from lxml import etree  # lazy: lxml and fmpy's SSP reader only when an SSP is read

        try:
            zf = zipfile.ZipFile(self.path)
        except (OSError, zipfile.BadZipFile) as exc:
            raise self.fail(f"not an SSP archive (a zip file): {exc}") from None
        with zf:
            self.members = set(zf.namelist())
            if "SystemStructure.ssd" not in self.members:
                raise self.fail("no SystemStructure.ssd in the archive")
            try:
                root = etree.fromstring(zf.read("SystemStructure.ssd"))
            except etree.XMLSyntaxError as exc:
                raise self.fail(f"SystemStructure.ssd: invalid XML ({exc})") from None
            ns = etree.QName(root).namespace or ""
            if ns != NS["ssd"]:
                version = root.get("version", "?")
                raise self.fail(f"SystemStructure.ssd: <{etree.QName(root).localname}> in "
                                f"namespace {ns!r} (version {version}) is not supported: "
                                f"uwcosim reads SSP 1.x ({NS['ssd']})")
            msg = unsupported_element(root)
            if msg:
                raise self.fail(msg)
            ssd = self._fmpy_read()
            for u in ssd.units:
                self.units[u.name] = (tuple(getattr(u, k) for k in BASE_UNITS), u.factor, u.offset)
            self._walk(ssd.system, root.find("ssd:System", NS), (), zf)
        flat_names: dict[str, str] = {}
        for c in self.comps.values():
            other = flat_names.setdefault(c.flat.name, c.flat.path)
            if other != c.flat.path:
                raise self.fail(f"components {other!r} and {c.flat.path!r} both flatten to the "
                                f"name {c.flat.name!r}; rename one")
        connections = self._connections()
        self._bind_system(())
        exp = root.find("ssd:DefaultExperiment", NS)
        start = stop = None
        if exp is not None:
            start = as_float(exp.get("startTime"))
            stop = as_float(exp.get("stopTime"))
        comps = {c.flat.name: c.flat for c in self.comps.values()}
        return FlatSystem(name=ssd.name or self.path.stem, components=comps,
                          connections=connections, start_time=start, stop_time=stop,
                          step=step_size(root), ignored=self.ignored,
                          description=ssd.system.description or "")

    def _fmpy_read(self):
        from fmpy.ssp.ssd import read_ssd  # lazy: as in read

        try:
            return read_ssd(str(self.path), validate=True)
        except KeyError as exc:  # a parameter set named by a binding is not in the archive
            raise self.fail(f"file {exc} named in SystemStructure.ssd is not in the "
                            f"archive") from None
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions on schema errors
            lines = [s.strip() for s in str(exc).splitlines() if s.strip()]
            if lines and lines[0].startswith("Failed to validate"):
                # fmpy names SystemStructure.ssd also when a parameter set (.ssv) is invalid
                raise self.fail(f"does not follow the SSP 1.0 schema (SystemStructure.ssd or "
                                f"a parameter set): {'; '.join(lines[1:3])}") from None
            raise self.fail(f"cannot be read by fmpy's SSP reader ({type(exc).__name__}: "
                            f"{' '.join(lines)})") from None

    def _extract(self, zf: zipfile.ZipFile, source: str, comp: str) -> Path:
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

    def _connectors(self, xml, owner: str, variables: dict | None) -> dict[str, _Connector]:
        out = {}
        for c in xml.iterfind("ssd:Connectors/ssd:Connector", NS):
            name, kind = c.get("name"), c.get("kind")
            if kind == "inout":
                raise self.fail(f"{owner}: <ssd:Connector name={name!r} kind='inout'> is not "
                                f"supported")
            typ = unit = None
            for t in ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary"):
                el = c.find(f"ssc:{t}", NS)
                if el is not None:
                    typ, unit = t, el.get("unit")
            if variables is not None and name not in variables:
                raise self.fail(f"{owner}: connector {name!r} is not a variable of the FMU")
            out[name] = _Connector(kind, typ, unit)
        return out

    def _walk(self, system, xml, path: tuple, zf) -> None:
        """Collect components, system connectors and connection edges of ``system``."""
        from fmpy.ssp.ssd import Component  # lazy: as in read

        label = ".".join(path) or system.name
        self.systems[path] = (system, self._connectors(xml, f"system {label!r}", None))
        comp_xml = {c.get("name"): c for c in xml.iterfind("ssd:Elements/ssd:Component", NS)}
        sys_xml = {s.get("name"): s for s in xml.iterfind("ssd:Elements/ssd:System", NS)}
        for el in system.elements:
            p = (*path, el.name)
            if not isinstance(el, Component):
                self._walk(el, sys_xml[el.name], p, zf)
                continue
            cx = comp_xml[el.name]
            hname = ".".join(p)
            typ = cx.get("type", FMU_TYPE)
            if typ != FMU_TYPE:
                raise self.fail(f"component {hname!r}: type {typ!r} is not supported (only "
                                f"FMUs, {FMU_TYPE!r})")
            fmu = self._extract(zf, el.source, hname)
            md = open_description(fmu)
            variables = {v.name: v for v in md.modelVariables}
            interface = INTERFACES[cx.get("implementation", "any")]
            if interface is None and md.coSimulation is None:
                interface = "me"  # "any" and the FMU has model exchange only
            flat = FlatComponent(name="_".join(p), path=hname, source=el.source, fmu=fmu,
                                 interface=interface)
            conns = self._connectors(cx, f"component {hname!r}", variables)
            self.comps[p] = _Comp(flat, md, variables, conns, el)
        for c, cx in zip(system.connections,
                         xml.iterfind("ssd:Connections/ssd:Connection", NS), strict=False):
            a = ((*path, c.startElement) if c.startElement else path, c.startConnector)
            b = ((*path, c.endElement) if c.endElement else path, c.endConnector)
            lt = cx.find("ssc:LinearTransformation", NS)
            text = (f"connection {end_name(c.startElement, c.startConnector)} -> "
                    f"{end_name(c.endElement, c.endConnector)} in system {label!r}")
            edge = _Edge(as_float(lt.get("factor")) if lt is not None else None,
                         as_float(lt.get("offset")) if lt is not None else None,
                         cx.get("suppressUnitConversion", "false") in ("true", "1"), text)
            edge.factor = 1.0 if edge.factor is None else edge.factor
            edge.offset = 0.0 if edge.offset is None else edge.offset
            for node in (a, b):
                self._connector(node, text)
            self.adj.setdefault(a, []).append((b, edge))
            self.adj.setdefault(b, []).append((a, edge))

    def _connector(self, node: tuple, text: str) -> _Connector:
        path, name = node
        if path in self.comps:
            comp = self.comps[path]
            if name in comp.connectors:
                return comp.connectors[name]
            v = comp.variables.get(name)
            if v is None:
                raise self.fail(f"{text}: component {'.'.join(path)!r} has no connector or "
                                f"FMU variable {name!r}")
            return _Connector(v.causality, None, None)
        if path in self.systems:
            conn = self.systems[path][1].get(name)
            if conn is None:
                raise self.fail(f"{text}: system {'.'.join(path) or 'root'!r} has no "
                                f"connector {name!r}")
            return conn
        raise self.fail(f"{text}: no element {'.'.join(path)!r}")

    # -- connections ------------------------------------------------------------------------
    def _reach(self, start: tuple) -> list[tuple[tuple, list[tuple[tuple, tuple, _Edge]]]]:
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

    def _convert(self, u_from: str, n_from: tuple, u_to: str, n_to: tuple,
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

    def _compose(self, hops, unit: str | None, node0: tuple) -> tuple[float, float]:
        """Affine map ``(F, O)`` of the value along ``hops`` (in the direction of flow)."""
        F, O = 1.0, 0.0
        for _, b, e in hops:
            u_b = self._unit(b)
            if u_b and unit and not e.suppress:
                ca, cb = self._convert(unit, node0, u_b, b, e.text)
                F, O = ca * F, ca * O + cb
            unit = u_b or unit
            F, O = e.factor * F, e.factor * O + e.offset
        return F, O

    def _connections(self) -> list[FlatConnection]:
        out = []
        for path, comp in self.comps.items():
            for name in sorted({n for p, n in self.adj if p == path}):
                node = (path, name)
                kind = self._connector(node, f"component {comp.flat.path!r}").kind
                if kind == "calculatedParameter":
                    raise self.fail(f"connector {comp.flat.path}.{name}: parameter "
                                    f"connections (calculatedParameter -> parameter) are not "
                                    f"supported")
                if kind != "input":
                    continue
                sources = [(leaf, hops) for leaf, hops in self._reach(node)
                           if self._connector(leaf, "").kind == "output"]
                if len(sources) > 1:
                    names = ", ".join(f"{'.'.join(s[0])}.{s[1]}" for s, _ in sources)
                    raise self.fail(f"input {comp.flat.path}.{name} is driven by more than "
                                    f"one output ({names})")
                if not sources:
                    continue
                leaf, hops = sources[0]
                flow = [(b, a, e) for a, b, e in reversed(hops)]
                src = self.comps[leaf[0]]
                for n, c in ((leaf, src), (node, comp)):
                    v = c.variables[n[1]]
                    if v.type not in REAL_TYPES:
                        raise self.fail(f"{flow[0][2].text}: {c.flat.path}.{n[1]} has type "
                                        f"{v.type}; only Real connections are supported")
                F, O = self._compose(flow, self._unit(leaf), leaf)
                out.append(FlatConnection(f"{src.flat.name}.{leaf[1]}",
                                          f"{comp.flat.name}.{name}", F, O))
        return out

    # -- parameters -------------------------------------------------------------------------
    def _bindings(self, element, owner: str):
        """``(name, value, unit, where)`` of every parameter of ``element``'s bindings."""
        for b in element.parameterBindings:
            if (b.type or PARAMETER_SET_TYPE) != PARAMETER_SET_TYPE:
                raise self.fail(f"{owner}: <ssd:ParameterBinding type={b.type!r}> is not "
                                f"supported (only {PARAMETER_SET_TYPE!r})")
            where = b.source or "inline ssd:ParameterValues"
            for ps in b.parameterValues:
                for p in ps.parameters:
                    if p.type not in ("Real", "Integer", "Boolean", "String"):
                        raise self.fail(f"{where}: parameter {p.name!r}: type {p.type} is not "
                                        f"supported (Real, Integer, Boolean, String)")
                    yield (b.prefix or "") + p.name, parameter_value(p), p.unit, where

    def _assign(self, path: tuple, var: str, value, unit, where: str, F=1.0, O=0.0) -> None:
        comp = self.comps[path]
        v = comp.variables.get(var)
        if v is None:  # SSP 1.0: names that match no variable are ignored
            self.ignored.append(f"{where}: {comp.flat.path}.{var}")
            return
        if v.type in REAL_TYPES:
            if isinstance(value, str):
                raise self.fail(f"{where}: parameter {var!r}: a string for the Real variable "
                                f"of component {comp.flat.path!r}")
            value = float(value)
            theirs = fmu_unit(v)
            if unit and theirs and unit != theirs:
                a, b = self._convert(unit, (path, var), theirs, (path, var),
                                     f"{where}: parameter {var!r}")
                value = a * value + b
            value = F * value + O
        elif isinstance(value, float) and value.is_integer() and v.type != "String":
            value = int(value)  # a Real in the parameter set for an Integer variable
        target = (comp.flat.parameters if v.causality in ("parameter", "calculatedParameter")
                  or v.type not in REAL_TYPES else comp.flat.start)
        comp.flat.parameters.pop(var, None)
        comp.flat.start.pop(var, None)
        target[var] = value

    def _bind_system(self, path: tuple) -> None:
        """Apply bindings bottom-up: a system's bindings override its elements' own."""
        system, connectors = self.systems[path]
        for el in system.elements:
            p = (*path, el.name)
            if p in self.comps:
                for name, value, unit, where in self._bindings(el, f"component {'.'.join(p)}"):
                    self._assign(p, name, value, unit, where)
            else:
                self._bind_system(p)
        label = ".".join(path) or system.name
        for name, value, unit, where in self._bindings(system, f"system {label!r}"):
            self._bind_name(path, name, value, unit, where)

    def _bind_name(self, path: tuple, name: str, value, unit, where: str) -> None:
        system, connectors = self.systems[path]
        if name in connectors:
            node = (path, name)
            for leaf, hops in self._reach(node):
                if self._connector(leaf, "").kind == "parameter":
                    F, O = (1.0, 0.0) if isinstance(value, str | bool) else \
                        self._compose(hops, unit, node)
                    self._assign(leaf[0], leaf[1], value, None, where, F, O)
            return
        for el in sorted(system.elements, key=lambda e: -len(e.name)):
            if name.startswith(el.name + "."):
                rest, p = name[len(el.name) + 1:], (*path, el.name)
                if p in self.comps:
                    self._assign(p, rest, value, unit, where)
                else:
                    self._bind_name(p, rest, value, unit, where)
                return
        self.ignored.append(f"{where}: {'.'.join((*path, name))}")  # matches nothing: ignored


def read_ssp(path: str | Path, fmu_dir: str | Path) -> FlatSystem:
    """Read and flatten an ``.ssp`` file; its FMUs are extracted into ``fmu_dir``."""
    Path(fmu_dir).mkdir(parents=True, exist_ok=True)
    return _Reader(Path(path), Path(fmu_dir)).read()
