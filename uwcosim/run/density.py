"""Posterior densities of the grid and projection filters at a few steps, during a run.

:class:`DensitySnapshots` (an observer of the master, after the estimator bank) evaluates the
density of every live estimator that has one (``density_grid``) at the snapshot steps (the
bank ends a block there, so every estimator is at that step): on one common grid per step,
the union of the estimators' own boxes made square. :meth:`DensitySnapshots.save` writes them
to ``densities.npz`` in the run directory, which the report stage draws
(:func:`uwcosim.plots.density_figures.draw_densities`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from pathlib import Path

import numpy as np

from uwcosim.filters import Estimator
from uwcosim.master.observer import StepView

#: points per axis of the common grid
N_POINTS = 81


class DensitySnapshots:
    """Keeps ``density_grid()`` of the live estimators that have one, at the given steps.

    ``live``: the estimators to look at (``(name, estimator)`` pairs, e.g.
    :meth:`uwcosim.run.bank.EstimatorBank.live`); ``truth_slots``: the bus slots of the
    truth's position ``(x, y)``; ``pos``: the indices of the position in the state."""

    def __init__(self, live: Callable[[], list[tuple[str, Estimator]]], steps: Collection[int],
                 truth_slots: Sequence[int], pos: tuple[int, int]) -> None:
        self.live = live
        self.steps = frozenset(int(k) for k in steps)
        self.truth_slots = np.asarray(truth_slots, dtype=np.intp)
        self.truth_xy = pos
        self.snaps: list[dict] = []

    def on_step(self, k: int, view: StepView) -> None:
        if k not in self.steps:
            return
        grids = {}
        for name, est in self.live():
            grid = getattr(est, "density_grid", None)
            if grid is None:
                continue
            axes, _ = grid(n=N_POINTS)
            if len(axes) == 2:
                grids[name] = (grid, axes, est.x.copy())
        if not grids:
            return
        lo = [min(a[d][0] for _, a, _ in grids.values()) for d in range(2)]
        hi = [max(a[d][-1] for _, a, _ in grids.values()) for d in range(2)]
        half = max(hi[0] - lo[0], hi[1] - lo[1]) / 2  # a square box: equal axes, no gaps
        mid = [(lo[d] + hi[d]) / 2 for d in range(2)]
        common = [np.linspace(mid[d] - half, mid[d] + half, N_POINTS) for d in range(2)]
        snap = {"t": view.t, "truth": view.signals(self.truth_slots),
                "axes": common, "densities": {}}
        for name, (grid, _, x) in grids.items():
            _, values = grid(axes=common)
            snap["densities"][name] = (values, x[list(self.truth_xy)])
        self.snaps.append(snap)

    def save(self, path: Path, states: list[str]) -> Path | None:
        """Write the snapshots to ``path`` (``.npz``); nothing when there is none."""
        if not self.snaps:
            return None
        arrays = {"states": np.array([states[i] for i in self.truth_xy])}
        for i, snap in enumerate(self.snaps):
            arrays[f"{i}|t"] = np.array(snap["t"])
            arrays[f"{i}|truth"] = np.asarray(snap["truth"], dtype=float)
            arrays[f"{i}|x"], arrays[f"{i}|y"] = snap["axes"]
            for name, (values, mean) in snap["densities"].items():
                arrays[f"{i}|{name}|values"] = values
                arrays[f"{i}|{name}|mean"] = mean
        np.savez_compressed(path, **arrays)
        return Path(path)
