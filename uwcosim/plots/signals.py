"""Figures of the logged signals of a run (a plain co-simulation run's report draws them:
:mod:`uwcosim.reports.signal_report`).

Reads only the run's log table (``log.parquet``), so it serves any run directory. One panel per
signal group: the part of the column name before the first ``.`` (the FMU, or ``controls``), at
most :data:`PER_PANEL` lines a panel, of one unit (or, without units in the log, of one scale:
metres of position not with metres per second of velocity); time on x. Integer and Boolean
signals are drawn as steps (held between samples); String columns are listed, not drawn.
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
#: signals whose largest values differ by more than this factor go on separate panels
SCALE_RATIO = 30.0


def _magnitude(y: np.ndarray) -> float:
    """The largest absolute finite value of ``y`` (0 when there is none)."""
    f = np.abs(y[np.isfinite(y)])
    return float(f.max()) if f.size else 0.0


def _by_scale(names: list[str], mags: dict[str, float]) -> list[list[str]]:
    """``names`` in clusters of magnitudes within a factor :data:`SCALE_RATIO` (zero-valued
    signals join the smallest), each in log order, the clusters in the order of their first
    column in the log."""
    pos = sorted((n for n in names if mags.get(n, 0.0) > 0), key=mags.__getitem__)
    clusters: list[list[str]] = []
    for n in pos:
        if not clusters or mags[n] > SCALE_RATIO * mags[clusters[-1][0]]:
            clusters.append([])
        clusters[-1].append(n)
    zero = [n for n in names if mags.get(n, 0.0) <= 0]
    if zero:
        clusters = [clusters[0] + zero, *clusters[1:]] if clusters else [zero]
    rank = {n: i for i, n in enumerate(names)}
    return sorted((sorted(c, key=rank.__getitem__) for c in clusters),
                  key=lambda c: rank[c[0]])


def signal_groups(names: list[str], units: dict[str, str] | None = None,
                  mags: dict[str, float] | None = None) -> list[tuple[str, str, list[str]]]:
    """``[(panel title, unit, [columns])]``: columns grouped by their prefix, in log order, and
    within a prefix by unit (``units``, from the log) so that no panel mixes units; columns
    without a unit by scale (``mags``: largest absolute values; within a factor
    :data:`SCALE_RATIO`), so that positions of 1e4 m do not flatten velocities of 1 m/s; at
    most :data:`PER_PANEL` lines a panel."""
    units = units or {}
    groups: dict[str, list[str]] = {}
    for n in names:
        if n == "time":
            continue
        groups.setdefault(n.split(".", 1)[0], []).append(n)
    out = []
    for g, cols in groups.items():
        by_unit: dict[str, list[str]] = {}
        for n in cols:
            by_unit.setdefault(units.get(n, ""), []).append(n)
        subsets = []
        for unit, members in by_unit.items():
            for c in (_by_scale(members, mags or {}) if not unit else [members]):
                subsets += [(unit, c[i:i + PER_PANEL]) for i in range(0, len(c), PER_PANEL)]
        for i, (unit, part) in enumerate(subsets):
            out.append((g if len(subsets) == 1 else f"{g} ({i + 1}/{len(subsets)})", unit,
                        part))
    return out


def _kinds(log_path: Path) -> tuple[dict[str, str], dict[str, str]]:
    """``({column: "float" | "step" | "text"}, {column: unit})`` from the Parquet schema (the
    unit from a field's ``unit`` metadata, where the log has it)."""
    import pyarrow as pa

    out, units = {}, {}
    for f in pq.read_schema(log_path):
        t = f.type
        if pa.types.is_string(t) or pa.types.is_large_string(t):
            out[f.name] = "text"
        elif pa.types.is_integer(t) or pa.types.is_boolean(t):
            out[f.name] = "step"
        else:
            out[f.name] = "float"
        unit = (f.metadata or {}).get(b"unit", b"").decode("utf-8", "replace").strip()
        if unit:
            units[f.name] = unit
    return out, units


def signal_figures(log_path: str | Path, out_dir: str | Path,
                   stem: str = "signals") -> tuple[list[Path], list[str]]:
    """Draw the log's signals into ``out_dir/stem.png`` (``stem_2.png``... when there are
    more than :data:`PANELS_PER_FIGURE` panels); returns the figures and the String columns.
    Each panel is titled with its group, its y axis labelled with the unit (or "value (no
    unit in the log)"), the figure titled with the scenario."""
    log_path, out_dir = Path(log_path), Path(out_dir)
    cols, meta = read_log(log_path)
    kinds, units = _kinds(log_path)
    text = [n for n, k in kinds.items() if k == "text"]
    drawn = [n for n in cols if kinds.get(n) != "text"]
    mags = {n: _magnitude(np.asarray(cols[n], dtype=float)) for n in drawn if n != "time"}
    groups = signal_groups(drawn, units, mags)
    t = np.asarray(cols["time"], dtype=float)
    name = meta.get("scenario_name") or log_path.parent.name
    paths = []
    for fig_i in range(0, len(groups), PANELS_PER_FIGURE):
        chunk = groups[fig_i:fig_i + PANELS_PER_FIGURE]
        fig, axes = plt.subplots(len(chunk), 1, figsize=(9, 2.2 * len(chunk) + 0.9), dpi=100,
                                 sharex=True, squeeze=False, layout="constrained")
        for ax, (title, unit, names) in zip(axes[:, 0], chunk):
            for n in names:
                y = np.asarray(cols[n], dtype=float)
                style = "steps-post" if kinds.get(n) == "step" else "default"
                ax.plot(t, y, lw=1.0, drawstyle=style, label=n.split(".", 1)[-1])
            ax.set_title(title, fontsize=9, loc="left")
            ax.set_ylabel(f"value ({unit})" if unit else "value\n(no unit in the log)", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
        axes[-1, 0].set_xlabel("time (s)")
        n = fig_i // PANELS_PER_FIGURE
        pages = -(-len(groups) // PANELS_PER_FIGURE)
        fig.suptitle(f"Logged signals of {name}"
                     + (f" ({n + 1}/{pages})" if pages > 1 else ""), fontsize=11)
        path = out_dir / (f"{stem}.png" if n == 0 else f"{stem}_{n + 1}.png")
        fig.savefig(path)
        plt.close(fig)
        paths.append(path)
    return paths, text
