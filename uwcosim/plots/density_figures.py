"""Posterior densities of grid and projection filters at a few instants (``density_t*.png``).

:func:`draw_densities` draws the snapshots a run saved to ``densities.npz``
(:class:`uwcosim.run.density.DensitySnapshots`) from that file alone (the report stage): in
each figure the panels share their extent and their colour scale, with one colorbar.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


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
