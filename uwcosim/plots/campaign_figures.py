"""Campaign figures: RMSE of every run (seed 000 Figs. 18-21) and a summary with the spread.

The runs are independent: ``rmse_per_run_*.png`` draws them as markers (no line joins them) at
integer run numbers; ``rmse_summary.png`` has a log axis with plain tick labels.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from uwcosim.plots.labels import display_name, plain_log_ticks  # noqa: E402

#: markers of the estimators, in turn
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*")


def rmse_per_run(rows: list[dict], out: Path) -> list[Path]:
    paths = []
    variants = sorted({r["variant"] for r in rows if r["estimator"]})
    for variant in variants:
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), dpi=110, sharex=True,
                                 layout="constrained")
        ests = sorted({r["estimator"] for r in rows if r["variant"] == variant and r["estimator"]})
        for k, est in enumerate(ests):
            rs = sorted((r for r in rows if r["variant"] == variant and r["estimator"] == est),
                        key=lambda r: r["run"])
            runs = [r["run"] for r in rs]
            style = {"marker": _MARKERS[k % len(_MARKERS)], "ls": "none", "ms": 6,
                     "mfc": "none", "mew": 1.3, "label": display_name(est)}
            axes[0].plot(runs, [r["rmse_position_m"] for r in rs], **style)
            axes[1].plot(runs, [r["rmse_velocity_mps"] for r in rs], **style)
        axes[0].set_ylabel("position RMSE (m)")
        axes[1].set_ylabel("velocity RMSE (m/s)")
        axes[1].set_xlabel("run")
        axes[1].xaxis.set_major_locator(MaxNLocator(integer=True))
        for ax in axes:
            ax.grid(alpha=0.3)
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside right upper",
                   fontsize=9, frameon=False)
        fig.suptitle(f"RMSE of each run (independent runs): {variant}")
        path = out / f"rmse_per_run_{variant}.png"
        fig.savefig(path)
        plt.close(fig)
        paths.append(path)
    return paths


def summary_chart(rows: list[dict], out: Path) -> Path:
    groups: dict[str, list[float]] = {}
    for r in rows:
        if r["estimator"] and r["status"] == "ok" and not r["diverged"]:
            groups.setdefault(f"{display_name(r['estimator'])}\n{r['variant']}",
                              []).append(r["rmse_position_m"])
    labels = sorted(groups)
    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(labels)), 4.5), dpi=110)
    if labels:
        ax.boxplot([np.asarray(groups[k]) for k in labels], showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=7)
    ax.set_ylabel("position RMSE per run (m)")
    ax.set_yscale("log")
    plain_log_ticks(ax.yaxis)
    ax.grid(alpha=0.3, axis="y", which="both")
    ax.set_title("Position RMSE over the runs (box: quartiles, triangle: mean)")
    fig.tight_layout()
    path = out / "rmse_summary.png"
    fig.savefig(path)
    plt.close(fig)
    return path
