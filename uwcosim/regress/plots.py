"""Diff plots of failing signals: the baseline's tolerance tube, the run, and their difference.

One PNG per failing signal (matplotlib, Agg backend: no display needed).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np


def _file_name(signal: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", signal) + ".png"


def diff_plot(result, arrays: dict, out_dir: Path) -> Path:
    """Write ``out_dir/<signal>.png`` for ``result`` (a failing SignalResult) and return it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, y, out = arrays["t"], arrays["y"], arrays["out"]
    fig, (ax, axd) = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5),
                                  gridspec_kw={"height_ratios": [3, 2]})
    ax.fill_between(t, arrays["lo"], arrays["hi"], color="0.8", label="tolerance tube",
                    step=None)
    ax.plot(arrays["t_ref"], arrays["y_ref"], color="0.3", lw=1.0, label="baseline")
    ax.plot(t, y, color="C0", lw=1.0, label="run")
    if out.any():
        ax.plot(t[out], np.where(np.isnan(y[out]), arrays["lo"][out], y[out]), "x", color="C3",
                ms=4, label=f"outside ({int(out.sum())})")
    ax.set_ylabel(result.name)
    ax.set_title(f"{result.name}: largest deviation {result.max_dev:.3g} at "
                 f"t={result.t_max_dev:g} s (tolerance {result.tol:.3g})", fontsize=9)
    ax.legend(fontsize=8, loc="best")
    ref_at = np.interp(t, arrays["t_ref"], arrays["y_ref"])
    axd.plot(t, y - ref_at, color="C0", lw=1.0, label="run - baseline")
    axd.axhline(result.tol, color="0.5", ls="--", lw=0.8, label="+/- tolerance")
    axd.axhline(-result.tol, color="0.5", ls="--", lw=0.8)
    axd.set_xlabel("time (s)")
    axd.legend(fontsize=8, loc="best")
    fig.tight_layout()
    path = Path(out_dir) / _file_name(result.name)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
