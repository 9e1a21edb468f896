"""A chi-square innovation gate for the Kalman family: :func:`gate` and its setting.

A measurement component ``i`` is rejected as an outlier when its normalized innovation

    d_i = (z_i - h_i(x))^2 / S_ii,      S = H P H' + R      (H = dh/dx at the prior mean x)

exceeds the ``gate_probability`` quantile of the chi-square distribution with one degree of
freedom (0.9999: d > 15.1, a 3.9-sigma innovation); the filter then updates with the
components that pass, as if the others were lost. Components are gated one by one, so an
outlier of the depth sounder does not take the DVL's velocities with it. Every Kalman-family
filter (``kf``, ``ekf``, ``ukf``, ``ckf``, ``cukf``) gates on this linearized ``S`` at its
prior mean (for a sigma-point filter it is the EKF's ``S``, not its own ``Pzz + R``: the gate
is a test of the prior, evaluated before the update it guards); the variational-Bayes filters
(``vbakf``, ``qivbf``) on ``S`` with their current estimate ``E[R]`` in place of ``R``. Off by
default (``gate_probability`` unset): no filter's results change.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field, StrictFloat
from scipy.special import chdtri

from uwcosim.models.protocol import StateSpaceModel

GATE = ("chi-square innovation gate: reject a measurement component whose normalized "
        "innovation exceeds this quantile of chi2(1), e.g. 0.9999 (default: no gate)")


#: the type of the ``gate_probability`` setting
GateProbability = StrictFloat | None


def gate_field() -> Any:
    """The ``gate_probability`` setting of a Kalman-family filter (default: no gate)."""
    return Field(None, gt=0, lt=1, description=GATE)


def gate_threshold(probability: float) -> float:
    """The chi2(1) quantile of ``probability``: the largest accepted normalized innovation."""
    return float(chdtri(1, 1.0 - probability))  # chi2(1).ppf(p), without scipy.stats' import


def gate(model: StateSpaceModel, x: np.ndarray, P: np.ndarray, z: np.ndarray,
         idx: np.ndarray, threshold: float,
         r: np.ndarray | None = None) -> tuple[np.ndarray | None, int]:
    """The components of ``idx`` that pass the gate (None if none) and how many were
    rejected. ``r``: the noise variances ``R_ii`` of the components ``idx`` (default: the
    model's; the VB filters pass their estimate ``E[R]``)."""
    H = np.asarray(model.H(x))[idx]
    y = np.asarray(z, dtype=float)[idx] - np.asarray(model.h(x))[idx]  # y = z - h(x)
    if r is None:
        r = np.diag(model.R)[idx]
    S = np.einsum("ij,jk,ik->i", H, P, H) + r  # S_ii = (H P H')_ii + R_ii
    keep = y * y <= threshold * S  # d_i = y_i^2 / S_ii <= threshold
    n_rejected = int(idx.size - np.count_nonzero(keep))
    if n_rejected == 0:
        return idx, 0
    kept = idx[keep]
    return (kept if kept.size else None), n_rejected
