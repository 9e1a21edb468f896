"""Compare a run's log with a baseline log, signal by signal, inside tolerance tubes.

As in fmpy's ``validate_signal`` and the Modelica ``csv-compare`` tool, each baseline signal
``y_ref(t)`` (piecewise linear between its samples) is given a tube: at a time ``t`` the band
is the range of ``y_ref`` over ``[t - ttol, t + ttol]``, widened by the value tolerance
``tol = atol + rtol * max|y_ref|`` (relative to the signal's magnitude, so a signal crossing
zero is not held to a tighter absolute band there). A run sample outside its band is a
deviation. NaN (a lost measurement, a diverged filter) must be NaN in the baseline too (within
the time tolerance); boolean columns (flags) are compared exactly (within the time tolerance).

Why ``rtol = 1e-6``, ``atol = 1e-9`` by default: the same scenario and seed on one machine give
bit-identical logs (tests/test_master.py), so any band only has to absorb what changes between
machines: the last bits of libm, BLAS (small 4x4 solves) and compiler contractions (FMA) in the
FMUs, about 1e-16 relative per operation. The filters are stable, so these stay small over a
few hundred steps: perturbing the initial position by 1e-13 relative and a sensor sigma by one
ulp moves every signal of the shipped scenarios' 300 s runs by at most 7e-11 of its magnitude
(the point-mass filter's NEES in tan_terrain: 7e-5 of its tolerance; docs/regression.md).
1e-6 leaves four orders of margin above that and is still far below any deliberate change to
a model or a filter (1e-4 and more). ``atol`` only covers signals that are exactly zero in
the baseline.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from uwcosim.core.errors import RegressionInputError, UwcosimError
from uwcosim.regress.plots import diff_plot
from uwcosim.runlog import read_log

DEFAULT_RTOL = 1e-6
DEFAULT_ATOL = 1e-9
DEFAULT_TTOL = 0.0


@dataclass
class SignalResult:
    """The comparison of one signal: ``n_out`` samples outside the tube."""

    name: str
    n: int
    n_out: int
    tol: float
    max_dev: float  # largest |run - baseline| (interpolated at the run's times)
    t_max_dev: float
    note: str = ""
    band_dev: float = 0.0  # largest distance outside the tube's band before ``tol`` is added

    @property
    def ok(self) -> bool:
        return self.n_out == 0 and not self.note


@dataclass
class RegressionReport:
    """All signals of one comparison; ``ok`` when every signal passes and the time ranges
    agree."""

    run: Path
    baseline: Path
    rtol: float
    atol: float
    ttol: float
    results: list[SignalResult] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)  # in the baseline, not in the run
    extra: list[str] = field(default_factory=list)  # in the run, not in the baseline (ignored)
    time_problem: str = ""
    warnings: list[str] = field(default_factory=list)  # e.g. the scenario hashes differ
    n_samples: int = 0
    t_range: tuple[float, float] = (0.0, 0.0)
    plots: list[Path] = field(default_factory=list)

    @property
    def failures(self) -> list[SignalResult]:
        return [r for r in self.results if not r.ok]

    @property
    def ok(self) -> bool:
        return not self.failures and not self.missing and not self.time_problem

    def text(self) -> str:
        lines = [f"regress {self.run} against {self.baseline}",
                 f"  {self.n_samples} samples, t = {self.t_range[0]:g} .. {self.t_range[1]:g} "
                 f"s; {len(self.results)} signals (rtol {self.rtol:g}, atol {self.atol:g}, "
                 f"ttol {self.ttol:g} s)"]
        lines += [f"  warning: {w}" for w in self.warnings]
        if self.time_problem:
            lines.append(f"  FAILED time: {self.time_problem}")
        for name in self.missing:
            lines.append(f"  FAILED {name}: in the baseline, not in the run")
        if self.extra:
            shown = ", ".join(self.extra[:6]) + (", ..." if len(self.extra) > 6 else "")
            lines.append(f"  note: {len(self.extra)} signals of the run are not in the baseline "
                         f"(not compared): {shown}")
        for r in self.failures:
            what = r.note or f"{r.n_out} of {r.n} samples outside the tube"
            lines.append(f"  FAILED {r.name}: {what}; largest deviation {r.max_dev:.3g} at "
                         f"t={r.t_max_dev:g} (tolerance {r.tol:.3g})")
        n_bad = len(self.failures) + len(self.missing) + bool(self.time_problem)
        if self.ok:
            # the margin is how far outside the tube's band (before the value tolerance) a
            # sample came, as a fraction of that tolerance: a step inside the time tolerance
            # is 0, not its height
            worst = max(self.results, key=lambda r: r.band_dev / r.tol if r.tol else 0.0,
                        default=None)
            margin = ""
            if worst is not None and worst.tol and worst.band_dev > 0:
                margin = (f"; closest: {worst.name}, {worst.band_dev:.3g} outside its band = "
                          f"{worst.band_dev / worst.tol:.2g} of its tolerance")
            elif all(r.max_dev == 0 for r in self.results):
                margin = " (identical values)"
            lines.append(f"  result: all {len(self.results)} signals pass{margin}")
        else:
            lines.append(f"  result: FAILED ({n_bad} problem{'s' if n_bad > 1 else ''})")
        if self.plots:
            lines.append(f"  diff plots: {self.plots[0].parent}")
        return "\n".join(lines)


def log_file(path: str | Path, what: str = "run log") -> Path:
    """``log.parquet`` of a run directory, or the file itself (``what`` names it in errors)."""
    p = Path(path)
    if p.is_dir():
        p = p / "log.parquet"
    if not p.is_file():
        raise RegressionInputError(f"{p}: {what} not found")
    return p


def check_tolerances(rtol: float, atol: float, ttol: float) -> None:
    """Refuse a NaN, infinite or negative tolerance: a NaN band would let anything pass."""
    for name, v in (("rtol", rtol), ("atol", atol), ("ttol", ttol)):
        if not (np.isfinite(v) and v >= 0):
            raise RegressionInputError(f"--{name} {v}: a tolerance must be a finite number >= 0")


def read_columns(path: Path) -> tuple[dict[str, np.ndarray], dict]:
    """The log's columns and metadata, or a one-line RegressionInputError."""
    try:
        cols, meta = read_log(path)
    except UwcosimError as exc:
        raise RegressionInputError(str(exc)) from None
    if "time" not in cols:
        raise RegressionInputError(f"{path}: no 'time' column (not a uwcosim run log)")
    t = np.asarray(cols["time"], float)
    if t.size == 0:
        raise RegressionInputError(f"{path}: the log has no rows")
    for name, v in cols.items():
        kind = np.asarray(v).dtype.kind
        if kind not in "fiub":
            raise RegressionInputError(f"{path}: column {name!r} is not numeric or boolean "
                                       f"(dtype {np.asarray(v).dtype}); not a uwcosim run log")
    if np.any(np.diff(t) < 0) or not np.all(np.isfinite(t)):
        raise RegressionInputError(f"{path}: 'time' is not finite and non-decreasing")
    return cols, meta


