"""Kalman-family filters on a :class:`~uwcosim.filters.base.StateSpaceModel`.

:class:`FilterBase` holds what every filter of the package shares: the ``measurements`` setting
(the subset of measurement names a filter uses), per-step diagnostics (reset when a step begins,
i.e. at ``predict``, or at ``update`` when no ``predict`` came before it; ``pd_repairs`` always,
``nis``/``nis_dof`` after an update with data, plus each filter's own), finiteness checks that
raise :class:`~uwcosim.errors.FilterDivergence`. A filter uses the model it is given: which
implementation that is (CasADi, or the closed-form TAN model) is chosen where the model is built
(:mod:`uwcosim.models.factory`).

:class:`KalmanFilter` (``kf``) needs a linear model (``model.linear``);
:class:`ExtendedKalmanFilter` (``ekf``) linearizes with the model's exact Jacobians (on a linear
model it is the Kalman filter).
Updates use the Joseph form and Cholesky solves.
"""

from __future__ import annotations

import numpy as np

from uwcosim.filters.base import Estimator, register, select
from uwcosim.filters.numerics import (
    check_finite,
    joseph_update,
    kalman_gain,
    linearize,
    nis,
    symmetrize,
)


def measurement_use(model, measurements: list[str] | None) -> np.ndarray:
    """Boolean mask of the measurement components a filter uses (default: all)."""
    names = model.measurement_names
    if measurements is None:
        return np.ones(model.nz, dtype=bool)
    unknown = [m for m in measurements if m not in names]
    if unknown:
        raise ValueError(f"unknown measurements {unknown} (valid: {', '.join(names)})")
    return np.array([n in measurements for n in names])


class FilterBase(Estimator):
    """Shared plumbing: measurement subset, step diagnostics, divergence checks."""

    def __init__(self, model, x0, P0, measurements: list[str] | None = None) -> None:
        super().__init__(model, x0, P0)
        self._use = measurement_use(model, measurements)
        self._predicted = False
        self._R_blocks: dict[bytes, np.ndarray] = {}
        check_finite("initial state or covariance", self.x, self.P)

    def _begin_predict(self) -> None:
        self.diagnostics = {"pd_repairs": 0.0}
        self._predicted = True

    def _begin_update(self, z, mask) -> np.ndarray | None:
        """Start the update half of a step; the indices of the usable components (or None)."""
        if not self._predicted:
            self.diagnostics = {"pd_repairs": 0.0}
        self._predicted = False
        if z is None:
            return None
        mask = self._use if mask is None else (np.asarray(mask, dtype=bool) & self._use)
        return select(z, mask, self.model.nz)

    def _R(self, idx: np.ndarray) -> np.ndarray:
        """``R[idx, idx]`` (cached per set of components)."""
        key = idx.tobytes()
        R = self._R_blocks.get(key)
        if R is None:
            R = self._R_blocks[key] = self.model.R[np.ix_(idx, idx)]
        return R

    def _check(self, what: str) -> None:
        check_finite(f"{self.kind} {what}", self.x, self.P)


@register("ekf")
class ExtendedKalmanFilter(FilterBase):
    """EKF: ``x = f(x, u)``, ``P = F P F' + Q``; update with ``H = dh/dx`` at the prior mean.

    ``measurements``: optional list of measurement names the filter uses (default: all).
    """

    def __init__(self, model, x0, P0, measurements: list[str] | None = None) -> None:
        super().__init__(model, x0, P0, measurements)

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        F, Q = linearize(self.model, self.x, u, dt)
        self.x = self.model.f(self.x, u, dt)  # x = f(x, u)
        self.P = symmetrize(F @ self.P @ F.T + Q)  # P = F P F' + Q
        self._check("prediction")

    def update(self, z, mask=None) -> None:
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        z = np.asarray(z, dtype=float)
        H = self.model.H(self.x)[idx]
        R = self._R(idx)
        y = z[idx] - self.model.h(self.x)[idx]  # y = z - h(x)
        PHt = self.P @ H.T
        S = H @ PHt + R  # S = H P H' + R
        K, cho = kalman_gain(PHt, S, self.diagnostics)  # K = P H' S^-1
        self.x = self.x + K @ y  # x = x + K y
        self.P = joseph_update(self.P, K, H, R)  # P = (I-KH) P (I-KH)' + K R K'
        self.diagnostics["nis"] = nis(y, cho)
        self.diagnostics["nis_dof"] = float(idx.size)
        self._check("update")


@register("kf")
class KalmanFilter(ExtendedKalmanFilter):
    """The Kalman filter of a linear model (``model.linear``): ``F``, ``H`` are matrices.

    Same equations as :class:`ExtendedKalmanFilter`, which on a linear model is exact; the
    separate name refuses nonlinear models instead of silently linearizing them.
    """

    def __init__(self, model, x0, P0, measurements: list[str] | None = None) -> None:
        if not getattr(model, "linear", False):
            raise ValueError(
                "estimator 'kf' needs a linear model (model.linear); use 'ekf', 'ukf' or 'ckf'"
            )
        super().__init__(model, x0, P0, measurements)


@register("dead_reckoning")
class DeadReckoning(ExtendedKalmanFilter):
    """DVL dead reckoning: integrates the measured velocities, ignores every other sensor.

    Written as the Kalman filter whose only measurements are the velocity components
    (names ending in ``vx_m``/``vy_m``), so its covariance shows the unbounded position drift.
    """

    def __init__(self, model, x0, P0, measurements: list[str] | None = None) -> None:
        if measurements is None:
            measurements = [n for n in model.measurement_names if n.endswith(("vx_m", "vy_m"))]
        super().__init__(model, x0, P0, measurements=measurements)
