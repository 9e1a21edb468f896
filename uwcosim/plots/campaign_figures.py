"""Campaign figures: RMSE of every run (seed 000 Figs. 18-21) and a summary with the spread."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def rmse_per_run(rows: list[dict], out: Path) -> list[Path]:
    paths = []
    variants = sorted({r["variant"] for r in rows if r["estimator"]})
    for variant in variants:
        fig, axes = plt.subplots(2, 1, figsize=(8, 6), dpi=110, sharex=True)
        ests = sorted({r["estimator"] for r in rows if r["variant"] == variant and r["estimator"]})
        for est in ests:
            rs = sorted((r for r in rows if r["variant"] == variant and r["estimator"] == est),
                        key=lambda r: r["run"])
            runs = [r["run"] for r in rs]
            axes[0].plot(runs, [r["rmse_position_m"] for r in rs], ".-", lw=0.8, label=est)
            axes[1].plot(runs, [r["rmse_velocity_mps"] for r in rs], ".-", lw=0.8, label=est)
        axes[0].set_ylabel("position RMSE (m)")
        axes[1].set_ylabel("velocity RMSE (m/s)")
        axes[1].set_xlabel("run")
        axes[0].legend(fontsize=8)
        fig.suptitle(f"RMSE of each run: {variant}")
        fig.tight_layout()
        path = out / f"rmse_per_run_{variant}.png"
        fig.savefig(path)
        plt.close(fig)
        paths.append(path)
    return paths


def summary_chart(rows: list[dict], out: Path) -> Path:
    groups: dict[str, list[float]] = {}
    for r in rows:
        if r["estimator"] and r["status"] == "ok" and not r["diverged"]:
            groups.setdefault(f"{r['estimator']}\n{r['variant']}", []).append(r["rmse_position_m"])
    labels = sorted(groups)
    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(labels)), 4.5), dpi=110)
    if labels:
        ax.boxplot([np.asarray(groups[k]) for k in labels], showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=7)
    ax.set_ylabel("position RMSE per run (m)")
    ax.set_yscale("log")
    ax.set_title("Position RMSE over the runs (box: quartiles, triangle: mean)")
    fig.tight_layout()
    path = out / "rmse_summary.png"
    fig.savefig(path)
    plt.close(fig)
    return path
