"""SSP XML: namespaces, versions, type names, and the small readers of values and annotations.

SSP 1.0 and SSP 2.0 share their XML namespaces (``http://ssp-standard.org/SSP1/...``); a file
says which version it follows in its ``version`` attribute (``1.0``, ``1.x``, ``2.0``). SSP 2.0
adds the FMI 3.0 types (``Float64``, ``Float32``, ``Int8`` ... ``UInt64``, ``Clock``) to the
connector types (``ssc``) and to the parameter values (``ssv``), arrays of values (space
separated, row-major; ``ssv:String`` through ``ssv:Value`` children), and the connector kinds
``structuralParameter`` and ``constant``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from lxml.etree import _Element as Element

SSP1 = "http://ssp-standard.org/SSP1/"
NS = {k: SSP1 + v for k, v in (("ssd", "SystemStructureDescription"),
                               ("ssc", "SystemStructureCommon"),
                               ("ssv", "SystemStructureParameterValues"),
                               ("ssm", "SystemStructureParameterMapping"),
                               ("ssb", "SystemStructureSignalDictionary"))}
UWC_NS = "urn:uwcosim:ssp:1"  # our annotation: the communication step
FMU_TYPE = "application/x-fmu-sharedlibrary"
PARAMETER_SET_TYPE = "application/x-ssp-parameter-set"
PARAMETER_MAPPING_TYPE = "application/x-ssp-parameter-mapping"
#: the SSP versions read (the major version of a file's ``version`` attribute)
VERSIONS = ("1", "2")
REAL_TYPES = ("Real", "Float64", "Float32")
INTERFACES = {"any": None, "CoSimulation": "cs", "ModelExchange": "me"}
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
SI_EXPONENTS = {"m": {"m": 1}, "rad": {"rad": 1}, "s": {"s": 1}, "m/s": {"m": 1, "s": -1},
                "m/s2": {"m": 1, "s": -2}}
#: SSP 2.0's integer types (SSP 1.0: Integer)
INT_TYPES = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64",
             "UInt64")
#: the type elements of a connector (``ssc``) or a parameter (``ssv``), SSP 1.0 and 2.0
TYPE_NAMES = ("Real", "Float64", "Float32", *INT_TYPES, "Boolean", "String", "Enumeration",
              "Binary", "Clock")
#: SSP 2.0 types and their SSP 1.0 counterparts (for the SSP 1.0 schema check of a 2.0 file)
SSP1_TYPE = {"Float64": "Real", "Float32": "Real",
             **{t: "Integer" for t in INT_TYPES if t != "Integer"}}
#: connector kinds: SSP 1.0, and SSP 2.0's additions (as the 1.0 kind they behave like here)
KINDS = ("input", "output", "parameter", "calculatedParameter", "inout")
SSP2_KINDS = {"structuralParameter": "parameter", "constant": "output"}


def major_version(root: Element) -> str:
    """``"1"`` or ``"2"`` (or another string: not read) from the ``version`` attribute."""
    return (root.get("version") or "").strip().split(".", 1)[0]


def unsupported_element(root: Element) -> str | None:
    """The one-line message for the first element we do not implement, or None."""
    checks = (
        ("ssd:SignalDictionaries/ssd:SignalDictionary", "signal dictionaries"),
        ("ssd:Elements/ssd:SignalDictionaryReference", "signal dictionary references"),
        ("ssd:Connections/ssd:Connection/ssc:BooleanMappingTransformation",
         "boolean mapping transformations on connections"),
        ("ssd:Connections/ssd:Connection/ssc:IntegerMappingTransformation",
         "integer mapping transformations on connections"),
        ("ssd:Connections/ssd:Connection/ssc:EnumerationMappingTransformation",
         "enumeration mapping transformations on connections"),
        ("ssd:Connectors/ssd:Connector/ssc:Clock", "clock connectors"),
        ("ssd:Connectors/ssd:Connector/ssc:Binary", "binary connectors"),
    )
    for system in [root.find("ssd:System", NS), *root.iterfind(".//ssd:System", NS)]:
        if system is None:
            continue
        for elements in [system, *system.iterfind("ssd:Elements/ssd:Component", NS)]:
            for xpath, what in checks:
                el = elements.find(xpath, NS)
                if el is not None:
                    return _unsupported(el, what, system.get("name"))
    return None


def end_name(element: str | None, connector: str) -> str:
    return f"{element}.{connector}" if element else connector


def as_float(text: str | None) -> float | None:
    return None if text is None else float(text)


def type_element(el: Element, prefix: str) -> Element | None:
    """The type child (``ssc:Real``, ``ssv:Float64``...) of a connector or parameter."""
    for child in el:
        if not isinstance(child.tag, str):
            continue
        ns, _, local = child.tag[1:].partition("}")
        if ns == NS[prefix] and local in TYPE_NAMES:
            return child
    return None


def _bool(text: str) -> bool:
    t = text.strip()
    if t in ("true", "1"):
        return True
    if t in ("false", "0"):
        return False
    raise ValueError(f"not a Boolean: {text!r}")


def parse_values(type_: str, el: Element) -> object:
    """The value of an ``ssv`` parameter element of type ``type_``: a Python float, int, bool
    or str, or a list of them (an SSP 2.0 array, row-major). ValueError for a bad text."""
    if type_ == "String":
        items = [v.get("value", "") for v in el.iterfind("ssv:Value", NS)]
        if items:
            return items if len(items) > 1 else items[0]
        return el.get("value", "")
    if type_ == "Enumeration":
        return el.get("value", "").strip()  # the item name (or its number)
    text = el.get("value")
    if text is None:
        raise ValueError("no value attribute")
    parts = text.split()
    if type_ in REAL_TYPES:
        vals: list = [float(p) for p in parts]
    elif type_ in INT_TYPES:
        vals = [int(p) for p in parts]
    elif type_ == "Boolean":
        vals = [_bool(p) for p in parts]
    else:
        raise ValueError(f"type {type_} has no value here")
    if not vals:
        raise ValueError("empty value")
    return vals[0] if len(vals) == 1 else vals


def _unsupported(el, what: str, system: str | None) -> str:
    from lxml import etree

    q = etree.QName(el)
    prefix = {v: k for k, v in NS.items()}.get(q.namespace, "")
    name = el.get("name")
    tag = f"<{prefix}:{q.localname}" + (f" name={name!r}" if name else "") + ">"
    return (f"SystemStructure.ssd: {tag} in system {system!r}: {what} are not supported "
            f"(see docs/ssp.md for the supported subset)")


def step_size(root: Element) -> float | None:
    """The communication step: our annotation on the DefaultExperiment, or a
    ``FixedStepMaster stepSize`` in any annotation (as OMSimulator writes it)."""
    found = None
    for el in root.iter("{*}Annotation"):
        for child in el.iter():
            step = child.get("stepSize")
            if step is not None and (child.tag == f"{{{UWC_NS}}}Experiment"
                                     or child.tag.endswith("FixedStepMaster")):
                if child.tag == f"{{{UWC_NS}}}Experiment":
                    return float(step)
                found = found if found is not None else float(step)
    return found
