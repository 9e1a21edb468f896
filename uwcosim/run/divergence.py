"""When is an estimator diverged? Checks of one estimate, applied by the estimator bank after
every update (the filters themselves only raise :class:`~uwcosim.core.errors.FilterDivergence` when
they cannot go on).

An estimate ``(x, P)`` is diverged when

- ``x`` or ``P`` has a NaN or infinite entry;
- ``P`` is not symmetric within ``SYM_RTOL`` of its largest entry;
- ``P`` is not positive definite: the Cholesky factorization of its symmetric part fails and its
  smallest eigenvalue is below ``-PD_RTOL`` times its largest (round-off around a singular
  direction is tolerated);
- NIS or NEES is negative (only possible with a broken covariance);
- the position estimate leaves the bound: ``[estimation] position_bound`` (``[xmin, xmax,
  ymin, ymax]``, m) or, by default, the map's extent widened on each side by the map's larger
  side (so only estimates far off the map are flagged; no bound without a map).

The diverged estimator is stopped and flagged; the others go on.

:meth:`DivergenceCheck.assess` checks all estimators of a step at once, with their NEES, in
scalar code (:mod:`uwcosim.run.scan`: compiled when Numba is loaded): about fifteen numpy
calls per estimator and step were a fifth of a Table 1 run. Only an estimate that fails a
check there goes through the per-estimate path (:meth:`DivergenceCheck.__call__`), which words
the reason.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uwcosim.evaluation.metrics import nees as metrics_nees
from uwcosim.run.scan import SYM_RTOL, scan_estimates

PD_RTOL = 1e-9


def default_bound(extent: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The map's extent widened on each side by its larger side."""
    xmin, xmax, ymin, ymax = extent
    m = max(xmax - xmin, ymax - ymin)
    return (xmin - m, xmax + m, ymin - m, ymax + m)


def covariance_problem(P: np.ndarray) -> str:
    """Why ``P`` is not a covariance (empty string if it is one, within tolerance)."""
    if not np.all(np.isfinite(P)):
        return "covariance has NaN or infinite entries"
    scale = float(np.max(np.abs(P))) if P.size else 0.0
    if scale == 0.0:
        return "covariance is zero"
    asym = float(np.max(np.abs(P - P.T)))
    if asym > SYM_RTOL * scale:
        return f"covariance is not symmetric (|P - P'| = {asym:.3g}, max |P| = {scale:.3g})"
    S = 0.5 * (P + P.T)
    try:
        np.linalg.cholesky(S)
        return ""
    except np.linalg.LinAlgError:
        ev = np.linalg.eigvalsh(S)
        if ev[0] < -PD_RTOL * max(ev[-1], 0.0) or ev[-1] <= 0:
            return f"covariance is not positive definite (eigenvalues {ev[0]:.3g} .. {ev[-1]:.3g})"
        return ""


@dataclass(frozen=True)
class DivergenceCheck:
    """The checks of the module docstring for one model (``pos``: indices of x, y)."""

    pos: tuple[int, ...] = ()
    bound: tuple[float, float, float, float] | None = None

    def assess(self, X: np.ndarray, Ps: np.ndarray, E: np.ndarray,
               nis: np.ndarray) -> tuple[list[str], np.ndarray]:
        """Why each of ``k`` estimates is diverged (empty string if not) and its NEES.

        ``X`` ``(k, n)`` estimates, ``Ps`` ``(k, n, n)`` covariances, ``E`` ``(k, n)`` errors
        (truth minus estimate), ``nis`` ``(k,)`` (NaN when none). A healthy estimate's NEES is
        ``|L^-1 e|^2`` with ``L L' = (P + P')/2`` (:mod:`uwcosim.run.scan`); one that
        fails a check there is checked by :meth:`__call__`, with the reason, and if it is
        not diverged (e.g. ``P`` singular within round-off) its NEES is ``e' P^-1 e``
        (:func:`uwcosim.evaluation.metrics.nees`, which may be negative: flagged). NaN for a
        diverged estimate.
        """
        k = X.shape[0]
        nees = scan_estimates(X, Ps, E, nis, self.pos, self.bound)
        bad = np.isnan(nees)
        if not bad.any():
            return [""] * k, nees
        whys = []
        for i in range(k):
            if not bad[i]:
                whys.append("")
                continue
            n_i = float(metrics_nees(E[i][None], Ps[i][None])[0])
            why = self(X[i], Ps[i], float(nis[i]), n_i)
            whys.append(why)
            nees[i] = np.nan if why else n_i
        return whys, nees

    def __call__(self, x: np.ndarray, P: np.ndarray, nis: float, nees: float) -> str:
        """Why the estimate is diverged, or an empty string."""
        if not np.all(np.isfinite(x)):
            return "estimate has NaN or infinite entries"
        why = covariance_problem(np.asarray(P, dtype=float))
        if why:
            return why
        if nis < 0:
            return f"negative NIS ({nis:.3g})"
        if nees < 0:
            return f"negative NEES ({nees:.3g})"
        if self.bound is not None and len(self.pos) >= 2:
            px, py = float(x[self.pos[0]]), float(x[self.pos[1]])
            xmin, xmax, ymin, ymax = self.bound
            if not (xmin <= px <= xmax and ymin <= py <= ymax):
                return (f"position estimate ({px:.4g}, {py:.4g}) m outside the bound "
                        f"[{xmin:g}, {xmax:g}] x [{ymin:g}, {ymax:g}]")
        return ""