def _windows(t_ref: np.ndarray, t: np.ndarray, ttol: float) -> tuple[np.ndarray, np.ndarray]:
    """Index ranges ``[a, b)`` of the reference samples within ``ttol`` of each ``t``,
    always including the nearest sample."""
    eps = 1e-9 * max(1.0, float(np.max(np.abs(t_ref))))
    a = np.searchsorted(t_ref, t - ttol - eps, side="left")
    b = np.searchsorted(t_ref, t + ttol + eps, side="right")
    j = np.clip(np.searchsorted(t_ref, t), 1, t_ref.size - 1) if t_ref.size > 1 else \
        np.zeros(t.size, dtype=int)
    near = j if t_ref.size == 1 else np.where(np.abs(t_ref[j] - t) < np.abs(t_ref[j - 1] - t),
                                              j, j - 1)
    return np.minimum(a, near), np.maximum(b, near + 1)


def tube(t_ref: np.ndarray, y_ref: np.ndarray, t: np.ndarray, ttol: float
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The band ``[lo, hi]`` of the reference at times ``t`` (NaN ignored), and whether the
    reference has a NaN / a finite value there: ``(lo, hi, has_nan, has_finite)``."""
    y_ref = np.asarray(y_ref, float)
    a, b = _windows(t_ref, t, ttol)
    lo = np.full(t.size, np.nan)
    hi = np.full(t.size, np.nan)
    has_nan = np.zeros(t.size, bool)
    for off in range(int(np.max(b - a)) if t.size else 0):
        idx = a + off
        valid = idx < b
        vals = np.where(valid, y_ref[np.minimum(idx, y_ref.size - 1)], np.nan)
        lo, hi = np.fmin(lo, vals), np.fmax(hi, vals)
        has_nan |= valid & np.isnan(vals)
    finite = np.isfinite(y_ref)
    if finite.sum() >= 2:  # the piecewise-linear reference at the window's ends (and at t)
        for s in ((-ttol, ttol) if ttol > 0 else (0.0,)):
            v = np.interp(t + s, t_ref, y_ref)  # NaN next to a NaN sample: ignored by fmin
            lo, hi = np.fmin(lo, v), np.fmax(hi, v)
    return lo, hi, has_nan, np.isfinite(lo)


def compare_signal(name: str, t_ref, y_ref, t, y, rtol: float, atol: float,
                   ttol: float) -> tuple[SignalResult, dict]:
    """Compare one signal; also returns the arrays a diff plot needs."""
    boolean = y.dtype == bool or y_ref.dtype == bool
    yr = np.asarray(y_ref, float)
    yy = np.asarray(y, float)
    finite_ref = yr[np.isfinite(yr)]
    scale = float(np.max(np.abs(finite_ref))) if finite_ref.size else 0.0
    tol = 0.0 if boolean else atol + rtol * scale
    lo, hi, has_nan, has_finite = tube(t_ref, yr, t, ttol)
    nan = np.isnan(yy)
    out = (nan & ~has_nan) | (~nan & ~has_finite)
    inside = ~nan & has_finite
    # written so that any NaN (in the band or the tolerance) fails: a comparison with NaN is
    # False, so "not inside" is True
    y_in = yy[inside]
    out[inside] |= ~((y_in >= lo[inside] - tol) & (y_in <= hi[inside] + tol))
    ref_at = np.interp(t, t_ref, yr) if yr.size > 1 else np.full(t.size, yr[0])
    near_nan = np.isnan(ref_at)
    ref_at[near_nan] = (lo[near_nan] + hi[near_nan]) / 2
    dev = np.abs(yy - ref_at)
    dev[nan | ~np.isfinite(dev)] = 0.0
    dev[out & ~inside] = np.inf  # NaN where the baseline has a value, or the reverse
    pick = np.where(out, dev, -1.0) if out.any() else dev
    i = int(np.argmax(pick)) if t.size else 0
    note = ""
    if (out & ~inside).any() or (out & nan).any():
        k = int(np.argmax(out & (nan | ~inside)))
        note = f"NaN pattern differs from the baseline (first at t={t[k]:g})"
    outside = np.zeros(t.size)
    outside[inside] = np.maximum(np.maximum(lo[inside] - y_in, y_in - hi[inside]), 0.0)
    outside[~np.isfinite(outside)] = 0.0
    res = SignalResult(name, int(t.size), int(out.sum()), tol, float(dev[i]) if t.size else 0.0,
                       float(t[i]) if t.size else 0.0, note,
                       float(outside.max()) if t.size else 0.0)
    return res, {"t": t, "y": yy, "t_ref": t_ref, "y_ref": yr, "lo": lo - tol, "hi": hi + tol,
                 "out": out}


def select_signals(names: list[str], patterns: list[str] | None) -> list[str]:
    if not patterns:
        return [n for n in names if n != "time"]
    return [n for n in names if n != "time" and any(fnmatch.fnmatch(n, p) for p in patterns)]


def compare_logs(run: str | Path, baseline: str | Path, rtol: float = DEFAULT_RTOL,
                 atol: float = DEFAULT_ATOL, ttol: float = DEFAULT_TTOL,
                 signals: list[str] | None = None, plot_dir: str | Path | None = None,
                 allow_shorter: bool = False) -> RegressionReport:
    """Compare the run log ``run`` (file or run directory) with ``baseline``.

    The two must cover the same time span (within ``ttol``): a shorter run fails, and so does
    a shorter baseline (a one-row baseline would otherwise vouch for a whole run) unless
    ``allow_shorter``, which compares the common span and says so in a warning line.
    Raises :class:`RegressionInputError` for bad input; returns the report otherwise, and
    writes one diff plot per failing signal into ``plot_dir`` when given.
    """
    check_tolerances(rtol, atol, ttol)
    run_p, base_p = log_file(run), log_file(baseline, "baseline")
    cols, meta = read_columns(run_p)
    ref, ref_meta = read_columns(base_p)
    wanted = select_signals(list(ref), signals)
    common = [n for n in wanted if n in cols]
    if not common:
        what = f"matching {', '.join(signals)} " if signals else ""
        raise RegressionInputError(f"{run_p}: no signals {what}in common with {base_p}")
    t, t_ref = np.asarray(cols["time"], float), np.asarray(ref["time"], float)
    lo, hi = max(t[0], t_ref[0]), min(t[-1], t_ref[-1])
    if lo > hi + ttol:
        raise RegressionInputError(f"{run_p}: time range {t[0]:g} .. {t[-1]:g} s does not "
                                   f"overlap the baseline's {t_ref[0]:g} .. {t_ref[-1]:g} s")
    rep = RegressionReport(run_p, base_p, rtol, atol, ttol,
                           missing=[n for n in wanted if n not in cols],
                           extra=[n for n in select_signals(list(cols), signals)
                                  if n not in ref])
    h_run, h_ref = meta.get("scenario_sha256"), ref_meta.get("scenario_sha256")
    if h_run and h_ref and h_run != h_ref:
        rep.warnings.append(f"the run's scenario (sha256 {h_run[:12]}, "
                            f"{meta.get('scenario_path', '?')}) differs from the baseline's "
                            f"({h_ref[:12]}, {ref_meta.get('scenario_path', '?')})")
    eps = ttol + 1e-9 * max(1.0, abs(t_ref[-1]))
    run_short = t[0] > t_ref[0] + eps or t[-1] < t_ref[-1] - eps
    base_short = t_ref[0] > t[0] + eps or t_ref[-1] < t[-1] - eps
    if base_short and allow_shorter and not run_short:
        rep.warnings.append(f"the baseline covers only t = {t_ref[0]:g} .. {t_ref[-1]:g} s of "
                            f"the run's {t[0]:g} .. {t[-1]:g} s (--allow-shorter): the rest "
                            f"of the run is not compared")
    elif run_short or base_short:
        rep.time_problem = (f"the run covers t = {t[0]:g} .. {t[-1]:g} s, the baseline "
                            f"{t_ref[0]:g} .. {t_ref[-1]:g} s")
    keep = (t >= lo - ttol) & (t <= hi + ttol)
    rep.n_samples, rep.t_range = int(keep.sum()), (float(lo), float(hi))
    data = {}
    for name in common:
        res, arrays = compare_signal(name, t_ref, np.asarray(ref[name]), t[keep],
                                     np.asarray(cols[name])[keep], rtol, atol, ttol)
        rep.results.append(res)
        data[name] = arrays
    if plot_dir is not None and rep.failures:
        out = Path(plot_dir)
        try:
            out.mkdir(parents=True, exist_ok=True)
            rep.plots = [diff_plot(r, data[r.name], out) for r in rep.failures]
        except OSError as exc:
            raise RegressionInputError(f"{out}: cannot write the diff plots "
                                       f"({exc.strerror or exc}); use --plots DIR or --no-plots"
                                       ) from None
    return rep
