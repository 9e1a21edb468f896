"""Schema checks of the XML files of an SSP, with the XML schemas fmpy ships (SSP 1.0).

fmpy (0.3) ships the SSP 1.0 schemas only (``fmpy/ssp/schema``: SSD, SSV, SSM, SSB). A file of
version 1.x is validated against them as it is. A file of version 2.0 (same namespaces) is
validated against them too, on a copy in which what SSP 2.0 adds is brought back to SSP 1.0:

- the version attribute becomes ``1.0``;
- the FMI 3.0 type elements become their SSP 1.0 counterparts (``Float64``/``Float32`` ->
  ``Real``, ``Int8`` ... ``UInt64`` -> ``Integer``) and a value list (an array) or an integer
  beyond 32 bits is replaced by a placeholder the 1.0 schema accepts;
- the connector kinds ``structuralParameter`` and ``constant`` become ``parameter`` and
  ``output``;
- elements and attributes the 1.0 schema does not know are reported as *not validated*
  (warnings), not as errors.

So in an SSP 2.0 file the structure shared with SSP 1.0 is validated; not validated are the
values of the new types (their ranges and array lengths; uwcosim checks them against the FMU's
variables when it applies them), the ``ssc:Dimension`` elements and every element or attribute
only SSP 2.0 defines (listed by :func:`schema_problems`).
"""

from __future__ import annotations

import copy
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from uwcosim.scenario.ssp.xml import NS, SSP1_TYPE, SSP2_KINDS, major_version

if TYPE_CHECKING:
    from lxml.etree import _Element as Element

#: the schema file of each kind of SSP file (fmpy's names)
SCHEMAS = {"ssd": "SystemStructureDescription.xsd", "ssv": "SystemStructureParameterValues.xsd",
           "ssm": "SystemStructureParameterMapping.xsd"}
#: the libxml2 messages of an element or attribute the schema does not define
_TOP_LEVEL = ("SystemStructureDescription", "ParameterSet", "ParameterMapping",
              "SignalDictionary")
_UNKNOWN = ("This element is not expected", "is not allowed", "No matching global declaration")


@cache
def _schema(kind: str):
    import fmpy.ssp.ssd
    from lxml import etree

    folder = Path(fmpy.ssp.ssd.__file__).resolve().parent / "schema"
    return etree.XMLSchema(file=str(folder / SCHEMAS[kind]))


def _as_ssp1(root: Element) -> Element:
    """A copy of an SSP 2.0 tree with SSP 2.0's additions mapped to SSP 1.0 (module docstring)."""
    root = copy.deepcopy(root)
    for el in root.iter():
        if not isinstance(el.tag, str):
            continue
        ns, _, local = el.tag[1:].partition("}")
        if local in _TOP_LEVEL and el.get("version") is not None:
            el.set("version", "1.0")
        if ns in (NS["ssc"], NS["ssv"]) and local in SSP1_TYPE:
            el.tag = f"{{{ns}}}{SSP1_TYPE[local]}"
            if ns == NS["ssv"] and el.get("value") is not None:
                el.set("value", "0")  # a list or a 64-bit integer: checked when applied
            for dim in list(el):
                if isinstance(dim.tag, str) and dim.tag.endswith("}Dimension"):
                    el.remove(dim)
        elif ns == NS["ssv"] and local == "Real" and len((el.get("value") or "").split()) > 1:
            el.set("value", "0")
        elif ns == NS["ssv"] and local == "String" and len(el):
            values = [v for v in el if isinstance(v.tag, str) and v.tag.endswith("}Value")]
            if values and el.get("value") is None:
                el.set("value", values[0].get("value", ""))
            for v in values:
                el.remove(v)
        if local == "Connector" and el.get("kind") in SSP2_KINDS:
            el.set("kind", SSP2_KINDS[el.get("kind")])
    return root


def schema_problems(root: Element, kind: str) -> tuple[list[str], list[str]]:
    """``(errors, not_validated)`` of an SSD (``kind`` "ssd"), SSV ("ssv") or SSM ("ssm")
    tree: schema errors as ``line N: message``; for an SSP 2.0 file also what the SSP 1.0
    schema could not check (module docstring)."""
    v2 = major_version(root) == "2"
    tree = _as_ssp1(root) if v2 else root
    schema = _schema(kind)
    if schema.validate(tree):
        return [], []
    errors, unknown = [], []
    for e in schema.error_log:
        text = f"line {e.line}: {e.message}"
        if v2 and any(s in e.message for s in _UNKNOWN):
            unknown.append(text)
        else:
            errors.append(text)
    return errors, unknown
