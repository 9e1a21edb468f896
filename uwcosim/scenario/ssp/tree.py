"""The XML files of an SSP read into plain records: the system tree, parameter sets, mappings.

:func:`read_document` reads ``SystemStructure.ssd`` of an archive (SSP 1.0 or 2.0), checks it,
every referenced parameter set (``.ssv``) and parameter mapping (``.ssm``) against the schemas
(:mod:`uwcosim.scenario.ssp.schema`), and returns a :class:`Document`: the root
:class:`System` with its :class:`Component` s and sub-systems, their :class:`Connector` s,
:class:`Connection` s and :class:`Binding` s (each with its :class:`Parameter` s and, when
it has one, its :class:`MappingEntry` s, inline or from an ``.ssm`` file), and the SSD's
:class:`Unit` s. Nothing here knows FMUs: :mod:`uwcosim.scenario.ssp.read` flattens the tree
against them. Every problem is one :class:`~uwcosim.core.errors.ScenarioError` line naming the
file, the element and what was expected.
"""

from __future__ import annotations

import logging
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from uwcosim.core.errors import ScenarioError
from uwcosim.scenario.ssp.schema import schema_problems
from uwcosim.scenario.ssp.xml import (
    BASE_UNITS,
    FMU_TYPE,
    INT_TYPES,
    NS,
    PARAMETER_MAPPING_TYPE,
    PARAMETER_SET_TYPE,
    REAL_TYPES,
    VERSIONS,
    as_float,
    major_version,
    parse_values,
    type_element,
    unsupported_element,
)

if TYPE_CHECKING:
    from lxml.etree import _Element as Element

log = logging.getLogger(__name__)
#: the ``ssv`` parameter types whose values are applied
PARAMETER_TYPES = (*REAL_TYPES, *INT_TYPES, "Boolean", "String", "Enumeration")


@dataclass
class Connector:
    name: str
    kind: str
    type: str | None = None  # "Real", "Float64", "Int8"... (None: from the FMU variable)
    unit: str | None = None


@dataclass
class Parameter:
    name: str
    type: str
    value: object  # float, int, bool, str, or a list of them (an array)
    unit: str | None = None


@dataclass
class MappingEntry:
    """``target`` takes the value of the parameter ``source``, transformed."""

    source: str
    target: str
    factor: float = 1.0  # ssc:LinearTransformation
    offset: float = 0.0
    values: dict | None = None  # a Boolean/Integer/Enumeration mapping transformation
    suppress_units: bool = False


@dataclass
class Binding:
    """One ``ssd:ParameterBinding``: its parameters and (optional) mapping."""

    where: str  # the parameter set's archive member, or "inline ssd:ParameterValues"
    prefix: str = ""
    parameters: list[Parameter] = field(default_factory=list)
    mapping: list[MappingEntry] | None = None


@dataclass
class Connection:
    start_element: str | None
    start_connector: str
    end_element: str | None
    end_connector: str
    factor: float = 1.0
    offset: float = 0.0
    suppress_units: bool = False


@dataclass
class Component:
    name: str
    source: str | None
    type: str = FMU_TYPE
    implementation: str = "any"
    connectors: list[Connector] = field(default_factory=list)
    bindings: list[Binding] = field(default_factory=list)


@dataclass
class System:
    name: str
    description: str = ""
    connectors: list[Connector] = field(default_factory=list)
    bindings: list[Binding] = field(default_factory=list)
    elements: list[Component | System] = field(default_factory=list)
    connections: list[Connection] = field(default_factory=list)


@dataclass
class Unit:
    name: str
    exponents: tuple[int, ...]  # of BASE_UNITS
    factor: float = 1.0
    offset: float = 0.0


@dataclass
class Document:
    name: str
    version: str
    system: System
    root: Element
    units: dict[str, Unit] = field(default_factory=dict)
    #: what the schema check could not validate (SSP 2.0 elements unknown to the 1.0 schema)
    not_validated: list[str] = field(default_factory=list)


