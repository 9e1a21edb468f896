"""Labels of the figures: display names of estimators and states, units, plain tick labels.

One place for what a reader sees, so that every figure (PNG and interactive) names a filter the
same way: :func:`display_name` turns a log name (``dead_reckoning``, ``pfm_psi``, ``pf_1000``)
into ``Dead reckoning``, ``PFM-PSI``, ``PF 1000``. The log's column names stay as they are; so
do the result tables' (``report.md``, ``table.md``, the HTML tables): there the name is the key
a user types in a scenario and reads in ``summary.json``. :func:`plain_log_ticks` gives a log
axis labels such as ``60`` or ``0.5`` instead of matplotlib's ``6x10^1``.
"""

from __future__ import annotations

from typing import Any

from uwcosim.models.states import position_velocity_indices

#: names of the estimator types as the papers write them
_KNOWN = {"dead_reckoning": "Dead reckoning", "point_mass": "Point mass", "pfm_psi": "PFM-PSI",
          "pmf": "PMF", "byo": "BYO"}
#: parts of a name written in capitals (filter acronyms)
_ACRONYMS = {"kf", "ekf", "ukf", "ckf", "cukf", "pf", "rpf", "rbpf", "qivbf", "vbakf", "vb",
             "vbf", "pmf", "psi", "pfm", "imm", "srukf", "sckf", "iekf", "gsf", "dr", "tan"}


def display_name(name: str) -> str:
    """The name of an estimator as a figure shows it: known names as the papers write them,
    filter acronyms in capitals, underscores as spaces, the first word capitalised."""
    if name in _KNOWN:
        return _KNOWN[name]
    words = [w for w in name.replace("-", "_").split("_") if w]
    if not words:
        return name
    for known, shown in _KNOWN.items():  # "pfm_psi_fast": "PFM-PSI fast"
        parts = known.split("_")
        if [w.lower() for w in words[:len(parts)]] == parts:
            return " ".join([shown, *(_word(w, False) for w in words[len(parts):])])
    return " ".join(_word(w, i == 0) for i, w in enumerate(words))


def _word(w: str, first: bool) -> str:
    if w.lower() in _ACRONYMS:
        return w.upper()
    return w[:1].upper() + w[1:] if first and w.islower() else w


def state_unit(state: str, states: list[str] | tuple[str, ...]) -> str:
    """The unit of one of the filters' states: metres for the position, metres per second for
    the velocity (:func:`~uwcosim.models.states.position_velocity_indices`), radians for a
    heading ``psi``; an empty string when unknown."""
    pos, vel = position_velocity_indices(list(states))
    i = list(states).index(state)
    if i in pos:
        return "m"
    if i in vel:
        return "m/s"
    return "rad" if state in ("psi", "heading", "yaw") else ""


def with_unit(label: str, unit: str) -> str:
    """``label (unit)``, or ``label`` alone without a unit."""
    return f"{label} ({unit})" if unit else label


def plain_number(v: float, _pos: Any = None) -> str:
    """A tick label without a power of ten: ``60``, ``0.5``, ``20000``."""
    return f"{v:.6g}" if abs(v) < 1e6 else f"{v:.3g}"


def plain_log_ticks(axis: Any) -> None:
    """Plain labels on a log ``axis`` (``ax.yaxis``), to be called once its limits are set: the
    decades always, 2 and 5 between them when the axis spans less than two decades, every
    integer multiple when it spans less than a factor 4, nothing between decades otherwise."""
    import matplotlib.ticker as mt  # not at import: the result table needs no matplotlib

    axis.set_major_formatter(mt.FuncFormatter(plain_number))
    lo, hi = sorted(axis.get_view_interval())
    if lo > 0 and hi / lo < 100.0:
        subs = tuple(range(2, 10)) if hi / lo < 4.0 else (2.0, 5.0)
        axis.set_minor_locator(mt.LogLocator(base=10.0, subs=subs))
        axis.set_minor_formatter(mt.FuncFormatter(plain_number))
    else:
        axis.set_minor_formatter(mt.NullFormatter())
