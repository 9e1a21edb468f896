"""Values exchanged between FMUs inside one unit, and algebraic loops solved by Newton's method.

An :class:`Exchange` sets the inputs of a group of FMUs (their :class:`~uwcosim.master.node.Node`
s) from each other's outputs at one time, with the FMUs' states and their inputs from outside
the group as they are: at a communication point after the FMUs stepped (``"point"``), in
initialization mode (``"init"``), or inside a joint integration of model-exchange FMUs at every
stage of the integrator (``"rhs"``; ``"event"``: in event mode, discrete inputs too).

The FMUs are visited in the order of their feedthrough graph (an input that an output depends
on directly is set before that output is read). FMUs whose feedthrough dependencies form a
cycle (an algebraic loop, :class:`~uwcosim.master.graph.Loop`) are one :class:`LoopStage`: the
unknowns ``u`` are the values of the connections into their feedthrough inputs, solved from the
coupling residual ``r(u) = u - g(y(u))`` (``g`` the connections, with their linear
transformations; ``y(u)`` the outputs read after setting ``u``) by Newton's method with a
backtracking line search. The Jacobian ``I - dg/dy dy/du`` is assembled from each FMU's block
``dy/du``: FMI directional derivatives where the FMU provides them
(:attr:`~uwcosim.fmi.adapter.FMUAdapter.provides_derivatives`), otherwise finite differences,
one input of one FMU at a time (only that FMU is evaluated). Converged when every
``|r_i| <= tolerance * (1 + |u_i|)``; otherwise, after ``max_iterations``, or when the Jacobian
is singular, a one-line :class:`~uwcosim.core.errors.FMUError` names the loop's variables.

Inputs driven from the group whose outputs do not depend on them directly (through states) are
set after every output is known. Inputs from outside the group are not touched: they keep what
the master set at the start of the step (:meth:`Exchange.mark_fresh`: the next call sets every
input once).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.fmi import vartypes
from uwcosim.fmi.binding import Binding
from uwcosim.master.graph import Loop, strongly_connected
from uwcosim.master.node import Node

#: defaults of ``run.loop_tolerance`` and ``run.loop_max_iterations``
LOOP_TOLERANCE = 1e-10
LOOP_MAX_ITERATIONS = 50
MODES = ("point", "init", "rhs", "event")


@dataclass
class _Feed:
    """The inputs of one member driven by one member's outputs: ``view[dst] = f*y[src] + o``."""

    src: int  # the driving member
    dst: np.ndarray  # indices in the driven member's input binding
    idx: np.ndarray  # indices in the driving member's output binding
    factor: np.ndarray
    offset: np.ndarray


