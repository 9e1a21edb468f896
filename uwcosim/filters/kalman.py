"""Kalman-family filters on a :class:`~uwcosim.filters.base.StateSpaceModel`.

:class:`ExtendedKalmanFilter` linearizes with the model's exact CasADi Jacobians; on a linear
model it is the Kalman filter. Updates use the Joseph form and Cholesky solves.
"""

from __future__ import annotations

import numpy as np

from uwcosim.filters.base import Estimator, register, select
from uwcosim.filters.numerics import joseph_update, kalman_gain, nis, symmetrize


@register("ekf")
class ExtendedKalmanFilter(Estimator):
    """EKF: ``x = f(x, u)``, ``P = F P F' + Q``; update with ``H = dh/dx`` at the prior mean.

    ``measurements``: optional list of measurement names the filter uses (default: all).
    """

    def __init__(self, model, x0, P0, measurements: list[str] | None = None) -> None:
        super().__init__(model, x0, P0)
        names = model.measurement_names
        if measurements is None:
            self._use = np.ones(model.nz, dtype=bool)
        else:
            unknown = [m for m in measurements if m not in names]
            if unknown:
                raise ValueError(
                    f"unknown measurements {unknown} (valid: {', '.join(names)})"
                )
            self._use = np.array([n in measurements for n in names])

    def predict(self, u, dt: float) -> None:
        F, G = self.model.FG(self.x, u, dt)
        Q = (G * (self.model.q_psd / dt)) @ G.T  # Q = G diag(psd/dt) G'
        self.x = self.model.f(self.x, u, dt)  # x = f(x, u)
        self.P = symmetrize(F @ self.P @ F.T + Q)  # P = F P F' + Q

    def update(self, z, mask=None) -> None:
        self.diagnostics = {}
        if z is not None:
            mask = self._use if mask is None else (np.asarray(mask, bool) & self._use)
        idx = select(z, mask, self.model.nz)
        if idx is None:
            return
        z = np.asarray(z, dtype=float)
        H = self.model.H(self.x)[idx]
        R = self.model.R[np.ix_(idx, idx)]
        y = z[idx] - self.model.h(self.x)[idx]  # y = z - h(x)
        PHt = self.P @ H.T
        S = H @ PHt + R  # S = H P H' + R
        K, cho = kalman_gain(PHt, S, self.diagnostics)  # K = P H' S^-1
        self.x = self.x + K @ y
        self.P = joseph_update(self.P, K, H, R)
        self.diagnostics["nis"] = nis(y, cho)
        self.diagnostics["nis_dof"] = float(idx.size)


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
