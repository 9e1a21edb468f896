"""The model structure of one FMU: which outputs depend directly on which inputs, and whether it
gives their partial derivatives.

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
