"""The master algorithms by name, and the units of FMUs they step.

``run.algorithm`` (:attr:`uwcosim.master.system.System.algorithm`):

- ``"gauss-seidel"`` (default): the units are stepped one after the other in the order of the
  feedthrough graph (:func:`uwcosim.master.graph.unit_order`); each gathers its inputs from the
  bus when its turn comes, so an FMU whose output depends directly on an input gets the
  upstream output of the *new* communication point ``t_{k+1}``; an input without direct
  feedthrough gets whatever its driver holds at that moment, ``t_{k+1}`` if the driver came
  before it, ``t_k`` otherwise: then the result depends on the order of the FMUs in the file
  (documented in the README, ``tests/test_algorithms.py``).
- ``"jacobi"``: every unit gathers its inputs from the bus at ``t_k`` before any steps (as
  OMSimulator's and libcosim's fixed-step algorithms do), so the result does not depend on the
  order; the outputs at ``t_{k+1}`` are read once all have stepped. In initialization, a
  connected input its FMU's outputs do not depend on directly keeps the FMU's start value
  (there is no previous point), so initialization does not depend on the order either.

In both, an input from a source (table, noise) set at ``t_k`` is held over the step: the log row
of ``t_{k+1}`` shows its effect (as ``fmpy.simulate_fmu``). A unit (:class:`Unit`) is one FMU, or
FMUs handled together (:func:`plan_units`): the FMUs of an algebraic loop (solved at every
communication point after they stepped and in initialization mode, by an
:class:`~uwcosim.master.loops.Exchange`), and model-exchange FMUs connected to each other
(:class:`CoupledSystem`: one integrator over all their states,
:class:`~uwcosim.fmi.coupled.CoupledModelExchange`), merged when they overlap.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi import vartypes
from uwcosim.fmi.coupled import CoupledModelExchange
from uwcosim.master.graph import Loop, algebraic_loops, merge_groups, stepping_order, unit_order
from uwcosim.master.loops import Exchange
from uwcosim.master.node import Node
from uwcosim.master.system import FMU, System

ALGORITHMS = ("gauss-seidel", "jacobi")
#: a loop inside a joint integration is solved to ``min(loop_tolerance, this * rtol)``
RHS_TOLERANCE_FACTOR = 1e-3


@dataclass
class CoupledSystem:
    """Model-exchange FMUs integrated as one system."""

    nodes: list[Node]
    #: what they exchange at every stage of the integrator (and their loops)
    exchange: Exchange
    #: the joint integrator of the current run (made by :meth:`start`)
    integrator: CoupledModelExchange | None = None

    @functools.cached_property
    def fresh(self) -> set[int]:
        """``id`` of the members whose outputs the last exchange of a step read at its end."""
        return {id(self.nodes[i]) for i in self.exchange.fresh_members()}

    @functools.cached_property
    def gathered(self) -> list[Node]:
        """The members with an input from outside the system (gathered from the bus at each
        step; the others' inputs are all set by the exchange)."""
        return [self.nodes[i] for i in self.exchange.outside_members()]

    @property
    def names(self) -> list[str]:
        return [n.adapter.name for n in self.nodes]

    @functools.cached_property
    def call(self) -> str:
        """The FMU call in progress while it steps (for the run-wide watchdog)."""
        return f"doStep (integrated with {', '.join(self.names[1:])})"

    def start(self, t0: float, t_stop: float) -> None:
        """A new joint integrator over the members' integrators (after their initialization)."""
        ads = [n.adapter for n in self.nodes]
        self.integrator = CoupledModelExchange(
            self.names, [a.model_exchange for a in ads], [n.inputs for n in self.nodes],
            self.exchange.run_flag, t0, t_stop, solvers=[a.solver for a in ads],
            substeps=[a.substeps for a in ads], rtols=[a.rtol for a in ads])


@dataclass
class Unit:
    """FMUs stepped together (one FMU, in most systems)."""

    nodes: list[Node]
    period: int
    #: the loops solved at communication points (None: no algebraic loop outside a coupled
    #: system, nothing to solve after the step)
    exchange: Exchange | None = None
    #: the loops solved in initialization mode (None: no algebraic loop)
    init_exchange: Exchange | None = None
    coupled: list[CoupledSystem] = field(default_factory=list)
    #: the members stepped on their own
    single: list[Node] = field(default_factory=list)

    @functools.cached_property
    def gathered(self) -> list[Node]:
        """The members whose inputs are gathered from the bus at each step (all but those of a
        coupled system whose every input comes from inside it: its exchange sets them)."""
        inside = {id(n) for s in self.coupled for n in s.nodes}
        keep = {id(n) for s in self.coupled for n in s.gathered}
        return [n for n in self.nodes if id(n) not in inside or id(n) in keep]


def coupled_groups(me_fmus: list[str], connections: list[tuple[str, str]],
                   periods: dict[str, int]) -> list[list[str]]:
    """The model-exchange FMUs (in-process) connected to each other with the same period:
    connected components of two or more, in the system's order."""
    me = set(me_fmus)
    groups = [{f} for f in me_fmus]
    for src, dst in connections:
        a, b = src.split(".", 1)[0], dst.split(".", 1)[0]
        if a != b and a in me and b in me and periods[a] == periods[b]:
            ga = next(g for g in groups if a in g)
            gb = next(g for g in groups if b in g)
            if ga is not gb:
                ga |= gb
                groups.remove(gb)
    return [[f for f in me_fmus if f in g] for g in groups if len(g) > 1]


def plan(system: System, adapters: dict, in_process: set[str],
         connections: list[tuple[str, str]]
         ) -> tuple[list[list[str]], list[Loop], list[list[str]]]:
    """The units of a system in stepping order, its algebraic loops and its coupled ME systems
    (``adapters``: the FMUs by name; ``in_process``: those not in a worker process;
    ``connections``: ``(output, input)`` variable signals, array elements by their array).
    :class:`~uwcosim.core.errors.AlgebraicLoopError` for a loop with ``algebraic_loops =
    "error"``, :class:`~uwcosim.core.errors.ScenarioError` for a loop that cannot be solved."""
    conns = list(connections)
    deps = {n: a.feedthrough() for n, a in adapters.items()}
    names = list(adapters)
    periods = {n: f.period for n, f in system.fmus.items()}
    # FMUs with array variables keep their own solver: the joint integrator and the loop
    # solver exchange scalar values only
    me = [n for n, a in adapters.items() if a.interface == "me" and n in in_process
          and not _has_arrays(a)]
    coupled = coupled_groups(me, conns, periods)
    if system.algebraic_loops == "error":
        return [[f] for f in stepping_order(names, conns, deps)], [], coupled
    loops = algebraic_loops(names, conns, deps)
    check_loops(loops, periods, in_process, adapters)
    return plan_units(names, conns, deps, loops, coupled), loops, coupled


def _has_arrays(adapter) -> bool:
    """Whether the FMU has an array input or output (FMI 3)."""
    return any(vartypes.is_array(v) for v in adapter.variables.values()
               if v.causality in ("input", "output"))


def jacobi_keeps(nodes: list[Node], drivers: dict[str, str], outputs: dict) -> dict[str, set]:
    """Jacobi's initialization: per FMU, the inputs that keep their start value (driven by an
    FMU output, not a direct feedthrough of their FMU: there is no previous point)."""
    keep: dict[str, set[int]] = {}
    for node in nodes:
        ad = node.adapter
        direct = {i for ins in ad.feedthrough().values() for i in ins}
        for j, name in zip(node.inputs.offsets, node.inputs.names):
            if drivers.get(f"{ad.name}.{name}") in outputs and name not in direct:
                keep.setdefault(ad.name, set()).add(j)
    return keep


def start_value(node: Node, fmu: FMU, j: int) -> float:
    """The start value of the input at binding position ``j`` of ``node``: the system's
    (``fmu.start``), else the FMU's declared one, else what its binding holds."""
    name = node.inputs.names[node.inputs.offsets.index(j)]
    value = fmu.start.get(name)
    if value is None:
        start = getattr(node.adapter.variables[name], "start", None)
        try:
            value = float(start) if start is not None else node.inputs.view[j]
        except (TypeError, ValueError):  # "true"/"false", an enumeration name
            value = node.inputs.view[j]
    return float(value) if not isinstance(value, str) else float(node.inputs.view[j])


def check_loops(loops: list[Loop], periods: dict[str, int], in_process: set[str],
                adapters: dict) -> None:
    """A loop the master cannot solve: through an input that is not a continuous Real, between
    FMUs of different periods, through an FMU in a worker process."""
    for lp in loops:
        for signal in lp.variables:
            fmu, var = signal.split(".", 1)
            ad = adapters[fmu]
            v = ad.variables[var]
            if v.causality == "input" and not (vartypes.kind(v) == "float" and (
                    ad.interface == "cs" or vartypes.is_continuous_input(v))):
                raise ScenarioError(f"algebraic loop {lp.message()}: {signal!r} is a {v.type} "
                                    f"input of variability {v.variability}; only continuous "
                                    f"Real inputs can be solved for (or break the loop)")
        per = {periods[f] for f in lp.fmus}
        if len(per) > 1:
            raise ScenarioError(f"algebraic loop {lp.message()}: its FMUs have different "
                                f"periods ({', '.join(f'{f}: {periods[f]}' for f in lp.fmus)});"
                                f" give them the same one")
        arrays = [f for f in lp.fmus if _has_arrays(adapters[f])]
        if arrays:
            raise ScenarioError(f"algebraic loop {lp.message()}: FMU '{arrays[0]}' has array "
                                f"inputs or outputs; loops are solved between FMUs of scalar "
                                f"variables only (or break the loop)")
        away = [f for f in lp.fmus if f not in in_process]
        if away:
            raise ScenarioError(f"algebraic loop {lp.message()}: FMU '{away[0]}' runs in a "
                                f"worker process (timeout_s), which cannot take part in an "
                                f"algebraic loop")


def plan_units(fmus: list[str], connections: list[tuple[str, str]],
               deps: dict[str, dict[str, set[str]]], loops: list[Loop],
               coupled: list[list[str]]) -> list[list[str]]:
    """The units in stepping order: FMUs of a loop or of a coupled system merged."""
    units = merge_groups(fmus, [set(lp.fmus) for lp in loops] + [set(g) for g in coupled])
    return unit_order(fmus, connections, deps, units)


def build_unit(names: list[str], nodes: dict[str, Node], loops: list[Loop],
               coupled: list[list[str]], tolerance: float, max_iterations: int) -> Unit:
    """The :class:`Unit` of the FMUs ``names`` (their loops and coupled systems)."""
    members = set(names)
    mine = [lp for lp in loops if set(lp.fmus) <= members]
    systems = []
    for group in coupled:
        if set(group) <= members:
            inner = [lp for lp in mine if set(lp.fmus) <= set(group)]
            gnodes = [nodes[f] for f in group]
            # a loop solved at every stage of the integrator: well inside its tolerance, or
            # the right-hand side is not smooth enough for CVode's error test
            tol = min(tolerance, RHS_TOLERANCE_FACTOR * min(n.adapter.rtol for n in gnodes))
            systems.append(CoupledSystem(gnodes, Exchange(gnodes, inner, tolerance=tol,
                                                          max_iterations=max_iterations)))
    in_system = {n.adapter.name for s in systems for n in s.nodes}
    order = [nodes[f] for f in names]
    unit = Unit(order, order[0].period, coupled=systems,
                single=[n for n in order if n.adapter.name not in in_system])
    if mine:
        unit.init_exchange = Exchange(order, mine, tolerance=tolerance,
                                      max_iterations=max_iterations)
        # initialization in the order of the feedthrough graph inside the unit
        unit.nodes = [unit.init_exchange.members[i].node for i in unit.init_exchange.order()]
        outside = [lp for lp in mine
                   if not any(set(lp.fmus) <= set(s.names) for s in systems)]
        if outside:
            unit.exchange = unit.init_exchange
    elif len(order) > 1:
        probe = Exchange(order)  # the order of the feedthrough graph, for initialization
        unit.nodes = [probe.members[i].node for i in probe.order()]
    return unit
