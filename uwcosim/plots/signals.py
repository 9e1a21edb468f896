"""Figures of the logged signals of a run (a plain co-simulation run's report draws them:
:mod:`uwcosim.reports.signal_report`).

Reads only the run's log table (``log.parquet``), so it serves any run directory. One panel per
signal group: the part of the column name before the first ``.`` (the FMU, or ``controls``), at
most :data:`PER_PANEL` lines a panel; time on x. Integer and Boolean signals are drawn as steps
(held between samples); String columns are listed, not drawn.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402

from uwcosim.runlog import read_log  # noqa: E402

PER_PANEL = 8
PANELS_PER_FIGURE = 6


def signal_groups(names: list[str]) -> list[tuple[str, list[str]]]:
    """``[(panel title, [columns])]``: columns grouped by their prefix, in log order."""
    groups: dict[str, list[str]] = {}
    for n in names:
        if n == "time":
            continue
        groups.setdefault(n.split(".", 1)[0], []).append(n)
    out = []
    for g, cols in groups.items():
        parts = [cols[i:i + PER_PANEL] for i in range(0, len(cols), PER_PANEL)]
        for i, part in enumerate(parts):
            out.append((g if len(parts) == 1 else f"{g} ({i + 1}/{len(parts)})", part))
    return out


def _kinds(log_path: Path) -> dict[str, str]:
    """``{column: "float" | "step" | "text"}`` from the Parquet schema."""
    import pyarrow as pa

    out = {}
    for f in pq.read_schema(log_path):
        t = f.type
        if pa.types.is_string(t) or pa.types.is_large_string(t):
            out[f.name] = "text"
        elif pa.types.is_integer(t) or pa.types.is_boolean(t):
            out[f.name] = "step"
        else:
            out[f.name] = "float"
    return out


def signal_figures(log_path: str | Path, out_dir: str | Path,
                   stem: str = "signals") -> tuple[list[Path], list[str]]:
    """Draw the log's signals into ``out_dir/stem.png`` (``stem_2.png``... when there are
    more than :data:`PANELS_PER_FIGURE` panels); returns the figures and the String columns."""
    log_path, out_dir = Path(log_path), Path(out_dir)
    cols, _ = read_log(log_path)
    kinds = _kinds(log_path)
    text = [n for n, k in kinds.items() if k == "text"]
    groups = signal_groups([n for n in cols if kinds.get(n) != "text"])
    t = np.asarray(cols["time"], dtype=float)
    paths = []
    for fig_i in range(0, len(groups), PANELS_PER_FIGURE):
        chunk = groups[fig_i:fig_i + PANELS_PER_FIGURE]
        fig, axes = plt.subplots(len(chunk), 1, figsize=(8, 2.1 * len(chunk) + 0.7), dpi=100,
                                 sharex=True, squeeze=False)
        for ax, (title, names) in zip(axes[:, 0], chunk):
            for n in names:
                y = np.asarray(cols[n], dtype=float)
                style = "steps-post" if kinds.get(n) == "step" else "default"
                ax.plot(t, y, lw=1.0, drawstyle=style, label=n.split(".", 1)[-1])
            ax.set_title(title, fontsize=9, loc="left")
            ax.grid(alpha=0.3)
            ax.legend(loc="upper right", fontsize=7, ncol=min(4, len(names)))
        axes[-1, 0].set_xlabel("time (s)")
        fig.tight_layout()
        n = fig_i // PANELS_PER_FIGURE
        path = out_dir / (f"{stem}.png" if n == 0 else f"{stem}_{n + 1}.png")
        fig.savefig(path)
        plt.close(fig)
        paths.append(path)
    return paths, text
