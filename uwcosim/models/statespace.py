"""Discrete-time state-space models for the filters, built from CasADi expressions.

:class:`CasadiModel` turns a continuous ODE ``xdot = ode(x, u, w)`` (noise ``w`` held over a
step, as the master feeds the FMUs) and an output map ``z = h(x)`` into everything the filters
need: ``f`` (one RK4 step), the Jacobians ``F = df/dx`` and ``G = df/dw``, the discrete process
covariance ``Q = G diag(psd / dt) G'`` (a held white-noise sample of power spectral density
``psd`` has variance ``psd / dt``), ``H = dh/dx``, and batch versions for particle and sigma-point
filters (``casadi.Function.map``). Functions are built once per model.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from uwcosim.models.vehicle import rk4_step


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
        self._f = ca.Function("f", [x, u, dt], [step(x, u, w0, dt)]).expand()
        self._FG = ca.Function(
            "FG", [x, u, dt],
            [ca.substitute(ca.jacobian(xf, x), w, w0), ca.substitute(ca.jacobian(xf, w), w, w0)],
        ).expand()
        self._h = h
        xs = ca.MX.sym("x", self.nx)
        self._H = ca.Function("H", [xs], [ca.jacobian(h(xs), xs)])
        self._f_maps: dict[int, ca.Function] = {}
        self._h_maps: dict[int, ca.Function] = {}

    # single-point evaluations -------------------------------------------------------------
    def f(self, x, u, dt: float) -> np.ndarray:
        return np.asarray(self._f(x, u, dt)).reshape(self.nx)

    def FG(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F, G = self._FG(x, u, dt)
        return np.asarray(F), np.asarray(G)

    def F(self, x, u, dt: float) -> np.ndarray:
        return self.FG(x, u, dt)[0]

    def Q(self, x, u, dt: float) -> np.ndarray:
        G = self.FG(x, u, dt)[1]
        return (G * (self.q_psd / dt)) @ G.T  # Q = G diag(psd/dt) G'

    def h(self, x) -> np.ndarray:
        return np.asarray(self._h(x)).reshape(self.nz)

    def H(self, x) -> np.ndarray:
        return np.asarray(self._H(x)).reshape(self.nz, self.nx)

    # batch evaluations (rows are points) -----------------------------------------------------
    def f_batch(self, X: np.ndarray, u, dt: float) -> np.ndarray:
        n = X.shape[0]
        fm = self._f_maps.get(n)
        if fm is None:
            fm = self._f_maps[n] = self._f.map(n)
        return np.asarray(fm(X.T, u, dt)).T

    def h_batch(self, X: np.ndarray) -> np.ndarray:
        n = X.shape[0]
        hm = self._h_maps.get(n)
        if hm is None:
            hm = self._h_maps[n] = self._h.map(n)
        return np.asarray(hm(X.T)).T


def simulate(model, x0, controls, steps: int, rng: np.random.Generator, dt: float = 1.0,
             noise: str = "cholesky"):
    """A truth trajectory of a filter model itself, without FMUs (for filter studies, tests and
    benchmarks): ``x_{k+1} = f(x_k, u_k) + w_k``, ``z_k = h(x_{k+1}) + v_k`` with
    ``u_k = controls(k)``, called once per step before the step's noise is drawn (it may draw
    from ``rng`` too). Two ways of drawing the same noise distribution (for a diagonal ``R``):

    - ``noise="cholesky"``: ``w_k = chol(Q(x_k, u_k)) e``, ``v_k = sqrt(diag R) e'``;
    - ``noise="held"`` (a model with ``FG`` and ``q_psd``: the continuous noise held over the
      step, ``Q = G diag(q_psd/dt) G'``): ``w_k = G diag(q_psd/dt)^(1/2) e``,
      ``v_k ~ N(0, R)`` by ``rng.multivariate_normal``.

    Returns ``(X [steps+1, nx] from x0, U [steps, nu], Z [steps, nz])``.
    """
    if noise not in ("cholesky", "held"):
        raise ValueError(f"noise must be 'cholesky' or 'held', not {noise!r}")
    X = np.zeros((steps + 1, model.nx))
    X[0] = x0
    U = np.zeros((steps, model.nu))
    Z = np.zeros((steps, model.nz))
    r = np.sqrt(np.diag(model.R))
    zero = np.zeros(model.nz)
    for k in range(steps):
        U[k] = controls(k)
        e = rng.standard_normal(model.nx)
        if noise == "held":
            w = model.FG(X[k], U[k], dt)[1] @ (e * np.sqrt(model.q_psd / dt))
        else:
            w = np.linalg.cholesky(model.Q(X[k], U[k], dt)) @ e
        X[k + 1] = model.f(X[k], U[k], dt) + w
        if noise == "held":
            Z[k] = model.h(X[k + 1]) + rng.multivariate_normal(zero, model.R)
        else:
            Z[k] = model.h(X[k + 1]) + r * rng.standard_normal(r.size)
    return X, U, Z


def wandering_heading(rng: np.random.Generator, psi0: float = 0.3):
    """Controls ``k -> [psi_k, a_k]`` of the TAN studies: a heading that turns slowly with a
    random walk (drawn from ``rng`` at each call, so call it once per step in order) and an
    acceleration ``0.002 sin(0.02 k)`` m/s^2."""
    psi = psi0

    def controls(k: int) -> np.ndarray:
        nonlocal psi
        psi += 0.01 * np.sin(0.01 * k) + 0.002 * rng.standard_normal()
        return np.array([psi, 0.002 * np.sin(0.02 * k)])

    return controls