class _Member:
    """One FMU of an exchange: its node and the inputs the group drives."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.name = node.adapter.name
        self.early: list[_Feed] = []  # from members visited before (or solved in its stage)
        self.late: list[_Feed] = []  # through states, from members visited at or after it
        self.post: list[_Feed] = []  # direct, inside its loop stage but off the cycle
        self.needed = False  # its outputs drive a member

    def pull(self, feeds: list[_Feed], members: list[_Member]) -> None:
        view = self.node.inputs.view
        for f in feeds:
            view[f.dst] = members[f.src].node.outputs.view[f.idx] * f.factor + f.offset


class LoopStage:
    """An algebraic loop between members: Newton on the coupling residual."""

    def __init__(self, members: list[_Member], index: list[int], unknowns: list[tuple],
                 label: str, tolerance: float, max_iterations: int) -> None:
        self.members = [members[i] for i in index]
        self.index = list(index)
        self.label = label
        self.tolerance, self.max_iterations = tolerance, max_iterations
        # per member: the binding of its unknown inputs and of the outputs that drive them
        self.parts: list[tuple[_Member, Binding, Binding, slice, slice, list[int]]] = []
        per_in: dict[int, list[tuple]] = {}
        for u in unknowns:  # (dst member, input index, src member, output index, f, o)
            per_in.setdefault(u[0], []).append(u)
        out_names: dict[int, list[str]] = {}
        for u in unknowns:
            names = out_names.setdefault(u[2], [])
            name = members[u[2]].node.outputs.names[u[3]]
            if name not in names:
                names.append(name)
        self.names: list[str] = []
        src_pos, u_pos = [], 0
        y_base: dict[int, int] = {}
        y_pos = 0
        for i in index:
            m = members[i]
            ad = m.node.adapter
            ins = per_in.get(i, [])
            outs = out_names.get(i, [])
            b_in = ad.bind([m.node.inputs.names[u[1]] for u in ins])
            b_out = ad.bind(outs)
            y_base[i] = y_pos
            self.parts.append((m, b_in, b_out, slice(u_pos, u_pos + len(ins)),
                               slice(y_pos, y_pos + len(outs)), [u[1] for u in ins]))
            self.names += [f"{m.name}.{m.node.inputs.names[u[1]]}" for u in ins]
            u_pos += len(ins)
            y_pos += len(outs)
        # u is ordered by member, then as listed: the source of each unknown in y
        ordered = [u for i in index for u in per_in.get(i, [])]
        for u in ordered:
            src_pos.append(y_base[u[2]] + out_names[u[2]].index(
                members[u[2]].node.outputs.names[u[3]]))
        self.src = np.array(src_pos, dtype=np.intp)
        self.factor = np.array([u[4] for u in ordered])
        self.offset = np.array([u[5] for u in ordered])
        self.n, self.ny = u_pos, y_pos
        self.iterations = 0  # Newton iterations of the last solve
        self.evaluations = 0  # residual evaluations so far
        self._last_dy: np.ndarray | None = None  # dy/du of the last Jacobian (for messages)

    # -- the residual -------------------------------------------------------------------------
    def _set(self, u: np.ndarray, t: float) -> None:
        for m, b_in, _, su, _, _ in self.parts:
            if b_in.n:
                b_in.view[:] = u[su]
                m.node.adapter.set_continuous(b_in, t)

    def _outputs(self, t: float) -> np.ndarray:
        y = np.empty(self.ny)
        for m, _, b_out, _, sy, _ in self.parts:
            if b_out.n:
                y[sy] = m.node.adapter.get_outputs(b_out, t)
        return y

    def residual(self, u: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(r(u), y(u))`` with ``u`` set in the FMUs."""
        self.evaluations += 1
        self._set(u, t)
        y = self._outputs(t)
        return u - (self.factor * y[self.src] + self.offset), y

    def jacobian(self, u: np.ndarray, y: np.ndarray, t: float) -> np.ndarray:
        """``dr/du = I - diag(factor) dy/du[src]`` (``u`` set in the FMUs, ``y = y(u)``)."""
        dy = np.zeros((self.ny, self.n))
        for m, b_in, b_out, su, sy, _ in self.parts:
            if not b_in.n or not b_out.n:
                continue
            ad = m.node.adapter
            if ad.provides_derivatives:
                dy[sy, su] = ad.output_derivatives(b_out, b_in, t)
                continue
            base = b_in.view.copy()
            for j in range(b_in.n):
                step = 1.4901161193847656e-08 * max(1.0, abs(base[j]))  # sqrt(eps)
                b_in.view[:] = base
                b_in.view[j] = base[j] + step
                ad.set_continuous(b_in, t)
                dy[sy, su.start + j] = (ad.get_outputs(b_out, t) - y[sy]) / step
            b_in.view[:] = base
            ad.set_continuous(b_in, t)
        self._last_dy = dy
        return np.eye(self.n) - self.factor[:, None] * dy[self.src, :]

    # -- Newton -------------------------------------------------------------------------------
    def _converged(self, r: np.ndarray, u: np.ndarray) -> bool:
        return bool(np.all(np.abs(r) <= self.tolerance * (1.0 + np.abs(u))))

    def solve(self, u: np.ndarray, t: float) -> np.ndarray:
        """The root of the residual from the guess ``u`` (left set in the FMUs)."""
        r, y = self.residual(u, t)
        norm = float(np.linalg.norm(r))
        for it in range(self.max_iterations + 1):
            if not np.all(np.isfinite(r)):
                raise FMUError(f"algebraic loop {self.label}: non-finite residual at t={t:g}")
            if self._converged(r, u):
                self.iterations = it
                return u
            if it == self.max_iterations:
                break
            jac = self.jacobian(u, y, t)
            try:
                du = np.linalg.solve(jac, -r)
            except np.linalg.LinAlgError:
                raise FMUError(f"algebraic loop {self.label}: singular Jacobian at "
                               f"t={t:g}{self._hint()}") from None
            lam = 1.0
            while True:  # backtracking: accept a sufficient decrease of |r|
                u_new = u + lam * du
                r_new, y_new = self.residual(u_new, t)
                norm_new = float(np.linalg.norm(r_new))
                if norm_new <= (1.0 - 1e-4 * lam) * norm or lam < 1e-3:
                    break
                lam *= 0.5
            u, r, y, norm = u_new, r_new, y_new, norm_new
        worst = int(np.argmax(np.abs(r) / (1.0 + np.abs(u))))
        raise FMUError(f"algebraic loop {self.label} did not converge at t={t:g} in "
                       f"{self.max_iterations} iterations (residual {abs(r[worst]):.3g} at "
                       f"{self.names[worst]}; run.loop_tolerance = {self.tolerance:g}, "
                       f"run.loop_max_iterations = {self.max_iterations})")

    def _hint(self) -> str:
        dy = self._last_dy
        for m, b_in, b_out, su, sy, _ in self.parts:
            if (dy is not None and b_in.n and b_out.n and m.node.adapter.interface == "cs"
                    and not np.any(dy[sy, su])):
                return (f" (co-simulation FMU '{m.name}' did not change its outputs when its "
                        f"inputs were set after doStep: it may compute them in doStep only)")
        return ""

    def guess(self) -> np.ndarray:
        """The unknowns as they are in the members' input bindings."""
        u = np.empty(self.n)
        for m, _, _, su, _, idx in self.parts:
            u[su] = m.node.inputs.view[idx]
        return u

    def keep(self, u: np.ndarray) -> None:
        """Write the solution into the members' input bindings."""
        for m, _, _, su, _, idx in self.parts:
            m.node.inputs.view[idx] = u[su]


