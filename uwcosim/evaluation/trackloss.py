"""Lost-track criterion of a terrain-navigation run: :func:`track_loss` (issue 25, section 4).

A filter has **lost the track** when its position error is, at once,

* above ``n_sigma`` (3) times its own position standard deviation, the radius
  ``sqrt(P_xx + P_yy)`` (the root of the trace of the position block; the log holds the
  variances, and the trace does not depend on the axes), and
* above ``min_error_m`` (50 m),

at every sample of an interval at least ``min_duration_s`` (60 s) long (first to last sample of
the interval). A filter that knows it is uncertain (large covariance during acquisition) has not
lost the track; one that is confident and wrong has. A diverged filter (no estimate any more, or
marked diverged by the master) counts as lost. Steps without a position reference (a replay's
sparse fixes) are left out by the caller (:mod:`uwcosim.evaluation.summary`), so an interval
spans the steps that have one. The statistic is per run: the track-loss rate of a
filter over a campaign is the fraction of its runs with ``track_lost``.
"""

from __future__ import annotations

import numpy as np

#: the default criterion: (n_sigma, min_error_m, min_duration_s)
CRITERION = (3.0, 50.0, 60.0)


def track_loss(t: np.ndarray, err: np.ndarray, var: np.ndarray, n_sigma: float = CRITERION[0],
               min_error_m: float = CRITERION[1],
               min_duration_s: float = CRITERION[2]) -> dict:
    """Whether a run lost the track, and when.

    ``t``: sample times ``(T,)``; ``err``: position errors ``(T, 2)``; ``var``: the filter's
    position variances ``(T, 2)``. A sample with a non-finite error or variance is a lost
    sample. Returns ``{"track_lost": bool}`` and, when lost, ``"track_lost_at_s"``: the start of
    the first interval that meets the criterion.
    """
    t = np.asarray(t, float)
    err = np.asarray(err, float)
    var = np.asarray(var, float)
    r = np.sqrt(np.sum(err**2, axis=1))  # |e|
    s = np.sqrt(np.sum(var, axis=1))  # sqrt(P_xx + P_yy)
    with np.errstate(invalid="ignore"):
        bad = ~(np.isfinite(r) & np.isfinite(s)) | ((r > n_sigma * s) & (r > min_error_m))
    start = None
    for k in range(t.size):
        if not bad[k]:
            start = None
            continue
        start = k if start is None else start
        if t[k] - t[start] >= min_duration_s:
            return {"track_lost": True, "track_lost_at_s": float(t[start])}
    return {"track_lost": False}
