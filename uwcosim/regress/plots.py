"""Diff plots of failing signals: the run over the baseline, and their difference against the
tolerance tube (at the signal's scale the tube is thinner than a line: the difference panel
shows it, drawn around the baseline's value).

One PNG per failing signal (matplotlib, Agg backend: no display needed).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np


def _file_name(signal: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", signal) + ".png"


def _diff_scale(axd, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """The difference panel's y scale: linear from the tube's widest point and the 99th
    percentile of the difference with a margin; when the difference is more than 20 times
    the tube, symmetric-log with the tube in its linear part (the tube stays visible)."""
    tube = np.abs(np.concatenate([lo, hi]))
    tube = tube[np.isfinite(tube)]
    dd = np.abs(d[np.isfinite(d)])
    w = float(tube.max()) if tube.size else 0.0
    big = float(np.percentile(dd, 99)) if dd.size else 0.0
    if w > 0 and big > 20 * w:
        axd.set_yscale("symlog", linthresh=w, linscale=1.5)
        return
    lim = 1.2 * max(w, big)
    if np.isfinite(lim) and lim > 0:
        axd.set_ylim(-lim, lim)


def diff_plot(result, arrays: dict, out_dir: Path) -> Path:
    """Write ``out_dir/<signal>.png`` for ``result`` (a failing SignalResult) and return it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, y, out = arrays["t"], arrays["y"], arrays["out"]
    fig, (ax, axd) = plt.subplots(2, 1, sharex=True, figsize=(8, 6.0), layout="constrained",
                                  gridspec_kw={"height_ratios": [2, 3]})
    ms = 4 if out.sum() < 200 else 2  # many points outside: small marks
    ax.plot(arrays["t_ref"], arrays["y_ref"], color="0.3", lw=1.0, label="baseline")
    ax.plot(t, y, color="C0", lw=1.0, ls="--", label="run")
    if out.any():
        ax.plot(t[out], np.where(np.isnan(y[out]), arrays["lo"][out], y[out]), "x", color="C3",
                ms=ms, label=f"outside ({int(out.sum())})")
    ax.set_ylabel(result.name, fontsize=9)
    ax.set_title("signal (its tolerance tube, too thin at this scale, in the panel below)",
                 fontsize=9, loc="left")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    # the difference from the baseline, against the tube drawn around the baseline's value
    ref_at = np.interp(t, arrays["t_ref"], arrays["y_ref"])
    d, lo, hi = y - ref_at, arrays["lo"] - ref_at, arrays["hi"] - ref_at
    axd.fill_between(t, lo, hi, color="C2", alpha=0.3, lw=0, label="tolerance tube")
    axd.plot(t, d, color="C0", lw=1.0, label="run - baseline")
    if out.any():
        axd.plot(t[out], np.where(np.isnan(d[out]), lo[out], d[out]), "x", color="C3", ms=ms,
                 label="outside")
    _diff_scale(axd, d, lo, hi)
    axd.axhline(0.0, color="0.5", lw=0.5)
    axd.set_ylabel(f"difference from the baseline ({result.name})", fontsize=9)
    axd.set_title(f"difference against the tolerance tube (tolerance {result.tol:.3g}, "
                  "and the baseline's spread within the time tolerance)", fontsize=9,
                  loc="left")
    axd.set_xlabel("time (s)")
    axd.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.suptitle(f"{result.name}: largest deviation {result.max_dev:.3g} at "
                 f"t = {result.t_max_dev:g} s (tolerance {result.tol:.3g})", fontsize=10)
    path = Path(out_dir) / _file_name(result.name)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
