"""Connection graph: stepping order, algebraic loops and the order of coupled FMU groups.

Variables are nodes; a connection ``a.y -> b.u`` is an edge, and inside an FMU an edge
``u -> y`` exists where the output ``y`` depends directly on the input ``u`` (its
ModelStructure, :func:`uwcosim.fmi.structure.feedthrough`; no dependency list means "depends on
every input"). A cycle in this graph is an algebraic loop: :func:`algebraic_loops` gives each
strongly connected set of variables as a :class:`Loop` (its variables, its FMUs and one cycle
along the data flow for messages). FMUs are stepped in topological order of the FMU graph
restricted to feedthrough edges (:func:`stepping_order`), which is Gauss-Seidel: a downstream FMU
sees its upstream's outputs of the same communication point. FMUs that must be handled together
(the FMUs of an algebraic loop, model-exchange FMUs integrated as one system) are merged into
one unit first (:func:`unit_order`).
"""

from __future__ import annotations

from dataclasses import dataclass
from graphlib import CycleError, TopologicalSorter

from uwcosim.core.errors import AlgebraicLoopError

Deps = dict[str, dict[str, set[str]]]


@dataclass(frozen=True)
class Loop:
    """A strongly connected set of variables of the feedthrough graph: an algebraic loop."""

    #: its variables (``fmu.variable``), sorted
    variables: tuple[str, ...]
    #: the FMUs it goes through, in the system's order
    fmus: tuple[str, ...]
    #: one cycle through it along the data flow, first variable repeated at the end
    cycle: tuple[str, ...]

    def message(self) -> str:
        """``a.y -> b.u -> b.y -> a.u -> a.y``: each arrow a connection or a feedthrough."""
        return " -> ".join(self.cycle)


def variable_graph(connections: list[tuple[str, str]], deps: Deps) -> dict[str, set[str]]:
    """``{variable: the variables it depends on directly}`` (connections and feedthrough)."""
    graph: dict[str, set[str]] = {}
    for src, dst in connections:
        graph.setdefault(dst, set()).add(src)  # dst depends on src
    for fmu, outs in deps.items():
        for out, ins in outs.items():
            graph.setdefault(f"{fmu}.{out}", set()).update(f"{fmu}.{i}" for i in ins)
    return graph


