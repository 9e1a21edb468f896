"""Kalman-family filters on a :class:`~uwcosim.filters.base.StateSpaceModel`.

They share :class:`~uwcosim.filters.base.FilterBase` with the other filters of the package.

:class:`KalmanFilter` (``kf``) needs a linear model (``model.linear``);
:class:`ExtendedKalmanFilter` (``ekf``) linearizes with the model's exact Jacobians (on a linear
model it is the Kalman filter).
Updates use the Joseph form and Cholesky solves.

The 4-state TAN filters are bound by numpy's per-call overhead (about 0.5-1 us per operation
on these small matrices), so the steps keep the number of numpy calls low: ``np.dot`` on
2-D arrays, the symmetrization in place, the identity kept, the gain and the NIS from one
LAPACK solve, no fancy indexing when every measurement component is used.
"""

from __future__ import annotations

import numpy as np

from uwcosim.filters.base import FilterBase, register
from uwcosim.filters.gating import GateProbability, gate_field
from uwcosim.filters.numerics import (
    gain_and_nis,
    joseph_update,
    linearize,
    symmetrize_,
)
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field


@register("ekf")
class ExtendedKalmanFilter(FilterBase):
    """EKF: ``x = f(x, u)``, ``P = F P F' + Q``; update with ``H = dh/dx`` at the prior mean."""

    class Settings(FilterSettings):
        measurements: Measurements = measurements_field()
        gate_probability: GateProbability = gate_field()  # filters.gating

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        self._eye = np.eye(model.nx)

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        F, Q = linearize(self.model, self.x, u, dt)
        self.x = self.model.f(self.x, u, dt)  # x = f(x, u)
        P = np.dot(np.dot(F, self.P), F.T)
        P += Q
        self.P = symmetrize_(P)  # P = F P F' + Q
        self._check("prediction")

    def update(self, z, mask=None) -> None:
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        z = np.asarray(z, dtype=float)
        model, x = self.model, self.x
        H, hx = model.H(x), model.h(x)
        if idx.size == hx.size:  # every component
            y = z - hx  # y = z - h(x)
        else:
            H, y = H[idx], z[idx] - hx[idx]
        R = self._R(idx)
        PHt = np.dot(self.P, H.T)
        S = np.dot(H, PHt)
        S += R  # S = H P H' + R
        K, self.diagnostics["nis"] = gain_and_nis(PHt, S, y, self.diagnostics)  # K = P H' S^-1
        self.x = x + np.dot(K, y)  # x = x + K y
        self.P = joseph_update(self.P, K, H, R, self._eye)  # P = (I-KH) P (I-KH)' + K R K'
        self.diagnostics["nis_dof"] = float(idx.size)
        self._check("update")


@register("kf")
class KalmanFilter(ExtendedKalmanFilter):
    """The Kalman filter of a linear model (``model.linear``): ``F``, ``H`` are matrices.

    Same equations as :class:`ExtendedKalmanFilter`, which on a linear model is exact; the
    separate name refuses nonlinear models instead of silently linearizing them.
    """

    def __init__(self, model, x0, P0, **settings) -> None:
        if not getattr(model, "linear", False):
            raise ValueError(
                "estimator 'kf' needs a linear model (model.linear); use 'ekf', 'ukf' or 'ckf'"
            )
        super().__init__(model, x0, P0, **settings)


@register("dead_reckoning")
class DeadReckoning(ExtendedKalmanFilter):
    """DVL dead reckoning: integrates the measured velocities, ignores every other sensor.

    Written as the Kalman filter whose only measurements are the velocity components
    (names ending in ``vx_m``/``vy_m``), so its covariance shows the unbounded position drift.
    """

    class Settings(FilterSettings):
        measurements: Measurements = measurements_field(
            "measurement components to integrate (default: the velocities)")

    def measurements_used(self) -> list[str]:
        """The ``measurements`` setting, by default the velocity components."""
        names = self.settings.measurements
        if names is None:
            names = [n for n in self.model.measurement_names if n.endswith(("vx_m", "vy_m"))]
        return names
