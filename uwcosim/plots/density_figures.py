"""Posterior densities of grid and projection filters at a few instants (``density_t*.png``).

During the run, :class:`DensitySnapshots` (a master hook) evaluates the density of every
estimator that has one (``density_grid``) on one common grid per instant: the union of the
estimators' own boxes, made square. The snapshots are saved to ``densities.npz`` in the run
directory, and :func:`draw_densities` draws them from that file alone (the report stage): in
each figure the panels share their extent and their colour scale, with one colorbar.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from uwcosim.estimator_bank import EstimatorBank
    from uwcosim.master.master import Master

import numpy as np

N_POINTS = 81


class DensitySnapshots:
    """A master hook that keeps ``density_grid()`` of the estimators that have one, at times."""

    def __init__(self, bank: EstimatorBank, times: list[float],
                 truth_xy: tuple[int, int]) -> None:
        self.bank = bank
        self.times = sorted(times)
        self.truth_xy = truth_xy
        self.snaps: list[dict] = []

    def __call__(self, master: Master) -> None:
        if not self.times or master.t + 1e-9 < self.times[0]:
            return
        while self.times and master.t + 1e-9 >= self.times[0]:
            self.times.pop(0)
        grids = {}
        for tr in self.bank.tracks:
            grid = getattr(tr.estimator, "density_grid", None)
            if grid is None or tr.diverged_at is not None:
                continue
            axes, _ = grid(n=N_POINTS)
            if len(axes) == 2:
                grids[tr.name] = (grid, axes, tr.estimator.x.copy())
        if not grids:
            return
        lo = [min(a[d][0] for _, a, _ in grids.values()) for d in range(2)]
        hi = [max(a[d][-1] for _, a, _ in grids.values()) for d in range(2)]
        half = max(hi[0] - lo[0], hi[1] - lo[1]) / 2  # a square box: equal axes, no gaps
        mid = [(lo[d] + hi[d]) / 2 for d in range(2)]
        common = [np.linspace(mid[d] - half, mid[d] + half, N_POINTS) for d in range(2)]
        snap = {"t": master.t, "truth": master.bus[self.bank.truth_slots][list(self.truth_xy)],
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


def read_densities(path: Path) -> tuple[list[str], list[dict]]:
    """``(state names of the two axes, snapshots)`` from a ``densities.npz``."""
    with np.load(path) as data:
        keys = list(data.keys())
        states = [str(s) for s in data["states"]]
        snaps = []
        i = 0
        while f"{i}|t" in data:
            names = [k.split("|")[1] for k in keys
                     if k.startswith(f"{i}|") and k.endswith("|values")]
            snaps.append({"t": float(data[f"{i}|t"]), "truth": data[f"{i}|truth"],
                          "axes": (data[f"{i}|x"], data[f"{i}|y"]),
                          "densities": {n: (data[f"{i}|{n}|values"], data[f"{i}|{n}|mean"])
                                        for n in names}})
            i += 1
    return states, snaps


def draw_densities(path: Path, out: Path) -> list[Path]:
    """One ``density_t<T>.png`` per snapshot of ``path``: shared extent, colour scale, colorbar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    states, snaps = read_densities(path)
    paths = []
    for snap in snaps:
        names = list(snap["densities"])
        vmax = max(float(np.max(v)) for v, _ in snap["densities"].values())
        levels = np.linspace(0.0, vmax if vmax > 0 else 1.0, 21)
        fig, axs = plt.subplots(1, len(names), figsize=(3.9 * len(names) + 1.0, 4.4), dpi=110,
                                squeeze=False, sharex=True, sharey=True, layout="constrained")
        X, Y = np.meshgrid(*snap["axes"], indexing="ij")
        im = None
        for ax, name in zip(axs[0], names):
            values, mean = snap["densities"][name]
            im = ax.contourf(X, Y, values, levels=levels, cmap="magma", extend="neither")
            ax.plot(*snap["truth"], "c+", ms=12, mew=2, label="truth")
            ax.plot(*mean, "wx", ms=8, label="mean")
            ax.set_title(name)
            ax.set_xlabel(f"{states[0]} (m)")
            ax.set_aspect("equal", adjustable="box")
            ax.legend(fontsize=7, loc="upper right")
        axs[0, 0].set_ylabel(f"{states[1]} (m)")
        fig.colorbar(im, ax=axs[0, :].tolist(), label="posterior density (1/m²)", shrink=0.9,
                     format="%.1e")
        fig.suptitle(f"Posterior density at t = {snap['t']:g} s (common grid and colour scale)")
        p = out / f"density_t{snap['t']:g}.png"
        fig.savefig(p)
        plt.close(fig)
        paths.append(p)
    return paths
