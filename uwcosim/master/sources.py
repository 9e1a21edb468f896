"""Signal sources owned by the master: control inputs, noise, and measurement-loss models.

- controls: :class:`TableControl` (a table, sampled on the grid; for model exchange also at the
  integrator's stage times, :class:`StageInputs`) and :class:`WaypointHeading` (closed loop on
  the true position); :func:`control_problem` says whether a control can drive an input;
- the seeded samples: :func:`sample_sources` (controls and process noise, a
  :class:`ChunkedTable`), the drawers of the noise (:func:`noise_drawer`), of the sensors'
  noise (:func:`gaussian_drawer`) and of the measurement losses (:func:`loss_drawer`), which
  :class:`~uwcosim.master.measurement.SensorBank` uses;
- :func:`noise_free_sources`: the noise sources a third-party vehicle has no inputs for.

All randomness comes from :func:`~uwcosim.core.rng.stream`, one independent
``numpy.random.Generator`` per named purpose derived from the run seed, so adding a sensor does
not change another sensor's noise, and the same scenario and seed always give the same samples.

Samples are drawn in chunks of :data:`CHUNK_STEPS` steps as the run goes (:class:`ChunkedTable`),
so memory does not depend on the run's duration. Each stream is drawn in the same order as one
draw for the whole run would be (``standard_normal`` and ``random`` fill their output in order;
the Gilbert-Elliott switch draws, which followed all ``n`` loss draws, come from a copy of the
stream advanced by ``n``), so a run's samples do not depend on the chunk size.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from uwcosim.core.rng import stream
from uwcosim.fmi import vartypes
from uwcosim.fmi.varmap import ROLES
from uwcosim.master.system import BernoulliLoss, Control, GilbertElliottLoss, System

if TYPE_CHECKING:
    from fmpy.model_description import ModelVariable


class TableControl:
    """A piecewise-linear (or held) table ``[[t, value], ...]``, constant beyond its ends.

    A time given twice is a step: the value is continuous from the right there (from that
    time on, the second row's value; as fmpy applies inputs at a communication point, after
    the event). The master does not cut a step at a jump: put jump times on the
    communication grid (an ME FMU's integrator, which evaluates the table at its stages,
    otherwise sees the jump inside a step)."""

    def __init__(self, spec: Control) -> None:
        table = np.asarray(spec.table, dtype=float)
        self.t, self.v = table[:, 0], table[:, 1]
        self.hold = spec.interpolation == "hold"
        self.steps = bool(np.any(np.diff(self.t) == 0))  # repeated times: jumps

    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        if self.hold:
            i = np.searchsorted(self.t, t, side="right") - 1
            return self.v[np.clip(i, 0, len(self.v) - 1)]
        if not self.steps:
            return np.interp(t, self.t, self.v)
        # right-continuous: the segment [t_j, t_{j+1}) with t_j <= t < t_{j+1}; at a repeated
        # time t_j is its second row, so a jump takes effect at its time
        tt = np.asarray(t, dtype=float)
        j = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, len(self.t) - 2)
        t0, t1, v0, v1 = self.t[j], self.t[j + 1], self.v[j], self.v[j + 1]
        with np.errstate(divide="ignore", invalid="ignore"):  # clipped ends: replaced below
            w = np.clip((tt - t0) / (t1 - t0), 0.0, 1.0)
        out = np.where(tt >= self.t[-1], self.v[-1], v0 + w * (v1 - v0))
        out = np.where(tt < self.t[0], self.v[0], out)
        return out if out.ndim else float(out)

    def samples(self, times: np.ndarray) -> np.ndarray:
        return np.asarray(self.value(times), dtype=float)


class WaypointHeading:
    """Heading towards the active waypoint (closed loop on the true position).

    The heading is ``atan2(dy, dx)`` in the frame of eq. (54) (psi from the x axis), unwrapped
    so it stays continuous; a waypoint is passed when the vehicle comes within
    ``acceptance_radius``. After the last one the heading is held.
    """

    def __init__(self, spec: Control) -> None:
        self.points = np.asarray(spec.waypoints, dtype=float)
        self.position = spec.position
        self.radius = spec.acceptance_radius
        self.reset()

    def reset(self) -> None:
        self.active = 0
        self.last = None

    def value_at(self, x: float, y: float) -> float:
        while self.active < len(self.points):
            dx, dy = self.points[self.active] - (x, y)
            if np.hypot(dx, dy) > self.radius:
                break
            self.active += 1
        if self.active >= len(self.points):
            return self.last if self.last is not None else 0.0
        psi = float(np.arctan2(dy, dx))
        if self.last is not None:  # unwrap
            psi = self.last + (psi - self.last + np.pi) % (2 * np.pi) - np.pi
        self.last = psi
        return psi

    def value(self, t: float) -> float:
        return self.last if self.last is not None else 0.0


#: steps of samples held in memory per source table
CHUNK_STEPS = 65_536

#: ``draw(k0, m)``: samples of steps ``k0 .. k0+m-1`` as ``[m, width]``; called for consecutive
#: chunks from ``k0 = 0``
Drawer = Callable[[int, int], np.ndarray]


class ChunkedTable:
    """Rows ``0 .. n-1`` of sampled sources, generated one chunk at a time.

    ``makers``: functions returning a fresh drawer (from the start of its stream). Rows are
    read in increasing order (a jump back restarts the streams and draws up to that row)."""

    def __init__(self, n: int, makers: list[Callable[[], Drawer]], width: int,
                 dtype: type | np.dtype = float, chunk: int | None = None) -> None:
        self.n, self.makers, self.width, self.dtype = int(n), makers, width, dtype
        self.chunk = int(CHUNK_STEPS if chunk is None else chunk)
        self._restart()

    def _restart(self) -> None:
        self._drawers = [m() for m in self.makers]
        self.k0 = 0
        self.rows = np.zeros((0, self.width), dtype=self.dtype)

    def _next(self) -> None:
        k0 = self.k0 + len(self.rows)
        m = min(self.chunk, self.n - k0)
        if m <= 0:
            raise IndexError(f"step {k0} is beyond the run's {self.n} samples")
        cols = [np.asarray(d(k0, m), dtype=self.dtype).reshape(m, -1) for d in self._drawers]
        self.rows = np.hstack(cols) if cols else np.zeros((m, 0), dtype=self.dtype)
        self.k0 = k0

    def row(self, k: int) -> np.ndarray:
        """Row ``k`` (a view: copy it to keep it)."""
        if k < self.k0:
            self._restart()
        while k >= self.k0 + len(self.rows):
            self._next()
        return self.rows[k - self.k0]


def noise_drawer(rng: np.random.Generator, psd: ArrayLike, h: float) -> Drawer:
    """Held white noise of power spectral density ``psd``: samples of variance ``psd / h``
    (the PSD held over the step ``h``), one column per component."""
    scale = np.sqrt(np.asarray(psd, dtype=float) / h)
    return lambda k0, m: rng.standard_normal((m, scale.size)) * scale


def gaussian_drawer(rng: np.random.Generator, sigma: ArrayLike) -> Drawer:
    """Gaussian samples of standard deviations ``sigma``, one column per component."""
    sigma = np.asarray(sigma, dtype=float)
    return lambda k0, m: rng.standard_normal((m, sigma.size)) * sigma


def loss_drawer(rng: np.random.Generator, n: int,
                spec: BernoulliLoss | GilbertElliottLoss | None) -> Drawer:
    """``True`` where the measurement is received, for the ``n`` samples of a run, in chunks
    drawn as the run goes (no loss model: every sample is received).

    Bernoulli: lost with probability ``p`` (seed 001 eq. 2). Gilbert-Elliott: a two-state
    Markov chain (good/bad) with transition probabilities ``p_good_to_bad``,
    ``p_bad_to_good`` and loss probabilities ``loss_good``, ``loss_bad`` per state (bursts).
    """
    if spec is None:
        return lambda k0, m: np.ones(m, dtype=bool)
    if isinstance(spec, BernoulliLoss):
        return lambda k0, m: rng.random(m) >= spec.p
    bits = type(rng.bit_generator)()
    bits.state = rng.bit_generator.state
    bits.advance(n)  # the switch draws followed the n loss draws
    switch_rng = np.random.Generator(bits)
    state = [False]

    def draw(k0: int, m: int) -> np.ndarray:
        u = rng.random(m)
        switch = switch_rng.random(m)
        bad = np.empty(m, dtype=bool)
        st = state[0]
        for i in range(m):
            bad[i] = st
            if st:
                st = switch[i] >= spec.p_bad_to_good
            else:
                st = switch[i] < spec.p_good_to_bad
        state[0] = st
        return u >= np.where(bad, spec.loss_bad, spec.loss_good)

    return draw


def control_problem(c: Control, var: ModelVariable) -> str | None:
    """Why control ``c`` cannot drive the FMU input ``var`` (None: it can). A control drives a
    Real input, or an Integer/Boolean one with a held table of whole (Boolean: 0/1) values."""
    kind = vartypes.kind(var)
    if kind == "float":
        return None
    if kind not in ("int", "bool"):
        return f"is of type {var.type}; controls drive numeric inputs only"
    if c.table is not None and c.interpolation == "hold":
        values = [v for _, v in c.table]
        if kind == "bool" and all(v in (0, 1) for v in values):
            return None
        if kind == "int" and all(float(v).is_integer() for v in values):
            return None
    need = "0/1" if kind == "bool" else "whole-number"
    return (f"is of type {var.type}: a control drives it only with a table of {need} values "
            f"and interpolation = \"hold\"")


class StageInputs:
    """Refreshes an ME FMU's table-control inputs at the integrator's stage times (picklable,
    so that an FMU in a worker process can take it along)."""

    def __init__(self, pairs: list[tuple[int, TableControl]]) -> None:
        self.pairs = pairs

    def __call__(self, t: float, view: np.ndarray) -> None:
        for j, ctl in self.pairs:
            view[j] = ctl.value(t)


def sample_sources(system: System, controls: dict, slots: dict[str, int], seed: int, n: int,
                   skip: Collection[str] = ()
                   ) -> tuple[ChunkedTable, np.ndarray, list[tuple[int, WaypointHeading]]]:
    """The open-loop controls and noise of ``system`` on the ``n`` grid points, drawn in chunks
    from the seed's streams (the sensors' noise: :mod:`uwcosim.master.measurement`):
    ``(ChunkedTable [n, m], bus slots [m], [(slot, closed-loop control)])``.
    Noise sources named in ``skip`` are left out (a truth FMU without their inputs)."""
    t0, h = system.start_time, system.step
    makers, where = [], []
    for cname, ctl in controls.items():
        if isinstance(ctl, TableControl):
            makers.append(lambda ctl=ctl: lambda k0, m: ctl.samples(
                t0 + h * np.arange(k0, k0 + m))[:, None])
            where.append([slots[f"controls.{cname}"]])
    for nname, nz in system.noise.items():
        if nname in skip:
            continue
        makers.append(lambda nname=nname, nz=nz: noise_drawer(
            stream(seed, f"noise:{nname}"), nz.psd, h))
        where.append([slots[f"noise.{nname}.{i}"] for i in range(len(nz.targets))])
    flat = np.array([s for group in where for s in group], dtype=np.intp)
    dynamic = [(slots[f"controls.{c}"], ctl) for c, ctl in controls.items()
               if not isinstance(ctl, TableControl)]
    return ChunkedTable(n, makers, len(flat)), flat, dynamic


def _absent_noise_inputs(system: System, adapters: dict, signals: list[str]) -> list[str]:
    """The process-noise roles (``w_*`` inputs of the vehicle roles) among ``signals`` that
    their FMU, a vehicle with no input besides its roles, does not have. A typo, or a
    vehicle with inputs it could take the noise on (unmapped), stays an error."""
    out = []
    for sig in signals:
        fmu, _, var = sig.partition(".")
        f = system.fmus.get(fmu)
        role = (f.role or (fmu if fmu in ROLES else None)) if f is not None else None
        roles = ROLES.get(role, {}) if role else {}
        spec = roles.get(var)
        if spec is None or not var.startswith("w_") or spec[0] != "input" or spec[2] \
                or fmu not in adapters:  # an FMU that could not be opened: reported already
            continue
        variables = adapters[fmu].variables
        other_inputs = [n for n, v in variables.items()
                        if v.causality == "input" and n not in roles]
        if var not in variables and not other_inputs:
            out.append(sig)
    return out


def noise_free_sources(system: System, adapters: dict) -> dict[str, str]:
    """``{noise source: FMU}`` for the noise sources none of whose targets their FMU has (a
    third-party vehicle without process-noise inputs): the truth runs without them."""
    out = {}
    for nname, nz in system.noise.items():
        absent = _absent_noise_inputs(system, adapters, list(nz.targets))
        if absent and len(absent) == len(nz.targets):
            out[nname] = absent[0].partition(".")[0]
    return out
