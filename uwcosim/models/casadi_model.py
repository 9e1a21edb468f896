"""Discrete-time state-space models for the filters, built from CasADi expressions.

:class:`CasadiModel` turns a continuous ODE ``xdot = ode(x, u, w)`` (noise ``w`` held over a
step, as the master feeds the FMUs) and an output map ``z = h(x)`` into everything the filters
need: ``f`` (one RK4 step), the Jacobians ``F = df/dx`` and ``G = df/dw``, the discrete process
covariance ``Q = G diag(psd / dt) G'`` (a held white-noise sample of power spectral density
``psd`` has variance ``psd / dt``), ``H = dh/dx``, and batch versions for particle and sigma-point
filters (:class:`PointwiseMap`, on ``casadi.Function.map``). Functions are built once per model.

With ``control_psd`` (noise on the controls, held over the step, that the truth follows and the
filters know) ``Q`` adds ``J_u diag(control_psd / dt) J_u'`` with ``J_u = df/du`` at the state
and control of the call (first order in the control noise; ``Q`` then depends on the state).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from uwcosim.models.auv_equations import rk4_step


class PointwiseMap:
    """A CasADi function ``fn(x, *args)`` evaluated at many points ``x`` in one call
    (``casadi.Function.map``, built once per number of points)."""

    def __init__(self, fn: ca.Function) -> None:
        self.fn = fn
        self._maps: dict[int, ca.Function] = {}

    def __call__(self, X: np.ndarray, *args) -> np.ndarray:
        """``fn`` at the rows of ``X``: one column per point (CasADi's layout)."""
        n = X.shape[0]
        mapped = self._maps.get(n)
        if mapped is None:
            mapped = self._maps[n] = self.fn.map(n)
        return np.asarray(mapped(X.T, *args))


class CasadiModel:
    """A filter model from a CasADi ODE ``ode(x, u, w)`` and measurement ``h(x)``."""

    def __init__(
        self,
        ode: ca.Function,
        h: ca.Function,
        q_psd,
        R,
        state_names: tuple[str, ...],
        measurement_names: tuple[str, ...],
        substeps: int = 1,
        control_psd=None,
    ) -> None:
        self.ode = ode  # the continuous drift (projection filters use it)
        self.nx = int(ode.size1_in(0))
        self.nu = int(ode.size1_in(1))
        self.nw = int(ode.size1_in(2))
        self.nz = int(h.size1_out(0))
        self.state_names = tuple(state_names)
        self.measurement_names = tuple(measurement_names)
        self.q_psd = np.asarray(q_psd, dtype=float).reshape(self.nw)
        R = np.asarray(R, dtype=float)
        self.R = np.diag(R) if R.ndim == 1 else R
        if self.R.shape != (self.nz, self.nz):
            raise ValueError(f"R must be {self.nz}x{self.nz}, got {self.R.shape}")
        step = rk4_step(ode, substeps)
        x = ca.MX.sym("x", self.nx)
        u = ca.MX.sym("u", self.nu)
        w = ca.MX.sym("w", self.nw)
        dt = ca.MX.sym("dt")
        xf = step(x, u, w, dt)
        w0 = ca.DM.zeros(self.nw)
        # SX-expanded: the ODE is pure arithmetic, so expansion makes calls several times faster
        self.f_fn = ca.Function("f", [x, u, dt], [step(x, u, w0, dt)]).expand()
        self.FG_fn = ca.Function(
            "FG", [x, u, dt],
            [ca.substitute(ca.jacobian(xf, x), w, w0), ca.substitute(ca.jacobian(xf, w), w, w0)],
        ).expand()
        self.control_psd = self.Ju_fn = None
        if control_psd is not None:
            self.control_psd = np.asarray(control_psd, dtype=float).reshape(self.nu)
            # Jacobian of the noise-free step with respect to the controls
            self.Ju_fn = ca.Function("Ju", [x, u, dt],
                                     [ca.substitute(ca.jacobian(xf, u), w, w0)]).expand()
        #: the CasADi functions of the model (the grid filters analyse them): the noise-free
        #: step ``f_fn(x, u, dt)``, its Jacobians ``FG_fn`` (in the state and the noise),
        #: ``Ju_fn`` (in the controls, with control noise) and the output map ``h_fn(x)``
        self.h_fn = h
        self._H: ca.Function | None = None  # dh/dx, built at the first H (see H)
        self._f_batch, self._h_batch = PointwiseMap(self.f_fn), PointwiseMap(h)

    # single-point evaluations -------------------------------------------------------------
    def f(self, x, u, dt: float) -> np.ndarray:
        return np.asarray(self.f_fn(x, u, dt)).reshape(self.nx)

    def FG(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F, G = self.FG_fn(x, u, dt)
        return np.asarray(F), np.asarray(G)

    def F(self, x, u, dt: float) -> np.ndarray:
        return self.FG(x, u, dt)[0]

    def Q(self, x, u, dt: float) -> np.ndarray:
        G = self.FG(x, u, dt)[1]
        Q = (G * (self.q_psd / dt)) @ G.T  # Q = G diag(psd/dt) G'
        if self.control_psd is not None:
            Ju = np.asarray(self.Ju_fn(x, u, dt))
            Q = Q + (Ju * (self.control_psd / dt)) @ Ju.T
        return Q

    def h(self, x) -> np.ndarray:
        return np.asarray(self.h_fn(x)).reshape(self.nz)

    def H(self, x) -> np.ndarray:
        """``dh/dx`` at ``x``. Its CasADi function is built at the first call, not with the
        model: with a terrain map it differentiates the map's B-spline (most of the model's CasADi
        set-up for the default map), which a run whose filters use the closed-form model
        never needs."""
        if self._H is None:
            xs = ca.MX.sym("x", self.nx)
            self._H = ca.Function("H", [xs], [ca.jacobian(self.h_fn(xs), xs)])
        return np.asarray(self._H(x)).reshape(self.nz, self.nx)

    # batch evaluations (rows are points) -----------------------------------------------------
    def f_batch(self, X: np.ndarray, u, dt: float) -> np.ndarray:
        return self._f_batch(X, u, dt).T

    def h_batch(self, X: np.ndarray) -> np.ndarray:
        return self._h_batch(X).T

