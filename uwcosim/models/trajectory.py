"""Truth trajectories of a filter model itself, without FMUs (filter studies, tests, benchmarks).

:func:`simulate` steps ``x_{k+1} = f(x_k, u_k) + w_k`` with noise drawn from the model's own
covariances; :func:`wandering_heading` is the control sequence of the TAN studies. Pass the
model whose arithmetic the truth should use (for the TAN model of
:func:`uwcosim.models.tan.tan_model`, ``model.symbolic`` is its CasADi form).
"""

from __future__ import annotations

import numpy as np


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
