"""The model structure of one FMU: which outputs depend directly on which inputs, and whether it
gives their partial derivatives; which of its inputs and outputs share a value reference.

FMI's ``ModelStructure`` lists, for each output, the inputs it depends on directly
(``dependencies``); an output without a dependency list depends on every input. The master's
connection graph (:mod:`uwcosim.master.graph`) adds these edges inside each FMU to find the
stepping order and the algebraic loops; :meth:`~uwcosim.fmi.adapter.FMUAdapter.feedthrough`
gives them under the names an adapter exposes. :func:`provides_directional_derivatives` reads
the capability flag (FMI 2 ``providesDirectionalDerivative``, FMI 3
``providesDirectionalDerivatives``, which fmpy does not read) for an algebraic-loop solver.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription


def feedthrough(md: ModelDescription) -> dict[str, set[str]]:
    """``{output name: {input names it depends on directly}}`` from a model description."""
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    deps: dict[str, set[str]] = {}
    for unknown in md.outputs:
        var = unknown.variable
        if unknown.dependencies is None:
            deps[var.name] = set(inputs)
        else:
            deps[var.name] = {d.name for d in unknown.dependencies if d.name in inputs}
    return deps


def provides_directional_derivatives(md: ModelDescription, path: str | Path,
                                     interface: str) -> bool:
    """True if the FMU declares directional derivatives for ``interface`` (``cs``/``me``)."""
    kind = md.coSimulation if interface == "cs" else md.modelExchange
    if kind is None:
        return False
    if not md.fmiVersion.startswith("3"):
        return bool(getattr(kind, "providesDirectionalDerivative", False))
    path = Path(path)
    try:
        if path.is_dir():
            text = (path / "modelDescription.xml").read_bytes()
        else:
            with zipfile.ZipFile(path) as zf:
                text = zf.read("modelDescription.xml")
        root = ET.fromstring(text)
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return False
    elem = root.find("CoSimulation" if interface == "cs" else "ModelExchange")
    return elem is not None and elem.get("providesDirectionalDerivatives") == "true"


def duplicate_references(md: ModelDescription) -> list[str]:
    """Inputs and outputs that share a value reference where the FMU cannot tell them apart.

    FMI 3 value references are unique in an FMU (aliases are ``<Alias>`` elements, not
    variables): two inputs or outputs with one value reference would read and write one
    value (``vx`` set, then ``vy`` overwrites it). FMI 2 numbers each base type on its own and
    allows aliases (variables of one type sharing a reference are one value); two *inputs* of
    one type sharing a reference are still one value driven twice. One line per clash, e.g.
    ``inputs 'vx' and 'vy' share value reference 3``.
    """
    fmi3 = md.fmiVersion.startswith("3")
    seen: dict[tuple, object] = {}
    out = []
    for v in md.modelVariables:
        if v.causality not in ("input", "output") or (not fmi3 and v.causality != "input"):
            continue
        key = (v.valueReference,) if fmi3 else (v.type, v.valueReference)
        first = seen.setdefault(key, v)
        if first is not v:
            kinds = "inputs" if first.causality == v.causality == "input" else (
                "outputs" if first.causality == v.causality else "input and output")
            out.append(f"{kinds} {first.name!r} and {v.name!r} share value reference "
                       f"{v.valueReference}")
    return out
