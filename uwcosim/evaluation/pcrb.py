"""The posterior Cramér-Rao lower bound (PCRB) of a discrete-time state-space system.

Tichavsky, Muravchik and Nehorai (1998, IEEE Trans. Signal Processing 46(5)) give
the information matrix ``J(k)`` of the state at step ``k`` for ``x(k+1) = f(x(k)) + w(k)``,
``w ~ N(0, Q)``, ``z(k) = h(x(k)) + v(k)``, ``v ~ N(0, R)``, by the recursion::

    J(k+1) = D22 - D21 (J(k) + D11)^-1 D12
    D11 = E[F' Q^-1 F],  D12 = -E[F'] Q^-1 = D21',  D22 = Q^-1 + E[H' R^-1 H]

with ``F``, ``H`` the Jacobians of ``f``, ``h`` at the true state and the expectations over the
true trajectories (here: Monte Carlo over truth runs, :func:`pcrb`). Every unbiased or Bayesian
estimator's error covariance is at least ``J(k)^-1``; the bound on the position RMSE at step
``k`` is ``sqrt(trace of the position block of J(k)^-1)`` (:func:`position_bound`).

Singular process noise. ``D11`` and ``D22`` need ``Q^-1``, which does not exist when a state has
no noise (a zero PSD, or a model whose noise drives fewer directions than it has states). When
the dynamics are linear in the state -- ``F`` and ``Q`` the same on every truth run at a step,
as for the TAN model of seed 000 eq. 54 (``F`` depends on the controls only) and every linear
model -- the recursion is used in the form that needs no ``Q^-1``: with ``D11 = F' Q^-1 F`` and
``D12 = -F' Q^-1`` the matrix inversion lemma turns the recursion above into::

    J(k+1) = (Q + F J(k)^-1 F')^-1 + E[H' R^-1 H]

which is exact for any positive semi-definite ``Q`` as long as ``Q + F J^-1 F'`` is invertible
(it is when ``J(0)`` is and ``F`` is nonsingular). This is also the Kalman filter's information
update: for a linear-Gaussian system the bound equals the Kalman filter's covariance
(``tests/test_pcrb.py`` checks it to 1e-9). When ``F`` or ``Q`` differ between the runs (a
model nonlinear in the state, or a ``Q`` that depends on it, as with ``model.control_noise``)
the general form above is used, which needs every ``Q`` invertible: a singular one there is an
error (:class:`~uwcosim.core.errors.UwcosimError`), not a pseudo-inverse (a pseudo-inverse
would give no bound). A state-dependent ``Q`` enters through ``E[Q^-1]`` and ``E[F' Q^-1 F]``
(the terms of its derivative in the state are left out: the linearized-noise approximation).

Intermittent measurements. ``E[H' R^-1 H]`` is taken over the components each run actually
received at that step (:func:`measurement_information`): a lost or unsampled measurement has no
``H`` term in that step, on that run (the bound conditioned on the loss pattern as realised).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uwcosim.core.errors import UwcosimError

__all__ = ["Bound", "Recursion", "measurement_information", "pcrb", "position_bound",
           "time_average"]

#: forms of the recursion (:func:`pcrb`): which one each step used
COVARIANCE_FORM = "covariance"  # (Q + F J^-1 F')^-1 + E[H' R^-1 H]: F, Q the same on every run
GENERAL_FORM = "general"  # D22 - D21 (J + D11)^-1 D12: F or Q differ between runs


@dataclass(frozen=True)
class Bound:
    """The PCRB of ``K + 1`` steps: ``P[k] = J(k)^-1`` (``(K + 1, n, n)``), step 0 the prior.

    ``forms``: the recursion's form at each step 1..K (``covariance`` or ``general``);
    ``runs``: the number of truth runs the expectations are over."""

    P: np.ndarray
    forms: tuple[str, ...]
    runs: int

    @property
    def std(self) -> np.ndarray:
        """The bound on each state's RMSE per step: ``sqrt(diag J(k)^-1)`` (``(K + 1, n)``)."""
        return np.sqrt(np.maximum(np.diagonal(self.P, axis1=1, axis2=2), 0.0))


def measurement_information(H: np.ndarray, R: np.ndarray, received: np.ndarray) -> np.ndarray:
    """``E[H' R^-1 H]`` over runs: ``H`` ``(N, nz, n)`` the Jacobians at the runs' true states,
    ``R`` ``(nz, nz)``, ``received`` ``(N, nz)`` the components each run received (only those
    rows, with their block of ``R``, enter its term)."""
    H = np.asarray(H, dtype=float)
    received = np.asarray(received, dtype=bool)
    N, _, n = H.shape
    R = np.asarray(R, dtype=float)
    if np.count_nonzero(R - np.diag(np.diag(R))) == 0:  # diagonal R: a weight per row
        W = received / np.diag(R)  # (N, nz): 1/r_j on the received rows, 0 elsewhere
        return np.einsum("kzi,kz,kzj->ij", H, W, H) / N  # sum_k H_k' W_k H_k / N
    out = np.zeros((n, n))
    for pattern in np.unique(received, axis=0):  # one R block inverse per loss pattern
        if not pattern.any():
            continue
        rows = np.all(received == pattern, axis=1)
        Hr = H[rows][:, pattern]  # (m, nr, n)
        Ri = np.linalg.inv(R[np.ix_(pattern, pattern)])
        out += np.einsum("kzi,zy,kyj->ij", Hr, Ri, Hr)
    return out / N


