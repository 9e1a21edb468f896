"""SSP 1.0 XML: namespaces, type names, and the few small readers fmpy does not provide."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from lxml.etree import _Element as Element

SSP1 = "http://ssp-standard.org/SSP1/"
NS = {k: SSP1 + v for k, v in (("ssd", "SystemStructureDescription"),
                               ("ssc", "SystemStructureCommon"),
                               ("ssv", "SystemStructureParameterValues"))}
UWC_NS = "urn:uwcosim:ssp:1"  # our annotation: the communication step
FMU_TYPE = "application/x-fmu-sharedlibrary"
PARAMETER_SET_TYPE = "application/x-ssp-parameter-set"
REAL_TYPES = ("Real", "Float64", "Float32")
INTERFACES = {"any": None, "CoSimulation": "cs", "ModelExchange": "me"}
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
SI_EXPONENTS = {"m": {"m": 1}, "rad": {"rad": 1}, "s": {"s": 1}, "m/s": {"m": 1, "s": -1},
       "m/s2": {"m": 1, "s": -2}}


def unsupported_element(root: Element) -> str | None:
    """The one-line message for the first element we do not implement, or None."""
    checks = (
        ("ssd:SignalDictionaries/ssd:SignalDictionary", "signal dictionaries"),
        ("ssd:Elements/ssd:SignalDictionaryReference", "signal dictionary references"),
        ("ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterMapping",
         "parameter mappings"),
        ("ssd:Connections/ssd:Connection/ssc:BooleanMappingTransformation",
         "boolean mapping transformations"),
        ("ssd:Connections/ssd:Connection/ssc:IntegerMappingTransformation",
         "integer mapping transformations"),
        ("ssd:Connections/ssd:Connection/ssc:EnumerationMappingTransformation",
         "enumeration mapping transformations"),
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


def parameter_value(p: object) -> float | int | bool | str:
    if p.type == "Real":
        return float(p.value)
    if p.type == "Integer":
        return int(p.value)
    if p.type == "Boolean":
        return p.value.strip() in ("true", "1")
    return p.value


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
