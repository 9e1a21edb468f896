"""Posterior densities of grid and projection filters at a few instants (``density_t*.png``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


class DensitySnapshots:
    """A master hook that keeps ``density_grid()`` of the estimators that have one, at times."""

    def __init__(self, bank, times: list[float], truth_xy: tuple[int, int]) -> None:
        self.bank = bank
        self.times = sorted(times)
        self.truth_xy = truth_xy
        self.snaps: list[dict] = []

    def __call__(self, master) -> None:
        if not self.times or master.t + 1e-9 < self.times[0]:
            return
        while self.times and master.t + 1e-9 >= self.times[0]:
            self.times.pop(0)
        snap = {"t": master.t, "truth": master.bus[self.bank.truth_slots][list(self.truth_xy)],
                "densities": {}}
        for tr in self.bank.tracks:
            grid = getattr(tr.estimator, "density_grid", None)
            if grid is None or tr.diverged_at is not None:
                continue
            axes, values = grid(n=81)
            if len(axes) == 2:
                snap["densities"][tr.name] = (axes, values, tr.estimator.x.copy())
        if snap["densities"]:
            self.snaps.append(snap)

    def draw(self, out: Path, states: list[str]) -> list[Path]:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        paths = []
        for snap in self.snaps:
            names = list(snap["densities"])
            fig, axs = plt.subplots(1, len(names), figsize=(4.2 * len(names), 4), dpi=110,
                                    squeeze=False)
            for ax, name in zip(axs[0], names):
                axes, values, x = snap["densities"][name]
                X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
                ax.contourf(X, Y, values, levels=20, cmap="magma")
                ax.plot(*snap["truth"], "c+", ms=12, mew=2, label="truth")
                ax.plot(x[self.truth_xy[0]], x[self.truth_xy[1]], "wx", ms=8, label="mean")
                ax.set_title(name)
                ax.set_xlabel(f"{states[self.truth_xy[0]]} (m)")
                ax.set_ylabel(f"{states[self.truth_xy[1]]} (m)")
                ax.legend(fontsize=7)
            fig.suptitle(f"Posterior density at t = {snap['t']:g} s")
            fig.tight_layout()
            path = out / f"density_t{snap['t']:g}.png"
            fig.savefig(path)
            plt.close(fig)
            paths.append(path)
        return paths
