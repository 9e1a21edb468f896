"""The model structure of one FMU: which outputs depend directly on which inputs.

FMI's ``ModelStructure`` lists, for each output, the inputs it depends on directly
(``dependencies``); an output without a dependency list depends on every input. The master's
connection graph (:mod:`uwcosim.master.graph`) adds these edges inside each FMU to find the
stepping order and the algebraic loops; :meth:`~uwcosim.fmi.adapter.FMUAdapter.feedthrough`
gives them under the names an adapter exposes.
"""

from __future__ import annotations

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
