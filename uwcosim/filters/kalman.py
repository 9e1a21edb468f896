"""Kalman-family filters on a :class:`~uwcosim.filters.base.StateSpaceModel`.

They share :class:`~uwcosim.filters.base.FilterBase` with the other filters of the package.

:class:`KalmanFilter` (``kf``) needs a linear model (``model.linear``);
:class:`ExtendedKalmanFilter` (``ekf``) linearizes with the model's exact Jacobians (on a linear
model it is the Kalman filter).
Updates use the Joseph form and Cholesky solves. Dead reckoning evaluates only the rows it
uses (no terrain lookup where the model offers ``h_rows``).

``compiled = true`` (every filter of this module and of :mod:`uwcosim.filters.sigma_point`)
runs the same equations compiled on the model's compiled form
(:mod:`uwcosim.filters.kalman_kernels`; the TAN and linear models offer one): two compiled
calls for ``predict`` and ``update``, one for a whole :meth:`~uwcosim.filters.base.Estimator.
step` (what the estimator bank calls), equal to the numpy step to round-off but not bit for bit
(BLAS groups the sums differently), hence off by default. With Numba off
(``UWCOSIM_NUMBA=0``) the numpy step runs. The compiled step updates ``x`` and ``P`` in place
(copy them to keep them).

The 4-state TAN filters are bound by numpy's per-call overhead (about 0.5-1 us per operation
on these small matrices), so the steps keep the number of numpy calls low: ``np.dot`` on
2-D arrays, the symmetrization in place, the identity kept, the gain and the NIS from one
LAPACK solve, no fancy indexing when every measurement component is used.
"""

from __future__ import annotations

from types import ModuleType
from typing import ClassVar

import numpy as np
from pydantic import Field, StrictBool

from uwcosim.filters import kalman_kernels
from uwcosim.filters.base import FilterBase, register
from uwcosim.filters.gating import GateProbability, gate_field
from uwcosim.filters.kalman_kernels import (
    BOOL,
    F8,
    NO_DATA,
    compiled_workspace,
    exact,
    raise_for_status,
)
from uwcosim.filters.numerics import (
    gain_and_nis,
    joseph_update,
    linearize,
    symmetrize_,
)
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field


def compiled_field():
    """The ``compiled`` setting of the Kalman family (off: the numpy step)."""
    return Field(False, description="run the compiled step on the model's compiled form "
                 "(TAN and linear models): equal to the numpy step to round-off, faster")


class CompiledUpdate:
    """The compiled halves and whole steps (a mixin of :class:`FilterBase` subclasses): the
    bookkeeping of ``FilterBase._begin_update`` and the diagnostics around one kernel call."""

    #: the kernel of a compiled whole step, by module and name (looked up at each call, so
    #: that the compiled kernel is reached once bound); None: ``predict``, then ``update``
    whole_step: ClassVar[tuple[ModuleType, str] | None] = None

    def step(self, u, dt: float, z, mask=None, t: float | None = None) -> None:
        w = self.workspace
        if w is None or self.whole_step is None:
            super().step(u, dt, z, mask, t)
            return
        module, name = self.whole_step
        self._compiled_step(getattr(module, name), w, u, dt, z, mask, t)  # predict, update

    def _compiled_update(self, kernel, w, z, mask, *extra) -> None:
        """``kernel(ws, table, x, P, z, mask, *extra) -> (status, nis, nis_dof, repairs)``."""
        if not self._predicted:
            self.diagnostics = {"pd_repairs": 0.0}
        self._predicted = False
        if z is None:
            return
        z = np.asarray(z, dtype=float)
        mask = w.everything if mask is None else np.asarray(mask, dtype=bool)
        args = (w.table, self.x, self.P, z, mask, *extra)
        if exact(self.x, F8, 1) and exact(self.P, F8, 2) and exact(z, F8, 1) and \
                exact(mask, BOOL, 1):
            status, nis, dof, repairs = w.call(kernel, *args)
        else:  # the dispatcher types (and checks) them
            status, nis, dof, repairs = kernel(w.ws, *args)
        d = self.diagnostics
        if repairs:
            d["pd_repairs"] += repairs
        if status == NO_DATA:
            return
        if status:
            raise_for_status(status, f"{self.kind} update")
        d["nis"] = nis
        d["nis_dof"] = dof

    def _compiled_step(self, kernel, w, u, dt, z, mask, t) -> None:
        """A whole step in one call: ``kernel(ws, table, u, dt, z, mask) -> (status, nis,
        nis_dof, repairs)`` on the workspace's ``x`` and ``P`` (``self.x``, ``self.P`` are
        their views; given new arrays, their values are copied in), the diagnostics of
        ``predict`` then ``update``."""
        if t is not None:
            self.t = t
        self._predicted = False
        if self.x is not w.x:  # the first step, or arrays set from outside
            w.x[:] = self.x
            self.x = w.x
        if self.P is not w.P:
            w.P[:] = self.P
            self.P = w.P
        if w.given:  # the model's transition is not compiled in: F, b, Q of the step first
            w.transition(u, float(dt), w.F, w.b, w.Q)
            u = w.nothing
        elif type(u) is not np.ndarray:
            u = np.asarray(u, dtype=float)
        if z is None:
            z, mask = w.nothing, w.everything  # NaN: no component available
        else:
            if type(z) is not np.ndarray:
                z = np.asarray(z, dtype=float)
            if mask is None:
                mask = w.everything
            elif type(mask) is not np.ndarray:
                mask = np.asarray(mask, dtype=bool)
        if (u is w.nothing or exact(u, F8, 1)) and (z is w.nothing or exact(z, F8, 1)) and \
                (mask is w.everything or exact(mask, BOOL, 1)):
            status, nis, dof, repairs = w.call(kernel, w.table, u, float(dt), z, mask)
        else:  # the dispatcher types (and checks) them
            status, nis, dof, repairs = kernel(w.ws, w.table, u, float(dt), z, mask)
        if status == 0:
            self.diagnostics = {"pd_repairs": repairs, "nis": nis, "nis_dof": dof}
            return
        self.diagnostics = {"pd_repairs": repairs}
        if status != NO_DATA:
            raise_for_status(status, f"{self.kind} update")