def _same_on_every_run(A: np.ndarray) -> bool:
    return bool(np.all(A == A[:1]))


def _symmetric(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


class Recursion:
    """The PCRB recursion step by step, from the prior covariance ``P0`` (``J(0) = P0^-1``).

    :meth:`step` takes one step's Jacobians and process covariances on the ``N`` truth runs
    (``(N, n, n)`` each, at the run's true state before the step) and the step's
    ``E[H' R^-1 H]`` after it (:func:`measurement_information`), and returns ``J(k+1)^-1``.
    The form is chosen per step (module docstring) and recorded in ``forms``."""

    def __init__(self, P0: np.ndarray, form: str | None = None) -> None:
        """``form``: ``general`` to use the general form at every step (for checking the two
        against each other); None: chosen per step."""
        self.form = form
        self.P = np.asarray(P0, dtype=float).copy()
        self.J = np.linalg.inv(self.P)
        self.forms: list[str] = []

    def step(self, F: np.ndarray, Q: np.ndarray, info: np.ndarray) -> np.ndarray:
        F, Q = np.asarray(F, dtype=float), np.asarray(Q, dtype=float)
        J, n = self.J, F.shape[-1]
        if self.form != GENERAL_FORM and _same_on_every_run(F) and _same_on_every_run(Q):
            Pp = F[0] @ self.P @ F[0].T + Q[0]  # Q + F J^-1 F'
            J = np.linalg.inv(_symmetric(Pp)) + info  # (Q + F J^-1 F')^-1 + E[H' R^-1 H]
            self.forms.append(COVARIANCE_FORM)
        else:
            if np.any(np.linalg.matrix_rank(Q) < n):
                raise UwcosimError(
                    f"bound: step {len(self.forms) + 1}: the process noise covariance Q is "
                    f"singular while F or Q differ between the truth runs: the PCRB recursion "
                    f"needs Q^-1 there (give every state process noise)")
            Qi = np.linalg.inv(Q)  # (N, n, n)
            FtQi = np.transpose(F, (0, 2, 1)) @ Qi
            D11 = np.mean(FtQi @ F, axis=0)  # E[F' Q^-1 F]
            D12 = -np.mean(FtQi, axis=0)  # -E[F' Q^-1]
            D22 = np.mean(Qi, axis=0) + info  # E[Q^-1] + E[H' R^-1 H]
            J = D22 - D12.T @ np.linalg.solve(J + D11, D12)  # D22 - D21 (J + D11)^-1 D12
            self.forms.append(GENERAL_FORM)
        self.J = _symmetric(J)
        self.P = _symmetric(np.linalg.inv(self.J))
        return self.P


def pcrb(P0: np.ndarray, F: np.ndarray, Q: np.ndarray, info: np.ndarray) -> Bound:
    """The PCRB from the prior covariance ``P0`` over ``K`` steps, all given at once.

    ``F``, ``Q``: ``(K, N, n, n)``, each step's Jacobian and process covariance on the ``N``
    truth runs; ``info``: ``(K, n, n)``, each step's ``E[H' R^-1 H]``
    (:class:`Recursion`, one step at a time)."""
    F, Q, info = (np.asarray(a, dtype=float) for a in (F, Q, info))
    K, N, n, _ = F.shape
    rec = Recursion(P0)
    P = np.empty((K + 1, n, n))
    P[0] = rec.P
    for k in range(K):
        P[k + 1] = rec.step(F[k], Q[k], info[k])
    return Bound(P, tuple(rec.forms), N)


def position_bound(bound: Bound | np.ndarray, position: list[int] | tuple[int, ...]) -> np.ndarray:
    """``sqrt(trace of the position block of J(k)^-1)`` per step: the bound on the position
    error norm's RMSE; ``bound`` a :class:`Bound` or its per-state ``std`` (``(K + 1, n)``)."""
    std = bound.std if isinstance(bound, Bound) else np.asarray(bound, dtype=float)
    return np.sqrt(np.sum(std[:, list(position)] ** 2, axis=1))


def time_average(per_step: np.ndarray) -> float:
    """The bound comparable with a run's RMSE (root of the time average of the squared error
    over steps 1..K): the root of the time average of the squared bound over steps 1..K."""
    b = np.asarray(per_step, dtype=float)[1:]
    return float(np.sqrt(np.mean(b**2))) if b.size else float("nan")