class _DocumentReader:
    def __init__(self, zf: zipfile.ZipFile, fail: Callable[[str], ScenarioError]) -> None:
        self.zf = zf
        self.members = set(zf.namelist())
        self.fail = fail
        self.not_validated: list[str] = []

    # -- files --------------------------------------------------------------------------------
    def parse(self, member: str, kind: str) -> Element:
        from lxml import etree  # lazy: lxml only when an SSP is read

        if member not in self.members:
            raise self.fail(f"file {member!r} named in SystemStructure.ssd is not in the archive")
        try:
            root = etree.fromstring(self.zf.read(member))
        except etree.XMLSyntaxError as exc:
            raise self.fail(f"{member}: invalid XML ({exc})") from None
        self.check(root, member, kind)
        return root

    def check(self, root: Element, member: str, kind: str) -> None:
        from lxml import etree

        q = etree.QName(root)
        expected = {"ssd": "SystemStructureDescription", "ssv": "ParameterSet",
                    "ssm": "ParameterMapping"}[kind]
        if q.namespace != NS[kind] or q.localname != expected:
            raise self.fail(f"{member}: <{q.localname}> in namespace {q.namespace!r} "
                            f"(version {root.get('version', '?')}) is not supported: uwcosim "
                            f"reads SSP 1.x and 2.0 ({NS[kind]}, <{kind}:{expected}>)")
        major = major_version(root)
        if major not in VERSIONS:
            raise self.fail(f"{member}: version {root.get('version')!r} is not supported "
                            f"(uwcosim reads SSP 1.x and 2.0)")
        errors, unknown = schema_problems(root, kind)
        if errors:
            what = ("the SSP 1.0 schema" if major == "1" else
                    "the SSP 2.0 schema (checked with the SSP 1.0 schema, see docs/ssp.md)")
            raise self.fail(f"{member}: does not follow {what}: {'; '.join(errors[:2])}")
        self.not_validated += [f"{member}: {u}" for u in unknown]

    # -- the system tree --------------------------------------------------------------------
    def document(self) -> Document:
        root = self.parse("SystemStructure.ssd", "ssd")
        msg = unsupported_element(root)
        if msg:
            raise self.fail(msg)
        units = {}
        for u in root.iterfind("ssd:Units/ssc:Unit", NS):
            base = u.find("ssc:BaseUnit", NS)
            b = base.attrib if base is not None else {}
            units[u.get("name")] = Unit(u.get("name"), tuple(int(b.get(k, 0)) for k in BASE_UNITS),
                                        float(b.get("factor", 1.0)), float(b.get("offset", 0.0)))
        system = self.system(root.find("ssd:System", NS))
        return Document(root.get("name") or system.name, root.get("version", ""), system, root,
                        units, self.not_validated)

    def connectors(self, xml: Element) -> list[Connector]:
        out = []
        for c in xml.iterfind("ssd:Connectors/ssd:Connector", NS):
            t = type_element(c, "ssc")
            out.append(Connector(c.get("name"), c.get("kind"),
                                 None if t is None else t.tag.rpartition("}")[2],
                                 None if t is None else t.get("unit")))
        return out

    def system(self, xml: Element) -> System:
        s = System(xml.get("name"), xml.get("description") or "", self.connectors(xml),
                   self.bindings(xml, f"system {xml.get('name')!r}"))
        for el in xml.iterfind("ssd:Elements/*", NS):
            local = el.tag.rpartition("}")[2]
            if local == "System":
                s.elements.append(self.system(el))
            elif local == "Component":
                s.elements.append(Component(
                    el.get("name"), el.get("source"), el.get("type", FMU_TYPE),
                    el.get("implementation", "any"), self.connectors(el),
                    self.bindings(el, f"component {el.get('name')!r}")))
        for c in xml.iterfind("ssd:Connections/ssd:Connection", NS):
            lt = c.find("ssc:LinearTransformation", NS)
            s.connections.append(Connection(
                c.get("startElement"), c.get("startConnector"), c.get("endElement"),
                c.get("endConnector"),
                as_float(lt.get("factor", "1")) if lt is not None else 1.0,
                as_float(lt.get("offset", "0")) if lt is not None else 0.0,
                c.get("suppressUnitConversion", "false") in ("true", "1")))
        return s

    # -- parameters ---------------------------------------------------------------------------
    def bindings(self, xml: Element, owner: str) -> list[Binding]:
        out = []
        for b in xml.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            typ = b.get("type", PARAMETER_SET_TYPE)
            if typ != PARAMETER_SET_TYPE:
                raise self.fail(f"{owner}: <ssd:ParameterBinding type={typ!r}> is not "
                                f"supported (only {PARAMETER_SET_TYPE!r})")
            source = b.get("source")
            if source is not None:
                where, ps = source, self.parse(source, "ssv")
            else:
                where = "inline ssd:ParameterValues"
                ps = b.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            binding = Binding(where, b.get("prefix") or "",
                              self.parameters(ps, where) if ps is not None else [])
            m = b.find("ssd:ParameterMapping", NS)
            if m is not None:
                binding.mapping = self.mapping(m, owner)
            out.append(binding)
        return out

    def parameters(self, ps: Element, where: str) -> list[Parameter]:
        out = []
        for p in ps.iterfind("ssv:Parameters/ssv:Parameter", NS):
            name = p.get("name")
            t = type_element(p, "ssv")
            typ = None if t is None else t.tag.rpartition("}")[2]
            if typ not in PARAMETER_TYPES:
                raise self.fail(f"{where}: parameter {name!r}: type {typ} is not supported "
                                f"({', '.join(PARAMETER_TYPES)})")
            try:
                value = parse_values(typ, t)
            except ValueError as exc:
                raise self.fail(f"{where}: parameter {name!r}: bad {typ} value "
                                f"{t.get('value')!r} ({exc})") from None
            out.append(Parameter(name, typ, value, t.get("unit")))
        return out

    def mapping(self, m: Element, owner: str) -> list[MappingEntry]:
        typ = m.get("type", PARAMETER_MAPPING_TYPE)
        if typ != PARAMETER_MAPPING_TYPE:
            raise self.fail(f"{owner}: <ssd:ParameterMapping type={typ!r}> is not supported "
                            f"(only {PARAMETER_MAPPING_TYPE!r})")
        source = m.get("source")
        if source is not None:
            where, root = source, self.parse(source, "ssm")
        else:
            where, root = f"{owner}: inline ssm:ParameterMapping", m.find("ssm:ParameterMapping",
                                                                         NS)
            if root is None:
                raise self.fail(f"{owner}: <ssd:ParameterMapping> has neither a source nor an "
                                f"inline <ssm:ParameterMapping>")
            self.check(root, where, "ssm")
        out = []
        for e in root.iterfind("ssm:MappingEntry", NS):
            entry = MappingEntry(e.get("source"), e.get("target"),
                                 suppress_units=e.get("suppressUnitConversion", "false")
                                 in ("true", "1"))
            lt = e.find("ssc:LinearTransformation", NS)
            if lt is not None:
                entry.factor = float(lt.get("factor", 1.0))
                entry.offset = float(lt.get("offset", 0.0))
            for kind, conv in (("Boolean", lambda s: s.strip() in ("true", "1")),
                               ("Integer", int), ("Enumeration", str)):
                vm = e.find(f"ssc:{kind}MappingTransformation", NS)
                if vm is not None:
                    try:
                        entry.values = {conv(x.get("source")): conv(x.get("target"))
                                        for x in vm.iterfind("ssc:MapEntry", NS)}
                    except (TypeError, ValueError):
                        raise self.fail(f"{where}: mapping entry {entry.source!r} -> "
                                        f"{entry.target!r}: bad {kind}MappingTransformation "
                                        f"entries") from None
            out.append(entry)
        return out


def read_document(zf: zipfile.ZipFile, fail: Callable[[str], ScenarioError]) -> Document:
    """``SystemStructure.ssd`` of the archive ``zf`` with its parameter sets and mappings
    (checked against the schemas); ``fail(message)`` makes the error to raise."""
    if "SystemStructure.ssd" not in zf.namelist():
        raise fail("no SystemStructure.ssd in the archive")
    return _DocumentReader(zf, fail).document()
