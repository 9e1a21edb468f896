"""Signal sources owned by the master: control inputs, noise, and measurement-loss models.

All randomness comes from :func:`stream`, one independent ``numpy.random.Generator`` per named
purpose derived from the run seed, so adding a sensor does not change another sensor's noise,
and the same scenario and seed always give the same samples.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from uwcosim.scenario.schema import BernoulliLoss, ControlSpec, GilbertElliottLoss


def stream(seed: int, purpose: str) -> np.random.Generator:
    """An independent generator for ``purpose`` (e.g. ``'noise:process'``, ``'loss:dvl'``)."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(purpose.encode())])


class TableControl:
    """A piecewise-linear (or held) table ``[[t, value], ...]``, constant beyond its ends."""

    dynamic = False

    def __init__(self, spec: ControlSpec) -> None:
        table = np.asarray(spec.table, dtype=float)
        self.t, self.v = table[:, 0], table[:, 1]
        self.hold = spec.interpolation == "hold"

    def value(self, t):
        if self.hold:
            i = np.searchsorted(self.t, t, side="right") - 1
            return self.v[np.clip(i, 0, len(self.v) - 1)]
        return np.interp(t, self.t, self.v)

    def samples(self, times: np.ndarray) -> np.ndarray:
        return np.asarray(self.value(times), dtype=float)


class WaypointHeading:
    """Heading towards the active waypoint (closed loop on the true position).

    The heading is ``atan2(dy, dx)`` in the frame of eq. (54) (psi from the x axis), unwrapped
    so it stays continuous; a waypoint is passed when the vehicle comes within
    ``acceptance_radius``. After the last one the heading is held.
    """

    dynamic = True

    def __init__(self, spec: ControlSpec) -> None:
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

    def value(self, t):
        return self.last if self.last is not None else 0.0


def white_noise(rng: np.random.Generator, n_steps: int, psd, h: float) -> np.ndarray:
    """Held white-noise samples ``[n_steps, n]`` of variance ``psd / h`` (PSD held over h)."""
    psd = np.asarray(psd, dtype=float)
    return rng.standard_normal((n_steps, psd.size)) * np.sqrt(psd / h)


def gaussian(rng: np.random.Generator, n_steps: int, sigma) -> np.ndarray:
    sigma = np.asarray(sigma, dtype=float)
    return rng.standard_normal((n_steps, sigma.size)) * sigma


def loss_mask(
    rng: np.random.Generator, n: int, spec: BernoulliLoss | GilbertElliottLoss | None
) -> np.ndarray:
    """``True`` where the measurement is received, for ``n`` samples.

    Bernoulli: lost with probability ``p`` (seed 001 eq. 2). Gilbert-Elliott: a two-state
    Markov chain (good/bad) with transition probabilities ``p_good_to_bad``,
    ``p_bad_to_good`` and loss probabilities ``loss_good``, ``loss_bad`` per state (bursts).
    """
    if spec is None:
        return np.ones(n, dtype=bool)
    u = rng.random(n)
    if isinstance(spec, BernoulliLoss):
        return u >= spec.p
    switch = rng.random(n)
    bad = np.empty(n, dtype=bool)
    state = False
    for i in range(n):
        bad[i] = state
        if state:
            state = switch[i] >= spec.p_bad_to_good
        else:
            state = switch[i] < spec.p_good_to_bad
    p_loss = np.where(bad, spec.loss_bad, spec.loss_good)
    return u >= p_loss


def control_problem(c: ControlSpec, var) -> str | None:
    """Why control ``c`` cannot drive the FMU input ``var`` (None: it can). A control drives a
    Real input, or an Integer/Boolean one with a held table of whole (Boolean: 0/1) values."""
    from uwcosim.master import vartypes

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


@dataclass
class Sensor:
    """A group of FMU outputs measured together, with its sampling and loss."""

    name: str
    outputs: list[str]
    slots: np.ndarray
    period: int
    received: np.ndarray  # [n_steps + 1] bool: sampled and not lost at step k
    sampled: np.ndarray = field(default=None)


def sample_sources(system, controls: dict, slots: dict[str, int], seed: int, n: int,
                   skip=()):
    """The open-loop sources of ``system`` sampled on the ``n`` grid points, from the seed's
    streams: ``(table [n, m], bus slots [m], [(slot, closed-loop control)])``. Noise sources
    named in ``skip`` are left out (a truth FMU without their inputs)."""
    times = system.start_time + system.step * np.arange(n)
    cols, where = [], []
    for cname, ctl in controls.items():
        if isinstance(ctl, TableControl):
            cols.append(ctl.samples(times)[:, None])
            where.append([slots[f"controls.{cname}"]])
    for nname, nz in system.noise.items():
        if nname in skip:
            continue
        cols.append(white_noise(stream(seed, f"noise:{nname}"), n, nz.psd, system.step))
        where.append([slots[f"noise.{nname}.{i}"] for i in range(len(nz.targets))])
    for sname, s in system.sensors.items():
        if s.noise_inputs:
            cols.append(gaussian(stream(seed, f"sensor-noise:{sname}"), n, s.sigma))
            where.append([slots[f"sensornoise.{sname}.{i}"] for i in range(len(s.noise_inputs))])
    table = np.hstack(cols) if cols else np.zeros((n, 0))
    flat = np.array([s for group in where for s in group], dtype=np.intp)
    dynamic = [(slots[f"controls.{c}"], ctl) for c, ctl in controls.items()
               if not isinstance(ctl, TableControl)]
    return table, flat, dynamic


def build_sensors(system, slots: dict[str, np.ndarray], seed: int, n: int) -> dict[str, Sensor]:
    """The sensors of ``system`` with their sampling and (seeded) loss over ``n`` grid points."""
    out = {}
    k = np.arange(n)
    for sname, s in system.sensors.items():
        sampled = (k % s.period == 0) & (k > 0)
        received = sampled & loss_mask(stream(seed, f"loss:{sname}"), n, s.loss)
        out[sname] = Sensor(sname, list(s.outputs), slots[sname], s.period, received, sampled)
    return out
