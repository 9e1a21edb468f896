"""Posterior densities of grid and projection filters at a few instants (``density_t*.png``).

:func:`draw_densities` draws the snapshots a run saved to ``densities.npz``
(:class:`uwcosim.run.density.DensitySnapshots`) from that file alone (the report stage): in
each figure the panels share their window and their colour scale, with one colorbar. The window
is where the posteriors are (:func:`density_window`: the box holding 99 % of every panel's
mass, the truth and the means, with half its size again around it as context), not the whole
grid, on which a tight posterior fills a few cells; zero density (the lowest of 20 bands, below
5 % of the largest value) is white.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from uwcosim.plots.labels import display_name


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


#: probability mass of each density (its positive part) that the window holds at least
WINDOW_MASS = 0.99
#: context around the box that holds the mass: this fraction of its size on each side
WINDOW_CONTEXT = 0.25


def _mass_interval(axis: np.ndarray, marginal: np.ndarray, mass: float) -> tuple[float, float]:
    """The central interval of ``axis`` that holds ``mass`` of the (unnormalised) marginal:
    from the cell where the cumulative sum passes ``(1 - mass) / 2`` to the one where it
    passes ``(1 + mass) / 2``."""
    c = np.cumsum(np.clip(np.nan_to_num(marginal), 0.0, None))
    if c[-1] <= 0:
        return float(axis[0]), float(axis[-1])
    c /= c[-1]
    i0 = int(np.searchsorted(c, (1.0 - mass) / 2.0))
    i1 = int(np.searchsorted(c, (1.0 + mass) / 2.0))
    return float(axis[max(i0 - 1, 0)]), float(axis[min(i1 + 1, axis.size - 1)])


def density_window(x: np.ndarray, y: np.ndarray, densities: list[np.ndarray],
                   points: list, mass: float = WINDOW_MASS,
                   context: float = WINDOW_CONTEXT) -> tuple[float, float, float, float]:
    """``(x0, x1, y0, y1)``: the square window that shows every density of ``densities``
    (values on the grid ``x`` by ``y``, ``indexing="ij"``) and the ``points`` ``(x, y)``.

    Per density (its positive part: a projection filter's ripples below zero are no mass),
    the central interval of each marginal that holds ``(1 + mass) / 2``, so that the box holds
    at least ``mass`` of the density (what falls outside is at most half of ``1 - mass`` in
    each of the two marginals); the union of these boxes and of the points, widened by
    ``context`` of its size on each side, made square (the panels have equal axes), at least
    four grid cells wide, and kept on the grid."""
    boxes = []
    for v in densities:
        v = np.asarray(v, dtype=float)
        v = np.clip(np.nan_to_num(v), 0.0, None)
        m = (1.0 + mass) / 2.0
        boxes.append((*_mass_interval(x, v.sum(axis=1), m), *_mass_interval(y, v.sum(axis=0), m)))
    pts = [p for p in points if p is not None and np.all(np.isfinite(p))]
    lo_x = min([b[0] for b in boxes] + [float(p[0]) for p in pts])
    hi_x = max([b[1] for b in boxes] + [float(p[0]) for p in pts])
    lo_y = min([b[2] for b in boxes] + [float(p[1]) for p in pts])
    hi_y = max([b[3] for b in boxes] + [float(p[1]) for p in pts])
    cell = max(abs(float(x[1] - x[0])) if x.size > 1 else 1.0,
               abs(float(y[1] - y[0])) if y.size > 1 else 1.0)
    half = max(hi_x - lo_x, hi_y - lo_y, 4 * cell) * (0.5 + context)
    cx, cy = (lo_x + hi_x) / 2, (lo_y + hi_y) / 2
    x0, x1 = max(cx - half, float(x.min())), min(cx + half, float(x.max()))
    y0, y1 = max(cy - half, float(y.min())), min(cy + half, float(y.max()))
    return x0, x1, y0, y1


def draw_densities(path: Path, out: Path) -> list[Path]:
    """One ``density_t<T>.png`` per snapshot of ``path``: one window (:func:`density_window`),
    colour scale and colorbar for its panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    states, snaps = read_densities(path)
    paths = []
    # one colour a band of the 20: white for the lowest (zero), then magma from light to dark
    cmap = ListedColormap(["white", *plt.get_cmap("magma_r")(np.linspace(0.08, 1.0, 19))])
    for snap in snaps:
        names = list(snap["densities"])
        vmax = max(float(np.max(v)) for v, _ in snap["densities"].values())
        levels = np.linspace(0.0, vmax if vmax > 0 else 1.0, 21)
        fig, axs = plt.subplots(1, len(names), figsize=(3.9 * len(names) + 1.0, 4.4), dpi=110,
                                squeeze=False, sharex=True, sharey=True, layout="constrained")
        gx, gy = snap["axes"]
        x0, x1, y0, y1 = density_window(gx, gy, [v for v, _ in snap["densities"].values()],
                                        [snap["truth"], *(m for _, m in
                                                          snap["densities"].values())])
        # the grid cells in the window, and one more on each side (the contours reach the edge)
        ki = np.flatnonzero((gx >= x0) & (gx <= x1))
        kj = np.flatnonzero((gy >= y0) & (gy <= y1))
        ki = np.arange(max(ki[0] - 1, 0), min(ki[-1] + 2, gx.size))
        kj = np.arange(max(kj[0] - 1, 0), min(kj[-1] + 2, gy.size))
        X, Y = np.meshgrid(gx[ki], gy[kj], indexing="ij")
        im = None
        handles = []
        for ax, name in zip(axs[0], names):
            values, mean = snap["densities"][name]
            shown = values[np.ix_(ki, kj)]
            im = ax.contourf(X, Y, shown, levels=levels, cmap=cmap, extend="neither")
            handles = [*ax.plot(*snap["truth"], "P", color="tab:green", mec="black", ms=11,
                                label="truth"),
                       *ax.plot(*mean, "X", color="tab:blue", mec="white", ms=9,
                                label="posterior mean")]
            ax.set_title(display_name(name))
            ax.set_xlabel(f"{states[0]} (m)")
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_aspect("equal", adjustable="box")
            ax.grid(alpha=0.3)
        axs[0, 0].set_ylabel(f"{states[1]} (m)")
        fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize=9,
                   frameon=False)
        fig.colorbar(im, ax=axs[0, :].tolist(), label="posterior density (1/m²)", shrink=0.9,
                     format="%.1e")
        fig.suptitle(f"Posterior density at t = {snap['t']:g} s (window around "
                     f"{100 * WINDOW_MASS:g} % of the mass; common colour scale)")
        p = out / f"density_t{snap['t']:g}.png"
        fig.savefig(p)
        plt.close(fig)
        paths.append(p)
    return paths