@register("ekf")
class ExtendedKalmanFilter(CompiledUpdate, FilterBase):
    """EKF: ``x = f(x, u)``, ``P = F P F' + Q``; update with ``H = dh/dx`` at the prior mean."""

    whole_step = (kalman_kernels, "ekf_step")

    class Settings(FilterSettings):
        measurements: Measurements = measurements_field()
        compiled: StrictBool = compiled_field()
        gate_probability: GateProbability = gate_field()  # filters.gating

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        self._eye = np.eye(model.nx)
        #: the compiled step's workspace (None: the numpy step)
        self.workspace = compiled_workspace(self, model, self._use)

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        w = self.workspace
        if w is not None:
            w.transition(u, float(dt), w.F, w.b, w.Q)  # F, b, Q of the step (the model's)
            kernel = kalman_kernels.ekf_predict  # x = F x + b, P = F P F' + Q
            if exact(self.x, F8, 1) and exact(self.P, F8, 2):
                status = w.call(kernel, self.x, self.P)
            else:  # the dispatcher types (and checks) them
                status = kernel(w.ws, self.x, self.P)
            if status:
                raise_for_status(status, f"{self.kind} prediction")
            return
        F, Q = linearize(self.model, self.x, u, dt)
        self.x = self.model.f(self.x, u, dt)  # x = f(x, u)
        P = np.dot(np.dot(F, self.P), F.T)
        P += Q
        self.P = symmetrize_(P)  # P = F P F' + Q
        self._check("prediction")

    def update(self, z, mask=None) -> None:
        if self.workspace is not None:
            self._compiled_update(kalman_kernels.ekf_update, self.workspace, z, mask)
            return
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        z = np.asarray(z, dtype=float)
        x = self.x
        H, y = self.innovation(z, idx)
        R = self._R(idx)
        PHt = np.dot(self.P, H.T)
        S = np.dot(H, PHt)
        S += R  # S = H P H' + R
        K, self.diagnostics["nis"] = gain_and_nis(PHt, S, y, self.diagnostics)  # K = P H' S^-1
        self.x = x + np.dot(K, y)  # x = x + K y
        self.P = joseph_update(self.P, K, H, R, self._eye)  # P = (I-KH) P (I-KH)' + K R K'
        self.diagnostics["nis_dof"] = float(idx.size)
        self._check("update")

    def innovation(self, z: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(H, y)`` of the components ``idx``: ``H = dh/dx`` and ``y = z - h(x)``."""
        model, x = self.model, self.x
        H, hx = model.H(x), model.h(x)
        if idx.size == hx.size:  # every component
            return H, z - hx  # y = z - h(x)
        return H[idx], z[idx] - hx[idx]


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
    On a terrain model that offers it (``model.without_terrain()``, the TAN model) and with the
    DVL rows as its measurements, it runs on that model and is given those rows of ``z``: no
    terrain ``h``/``H`` evaluated and dropped (the same numbers).
    """

    class Settings(FilterSettings):
        measurements: Measurements = measurements_field(
            "measurement components to integrate (default: the velocities)")
        compiled: StrictBool = compiled_field()

    def __init__(self, model, x0, P0, **settings) -> None:
        names = list(model.measurement_names)
        used = settings.get("measurements") or [n for n in names if n.endswith(("vx_m", "vy_m"))]
        narrow = getattr(model, "without_terrain", None)
        #: the rows of the full model's ``z`` this filter is given (None: all of them)
        self.rows = None
        if narrow is not None and getattr(model, "terrain", None) is not None and \
                [names.index(n) for n in used if n in names] == [0, 1] and len(used) == 2:
            model = narrow()
            self.rows = np.array([0, 1])
        super().__init__(model, x0, P0, **settings)

    def step(self, u, dt: float, z, mask=None, t: float | None = None) -> None:
        if self.workspace is None or self.rows is None:  # predict, then update (below)
            super().step(u, dt, z, mask, t)
            return
        z, mask = self._rows_of(z, mask)
        super().step(u, dt, z, mask, t)  # the compiled whole step: no update() of ours

    def update(self, z, mask=None) -> None:
        if self.rows is not None:
            z, mask = self._rows_of(z, mask)
        super().update(z, mask)

    def _rows_of(self, z, mask):
        """``z`` and ``mask`` of the rows this filter is given."""
        z = None if z is None else np.asarray(z, dtype=float)[self.rows]
        return z, None if mask is None else np.asarray(mask)[self.rows]

    def measurements_used(self) -> list[str]:
        """The ``measurements`` setting, by default the velocity components."""
        names = self.settings.measurements
        if names is None:
            names = [n for n in self.model.measurement_names if n.endswith(("vx_m", "vy_m"))]
        return names

    def innovation(self, z: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """As the EKF's, from only the rows used (``model.h_rows``: no terrain lookup for the
        velocity rows; the same numbers)."""
        rows = getattr(self.model, "h_rows", None)
        if rows is None or idx.size == self.model.nz:
            return super().innovation(z, idx)
        hx, H = rows(self.x, idx)
        return H, z[idx] - hx  # y = z - h(x)
