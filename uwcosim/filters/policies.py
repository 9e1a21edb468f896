"""Lost-measurement policies: what a filter is fed when measurement components are missing.

``policy = POLICIES.get(name)(nz)`` builds one policy object per estimator (it may keep
history); before every ``update`` the driver calls ``z2, mask2 = policy(t, z, mask)`` with the
received vector ``z`` (``None``, or NaN where missing) and ``mask`` (False = missing) and feeds
``est.update(z2, mask2)``. A component is missing when its mask is False or its value is not
finite.

- ``skip``: the standard filter: missing components are left out of the update (nothing
  received: no update).
- ``zero``: seed 001 eq. (2): a lost measurement reaches the filter as ``Y_k = 0``; missing
  components are set to 0 and marked present.
- ``extrapolate``: seed 001 eq. (28): a missing component is replaced by the three-point
  Lagrange polynomial through the last three *received* values of that component, at their
  actual times, evaluated at ``t``. With fewer than three received values it stays missing.
  Extrapolated values never enter the history. ``mode="runs"`` (the policy's default)
  extrapolates every missing value, also inside a run of consecutive losses (our
  generalization); ``mode="isolated"`` only a single loss right after three consecutive
  receipts (seed 001's Assumption 1), other losses stay missing.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from uwcosim.core.registry import Registry

POLICIES: Registry[type] = Registry("lost-measurement policy")


def lagrange_weights(ts, t: float) -> tuple[float, float, float]:
    """The weights ``l_j(t) = prod_{i != j} (t - t_i) / (t_j - t_i)`` of seed 001 eq. (28)."""
    t0, t1, t2 = (float(v) for v in ts)
    l0 = (t - t1) * (t - t2) / ((t0 - t1) * (t0 - t2))
    l1 = (t - t0) * (t - t2) / ((t1 - t0) * (t1 - t2))
    l2 = (t - t0) * (t - t1) / ((t2 - t0) * (t2 - t1))
    return l0, l1, l2


def lagrange_extrapolate(ts, ys, t: float) -> np.ndarray:
    """Seed 001 eq. (28): ``L_2(t) = sum_j Y_j l_j(t)`` through three points ``(ts[j], ys[j])``.

    ``ys`` may hold vectors (rows).
    """
    l0, l1, l2 = lagrange_weights(ts, t)
    ys = np.asarray(ys, dtype=float)
    return l0 * ys[0] + l1 * ys[1] + l2 * ys[2]


def noise_gain(ts, t: float) -> float:
    """``sum_j l_j(t)^2``: the variance of an extrapolated value over that of one measurement
    (independent equal noises); 1 + 9 + 9 = 19 for one step after three equally spaced ones."""
    return float(sum(v * v for v in lagrange_weights(ts, t)))


def missing_mask(z, mask, nz: int) -> np.ndarray:
    """Boolean mask of the *present* components (mask True and value finite)."""
    if z is None:
        return np.zeros(nz, dtype=bool)
    present = np.isfinite(np.asarray(z, dtype=float))
    if mask is not None:
        present &= np.asarray(mask, dtype=bool)
    return present


class Policy:
    """Base class: ``policy(t, z, mask) -> (z, mask)`` for a measurement vector of size nz."""

    def __init__(self, nz: int) -> None:
        self.nz = int(nz)

    def __call__(self, t: float, z, mask=None):
        raise NotImplementedError


@POLICIES.register("skip")
class Skip(Policy):
    """Standard filtering: missing components are skipped (``z`` and ``mask`` unchanged)."""

    def __call__(self, t: float, z, mask=None):
        present = missing_mask(z, mask, self.nz)
        return (None if z is None else np.asarray(z, dtype=float)), present


@POLICIES.register("zero")
class Zero(Policy):
    """Seed 001 eq. (2): missing components are fed as 0 (and marked present)."""

    def __call__(self, t: float, z, mask=None):
        present = missing_mask(z, mask, self.nz)
        z2 = np.zeros(self.nz) if z is None else np.asarray(z, dtype=float).copy()
        z2[~present] = 0.0
        return z2, np.ones(self.nz, dtype=bool)


@POLICIES.register("extrapolate")
class Extrapolate(Policy):
    """Seed 001 eq. (28): missing components extrapolated by the three-point Lagrange
    polynomial through the last three received values (per component, at their times).

    ``mode``: ``"runs"`` (every missing value once three were received) or ``"isolated"``
    (only a loss right after three consecutive receipts). After a call, ``extrapolated`` counts
    the filled components and ``gain[i]`` is the noise gain :func:`noise_gain` of component
    ``i`` (1 where it was received or left missing).
    """

    MODES = ("runs", "isolated")

    def __init__(self, nz: int, mode: str = "runs") -> None:
        super().__init__(nz)
        if mode not in self.MODES:
            raise ValueError(f"extrapolate must be one of {', '.join(self.MODES)}, got {mode!r}")
        self.mode = mode
        self.history: list[deque] = [deque(maxlen=3) for _ in range(self.nz)]
        self.streak = np.zeros(self.nz, dtype=int)  # consecutive receipts before now
        self.extrapolated = 0  # components filled by the last call
        self.gain = np.ones(self.nz)

    def __call__(self, t: float, z, mask=None):
        t = float(t)
        present = missing_mask(z, mask, self.nz)
        z2 = np.full(self.nz, np.nan) if z is None else np.asarray(z, dtype=float).copy()
        out = present.copy()
        self.gain = np.ones(self.nz)
        isolated = self.mode == "isolated"
        for i in range(self.nz):
            hist = self.history[i]
            if present[i]:
                if hist and hist[-1][0] == t:  # the same instant again: keep the latest value
                    hist.pop()
                else:
                    self.streak[i] += 1
                hist.append((t, z2[i]))
            else:
                if len(hist) == 3 and (not isolated or self.streak[i] >= 3):
                    ts, ys = zip(*hist)
                    z2[i] = lagrange_extrapolate(ts, ys, t)
                    self.gain[i] = noise_gain(ts, t)
                    out[i] = True
                self.streak[i] = 0
        self.extrapolated = int(np.count_nonzero(out & ~present))
        return z2, out