class Exchange:
    """The values exchanged between ``nodes`` (see the module docstring)."""

    def __init__(self, nodes: list[Node], loops: list[Loop] = (), *,
                 tolerance: float = LOOP_TOLERANCE,
                 max_iterations: int = LOOP_MAX_ITERATIONS) -> None:
        self.members = [_Member(n) for n in nodes]
        members = self.members
        owner: dict[int, tuple[int, int]] = {}
        for i, m in enumerate(members):
            for k, slot in enumerate(m.node.out_slots):
                owner[int(slot)] = (i, k)
        # the connections inside the group: (dst, input index, src, output index, f, o)
        links: list[tuple] = []
        for i, m in enumerate(members):
            node = m.node
            for j, slot in enumerate(node.in_slots):
                src = owner.get(int(slot))
                if src is None:
                    continue
                f, o = (1.0, 0.0) if node.in_affine is None else (
                    float(node.in_affine[0][j]), float(node.in_affine[1][j]))
                links.append((i, j, src[0], src[1], f, o))
                members[src[0]].needed = True
        feeds = {i: {n for ins in m.node.adapter.feedthrough().values() for n in ins}
                 for i, m in enumerate(members)}

        def direct(link: tuple) -> bool:
            return members[link[0]].node.inputs.names[link[1]] in feeds[link[0]]

        succ: dict[int, list[int]] = {i: [] for i in range(len(members))}
        for link in links:
            if direct(link) and link[0] not in succ[link[2]]:
                succ[link[2]].append(link[0])
        comps = strongly_connected(succ)
        comp_of = {i: c for c, comp in enumerate(comps) for i in comp}
        preds: dict[int, set[int]] = {c: set() for c in range(len(comps))}
        for src, dsts in succ.items():
            for dst in dsts:
                if comp_of[src] != comp_of[dst]:
                    preds[comp_of[dst]].add(comp_of[src])
        # the components in topological order, ties in the members' order
        order: list[int] = []
        done: set[int] = set()
        while len(order) < len(comps):
            ready = [c for c in range(len(comps)) if c not in done and preds[c] <= done]
            c = min(ready, key=lambda c: min(comps[c]))
            order.append(c)
            done.add(c)
        stage_of: dict[int, int] = {}
        solved: set[tuple[int, int]] = set()  # (member, input index) a loop stage solves for
        post: set[tuple[int, int]] = set()  # direct inputs inside a loop stage, off its cycle
        #: the stages: a member index (set its inputs, read its outputs) or a LoopStage
        self.stages: list[int | LoopStage] = []
        for s, c in enumerate(order):
            comp = sorted(comps[c])
            for i in comp:
                stage_of[i] = s
            inner = [lk for lk in links if comp_of[lk[0]] == c and comp_of[lk[2]] == c
                     and direct(lk)]
            if len(comp) == 1 and not inner:
                self.stages.append(comp[0])
                continue
            names = {m.name for m in (members[i] for i in comp)}

            def on_cycle(lk: tuple) -> bool:  # both ends in one strongly connected variable set
                src = f"{members[lk[2]].name}.{members[lk[2]].node.outputs.names[lk[3]]}"
                dst = f"{members[lk[0]].name}.{members[lk[0]].node.inputs.names[lk[1]]}"
                return any(src in lp.variables and dst in lp.variables for lp in loops)

            # the unknowns: the connections on a cycle; the other direct ones inside the
            # stage (one way: no cycle) are passed on once the loop is solved
            post |= {(lk[0], lk[1]) for lk in inner if not on_cycle(lk)}
            inner = [lk for lk in inner if on_cycle(lk)]
            for lk in inner:
                node = members[lk[0]].node
                var = node.adapter.variables[node.inputs.names[lk[1]]]
                where = f"{members[lk[0]].name}.{node.inputs.names[lk[1]]}"
                if node.inputs.kinds[lk[1]] != "float" or (
                        node.adapter.interface == "me" and not vartypes.is_continuous_input(var)):
                    raise ScenarioError(f"algebraic loop through {where} ({var.type}, "
                                        f"variability {var.variability}): only continuous Real "
                                        f"inputs can be solved for")
            label = next((lp.message() for lp in loops if set(lp.fmus) <= names), None) or \
                ", ".join(f"{members[lk[2]].name}.{members[lk[2]].node.outputs.names[lk[3]]}"
                          f" -> {members[lk[0]].name}.{members[lk[0]].node.inputs.names[lk[1]]}"
                          for lk in inner)
            self.stages.append(LoopStage(members, comp, inner, label, tolerance,
                                         max_iterations))
            solved.update((lk[0], lk[1]) for lk in inner)
        for i, m in enumerate(members):
            for src in sorted({lk[2] for lk in links if lk[0] == i}):
                mine = [lk for lk in links if lk[0] == i and lk[2] == src]
                early = [lk for lk in mine if stage_of[src] < stage_of[i] or (i, lk[1]) in solved]
                after = [lk for lk in mine if (i, lk[1]) in post]
                late = [lk for lk in mine if lk not in early and lk not in after]
                for group, target in ((early, m.early), (after, m.post), (late, m.late)):
                    if group:
                        target.append(_Feed(src, np.array([lk[1] for lk in group], np.intp),
                                            np.array([lk[3] for lk in group], np.intp),
                                            np.array([lk[4] for lk in group]),
                                            np.array([lk[5] for lk in group])))
        self._late = [m for m in members if m.late]
        self._fresh = True
        # does anything come from outside the group (an input not driven by a member, a table
        # control at the integrator's stages)? If not, a new step changes no input
        driven = {(lk[0], lk[1]) for lk in links}
        # (a String input counts as from outside: its text travels on the bus, not here)
        self._from_outside = [i for i, m in enumerate(members) if m.node.input_fn is not None
                              or m.node.str_inputs
                              or any((i, j) not in driven for j in range(m.node.inputs.n))]
        self._outside = bool(self._from_outside)
        self._plain = self._compile() if not self.loops else None

    def _compile(self) -> list[tuple]:
        """The right-hand-side pass without loops as a flat list of operations: ``(pulls,
        set, get)`` per visit, a pull ``(dst view, dst index, src view, src index, f, o)``."""
        ops = []

        def pulls(m: _Member, feeds: list[_Feed]) -> list[tuple]:
            out = []
            for f in feeds:
                src = self.members[f.src].node.outputs.view
                out += [(m.node.inputs.view, int(d), src, int(i), float(a), float(b))
                        for d, i, a, b in zip(f.dst, f.idx, f.factor, f.offset)]
            return out

        for st in self.stages:
            m = self.members[st]
            node = m.node
            setter = node.adapter.set_continuous if (m.early or node.input_fn) else None
            getter = node.adapter.get_outputs if m.needed else None
            ops.append((pulls(m, m.early), node, setter, getter))
        for m in self._late:
            ops.append((pulls(m, m.late), m.node, m.node.adapter.set_continuous, None))
        return ops

    @property
    def loops(self) -> list[LoopStage]:
        return [s for s in self.stages if isinstance(s, LoopStage)]

    def order(self) -> list[int]:
        """The members (indices) in the order the stages visit them."""
        return [i for st in self.stages
                for i in (st.index if isinstance(st, LoopStage) else [st])]

    def unknowns(self) -> set[tuple[str, str]]:
        """``(fmu, input)`` of every input a loop stage solves for."""
        return {(m.name, m.node.inputs.names[j]) for st in self.loops
                for m, _, _, _, _, idx in st.parts for j in idx}

    def run_flag(self, t: float, event: bool) -> bool:
        """:meth:`run` as a joint integrator calls it (``event``: in event mode)."""
        return self.run(t, "event" if event else "rhs")

    def fresh_members(self) -> list[int]:
        """The members whose outputs binding :meth:`run` leaves read at its time (those that
        drive a member, those of a loop): their outputs need no other get at that time."""
        return [i for i, m in enumerate(self.members)
                if m.needed or any(m in st.members for st in self.loops)]

    def outside_members(self) -> list[int]:
        """The members with an input from outside the group (or a table at stage times)."""
        return list(self._from_outside)

    def mark_fresh(self) -> None:
        """The next :meth:`run` sets every input of every member once (a new step: the inputs
        from outside were gathered again)."""
        self._fresh = True

    def _set(self, m: _Member, t: float, mode: str) -> bool:
        node = m.node
        if mode == "rhs" and node.input_fn is not None:
            node.input_fn(t, node.inputs.view)
        if mode in ("init", "event"):
            return node.adapter.set_inputs_now(node.inputs, t)
        node.adapter.set_continuous(node.inputs, t)
        return False

    def run(self, t: float, mode: str) -> bool:
        """Set the members' inputs from each other's outputs at ``t``; True if a discrete
        input changed (``mode = "event"``)."""
        if self._fresh and mode == "rhs" and not self._outside:
            self._fresh = False  # a new step, nothing from outside: all set as it was
            return False
        if self._plain is not None and mode == "rhs" and not self._fresh:
            for pulls, node, setter, getter in self._plain:
                for dst, d, src, i, f, o in pulls:
                    dst[d] = src[i] * f + o
                if node.input_fn is not None:
                    node.input_fn(t, node.inputs.view)
                if setter is not None:
                    setter(node.inputs, t)
                if getter is not None:
                    getter(node.outputs, t)
            return False
        members, fresh = self.members, self._fresh or mode != "rhs"
        self._fresh = False
        changed = False
        for st in self.stages:
            if isinstance(st, LoopStage):
                # in initialization, the guess is the inputs' start values (in the bindings)
                u0 = st.guess() if mode == "init" else None
                for m, *_ in st.parts:
                    m.pull(m.early, members)
                    changed = self._set(m, t, mode) or changed
                u = st.solve(st.guess() if u0 is None else u0, t) if st.n else u0
                if st.n:
                    st.keep(u)
                for m, *_ in st.parts:
                    m.node.adapter.get_outputs(m.node.outputs, t)
                after = [m for m, *_ in st.parts if m.post]
                for _ in after:  # one-way links between them: as many passes as members
                    for m in after:
                        m.pull(m.post, members)
                        changed = self._set(m, t, mode) or changed
                        m.node.adapter.get_outputs(m.node.outputs, t)
                continue
            m = members[st]
            if m.early or fresh or m.node.input_fn is not None:
                m.pull(m.early, members)
                changed = self._set(m, t, mode) or changed
            if m.needed:
                m.node.adapter.get_outputs(m.node.outputs, t)
        for m in self._late:
            m.pull(m.late, members)
            changed = self._set(m, t, mode) or changed
        return changed
