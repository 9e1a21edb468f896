"""Connection graph: Gauss-Seidel stepping order and algebraic-loop detection.

Variables are nodes; a connection ``a.y -> b.u`` is an edge, and inside an FMU an edge
``u -> y`` exists where the output ``y`` depends directly on the input ``u`` (its
ModelStructure, :func:`uwcosim.fmi.structure.feedthrough`; no dependency list means "depends on
every input"). A cycle in this graph is an algebraic loop. FMUs are stepped in topological
order of the FMU graph restricted to feedthrough edges, which is Gauss-Seidel: a downstream FMU
sees its upstream's outputs of the same communication point.
"""

from __future__ import annotations

from graphlib import CycleError, TopologicalSorter

from uwcosim.core.errors import AlgebraicLoopError


def stepping_order(
    fmus: list[str],
    connections: list[tuple[str, str]],
    deps: dict[str, dict[str, set[str]]],
) -> list[str]:
    """Topological FMU order; raise :class:`AlgebraicLoopError` naming the loop's variables."""
    var_graph: dict[str, set[str]] = {}
    for src, dst in connections:
        var_graph.setdefault(dst, set()).add(src)  # dst depends on src
    for fmu, outs in deps.items():
        for out, ins in outs.items():
            var_graph.setdefault(f"{fmu}.{out}", set()).update(f"{fmu}.{i}" for i in ins)
    try:
        tuple(TopologicalSorter(var_graph).static_order())
    except CycleError as exc:
        # graphlib lists the cycle with each node a predecessor of the next: the data flow
        loop = " -> ".join(exc.args[1])
        raise AlgebraicLoopError(f"algebraic loop between FMUs: {loop}") from None
    fmu_graph: dict[str, set[str]] = {f: set() for f in fmus}
    for src, dst in connections:
        sf, sv = src.split(".", 1)
        df, dv = dst.split(".", 1)
        if sf == df:
            continue
        # an input with no direct feedthrough may take the previous value: no ordering edge
        if any(dv in ins for ins in deps.get(df, {}).values()):
            fmu_graph[df].add(sf)
    try:
        order = list(TopologicalSorter(fmu_graph).static_order())
    except CycleError:
        # a feedback loop through states (not algebraic): keep the scenario's order
        order = list(fmus)
    return order