def strongly_connected(succ: dict[str, list[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of ``{node: successors}`` (iterative), in
    reverse topological order of the condensation."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    for root in succ:
        if root in index:
            continue
        work = [(root, iter(succ.get(root, ())))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, it = work[-1]
            nxt = next(it, None)
            if nxt is not None:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(succ.get(nxt, ()))))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    v = stack.pop()
                    on_stack.discard(v)
                    comp.append(v)
                    if v == node:
                        break
                out.append(comp)
    return out


def _cycle(members: set[str], succ: dict[str, list[str]], start: str) -> list[str]:
    """A shortest cycle from ``start`` back to it inside ``members`` (breadth first)."""
    prev: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt_frontier = []
        for node in frontier:
            for nxt in succ.get(node, ()):
                if nxt not in members:
                    continue
                if nxt == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(prev[path[-1]])
                    return [*reversed(path), start]
                if nxt not in prev:
                    prev[nxt] = node
                    nxt_frontier.append(nxt)
        frontier = nxt_frontier
    return [start, start]


def algebraic_loops(fmus: list[str], connections: list[tuple[str, str]],
                    deps: Deps) -> list[Loop]:
    """The algebraic loops of a system (none: an empty list), in the system's FMU order."""
    graph = variable_graph(connections, deps)
    succ: dict[str, list[str]] = {}
    for node, preds in graph.items():
        succ.setdefault(node, [])
        for p in sorted(preds):
            succ.setdefault(p, []).append(node)
    rank = {f: i for i, f in enumerate(fmus)}
    loops = []
    for comp in strongly_connected(succ):
        members = set(comp)
        if len(comp) == 1 and comp[0] not in succ.get(comp[0], ()):
            continue
        variables = tuple(sorted(members))
        owners = {v.split(".", 1)[0] for v in variables}
        order = sorted(owners, key=lambda f: rank.get(f, len(rank)))
        # start at an output of the first FMU, so the message reads from a connection
        first = [v for v in variables if v.split(".", 1)[0] == order[0]]
        outs = [v for v in first if any(v == s for s, _ in connections)]
        loops.append(Loop(variables, tuple(order),
                          tuple(_cycle(members, succ, (outs or first)[0]))))
    loops.sort(key=lambda lp: (rank.get(lp.fmus[0], len(rank)), lp.variables))
    return loops


def _fmu_edges(fmus: list[str], connections: list[tuple[str, str]],
               deps: Deps) -> dict[str, set[str]]:
    """``{fmu: the FMUs it must be stepped after}``: connections into feedthrough inputs."""
    fmu_graph: dict[str, set[str]] = {f: set() for f in fmus}
    for src, dst in connections:
        sf, sv = src.split(".", 1)
        df, dv = dst.split(".", 1)
        if sf == df:
            continue
        # an input with no direct feedthrough may take the previous value: no ordering edge
        if any(dv in ins for ins in deps.get(df, {}).values()):
            fmu_graph[df].add(sf)
    return fmu_graph


def stepping_order(
    fmus: list[str],
    connections: list[tuple[str, str]],
    deps: Deps,
) -> list[str]:
    """Topological FMU order; raise :class:`AlgebraicLoopError` naming the loop's variables."""
    try:
        tuple(TopologicalSorter(variable_graph(connections, deps)).static_order())
    except CycleError as exc:
        # graphlib lists the cycle with each node a predecessor of the next: the data flow
        loop = " -> ".join(exc.args[1])
        raise AlgebraicLoopError(f"algebraic loop between FMUs: {loop}") from None
    fmu_graph = _fmu_edges(fmus, connections, deps)
    try:
        order = list(TopologicalSorter(fmu_graph).static_order())
    except CycleError:
        # a feedback loop through states (not algebraic): keep the scenario's order
        order = list(fmus)
    return order


def merge_groups(fmus: list[str], groups: list[set[str]]) -> list[list[str]]:
    """The units of FMUs handled together: overlapping ``groups`` merged, every other FMU a
    unit of its own; members in the system's order, units by their first member."""
    parent = {f: f for f in fmus}

    def find(f: str) -> str:
        while parent[f] != f:
            parent[f] = parent[parent[f]]
            f = parent[f]
        return f

    for g in groups:
        g = [f for f in fmus if f in g]
        for f in g[1:]:
            parent[find(f)] = find(g[0])
    units: dict[str, list[str]] = {}
    for f in fmus:
        units.setdefault(find(f), []).append(f)
    return list(units.values())


def unit_order(fmus: list[str], connections: list[tuple[str, str]], deps: Deps,
               units: list[list[str]]) -> list[list[str]]:
    """The units in stepping order (topological over the feedthrough edges between units; the
    system's order where they form a cycle through states). Units of one FMU each, without
    loops: the order of :func:`stepping_order`."""
    if all(len(u) == 1 for u in units):
        fmu_graph = _fmu_edges(fmus, connections, deps)
        try:
            return [[f] for f in TopologicalSorter(fmu_graph).static_order()]
        except CycleError:
            return [[f] for f in fmus]
    of = {f: i for i, u in enumerate(units) for f in u}
    graph: dict[int, set[int]] = {i: set() for i in range(len(units))}
    for df, sfs in _fmu_edges(fmus, connections, deps).items():
        graph[of[df]].update(of[s] for s in sfs if of[s] != of[df])
    try:
        return [units[i] for i in TopologicalSorter(graph).static_order()]
    except CycleError:
        return list(units)
