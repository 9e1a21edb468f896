"""Variational-Bayes adaptive Kalman filters: VB-AKF (``vbakf``) and QIVBF (``qivbf``).

``qivbf`` is ``vbakf`` fed through the ``extrapolate`` lost-measurement policy
(:class:`~uwcosim.filters.policies.Extrapolate`, seed 001 eq. 28) before every update:
:class:`ExtrapolatingVBAKF` is :class:`VariationalBayesAKF` plus that policy, plus the optional
``inflate_r`` correction below. (``vbakf`` with a scenario's ``policy = "extrapolate"`` gets
the same extrapolation from outside the filter; the registered name ``qivbf`` is seed 001's.)

VB-AKF: Huang, Zhang, Wu, Li & Chambers, "A novel adaptive Kalman filter with inaccurate process
and measurement noise covariance matrices", IEEE TAC 63(2), 2018, Algorithm 1. The predicted
covariance ``P_{k|k-1}`` and ``R_k`` get inverse-Wishart models::

    time update      x = f(x, u), P~ = F P F' + Q~                 (nominal Q~ = model.Q)
                     u = rho (u - m - 1) + m + 1, U = rho U         (R forgetting, eqs. 14-15)
    initialization   t = n + tau + 1, T = tau P~; x(0) = x, P(0) = P~
    iteration i      A = P(i) + (x(i) - x)(x(i) - x)'              (a sum)
                     t(i+1) = t + 1, T(i+1) = A + T
                     B = (z - H x(i))(z - H x(i))' + H P(i) H'
                     u(i+1) = u + 1, U(i+1) = B + U
                     P^ = T(i+1) / (t(i+1) - n - 1), R^ = U(i+1) / (u(i+1) - m - 1)
                     K = P^ H' (H P^ H' + R^)^-1                   (the inverse of S)
                     x(i+1) = x + K (z - H x), P(i+1) = P^ - K H P^ (Joseph form)

``t``, ``T``, ``u``, ``U`` inside the loop always start from the priors (the iterations do not
accumulate). The loop stops after ``iterations`` passes or when the state moves by less than
``tol`` posterior standard deviations. ``E[R] = U / (u - m - 1)`` is :attr:`R_hat`.

Nonlinear ``h``: EKF-style, ``H`` is the Jacobian at the predicted mean and the residual of
iterate ``x(i)`` is ``z - h(x) - H (x(i) - x)`` (for linear ``h`` this is ``z - H x(i)``).

Missing components (sensors at different rates, lost components; neither Huang nor seed 001
treats a partly observed ``z``, so this rule is ours): with ``p`` of the ``m`` components
observed (block ``o``), the likelihood involves only ``R_oo``. The marginal of ``R_oo`` under
``IW(u, U)`` is ``IW(u - (m - p), U_oo)``; the update runs on it (``U_oo + B`` with dof
``+ 1``); the unobserved components got no data. One inverse-Wishart has one dof for all
components, so the posterior is projected back on one: ``u`` is kept and the observed block is
set to ``c (U_oo + B)``, ``c = (u - m - 1) / (u - m)``, so that its mean ``E[R_oo]`` is the
block's posterior mean (the block's spread is overstated by one dof, a conservative
projection); :func:`partial_iw_update` writes this block back by a congruence that keeps the
unobserved block ``U_uu`` (its marginal, hence the mean of its noise) and its Schur complement
``U_uu - U_uo U_oo^-1 U_ou``, and carries the cross terms along with the observed block's
square root, so ``U`` stays positive definite. Keeping ``U_uu`` rather than the regression
``U_oo^-1 U_ou`` is our choice for independent sensors (as the scenarios declare them): there
the cross terms of ``U`` are only sampling noise of the full updates' ``e e'`` and must not
move another sensor's noise level. (The old write-back replaced the block and kept the cross
terms as they were: a residual smaller than expected shrinks the block, ``c (U_oo + B) <
U_oo``, the cross terms of the full updates then no longer fit, the Schur complement of the
rest goes negative, and the next full update gave an indefinite ``P``.) With all components
observed the update is Huang's, bit for bit as before; with a block-diagonal ``U`` the
write-back is the old one, bit for bit. The other projection, ``u + 1`` with the
unobserved block's mean kept, claims one sample per step for a sensor that reports less often
and was much worse on the current-navigation example (docs/your_own_model.md).

QIVBF (seed 001): a lost component is first extrapolated by the three-point Lagrange polynomial
through its last three received values (eq. 28, :class:`~uwcosim.filters.policies.Extrapolate`,
at the estimator's ``t``), then the VB-AKF update runs. Seed 001 deviations, all from garbled
text: the Table 1 time update ``P = (X_{k|k-1} - X_{k-1|k-1})(...)' + Q`` is read as
``F P F' + Q``; eq. (40) ``X(l+1) = X(l) + K (Y - H X(l))`` would apply the measurement once per
iteration, Huang's ``x(i+1) = x + K (z - H x)`` from the prior is used; eqs. (37)-(38) are used as
printed (``E = M / (m - n - 1)``, as in Huang).

QIVBF settings beyond the paper: ``extrapolate`` (``"runs"``, default: every lost value once
three were received, our generalization to consecutive losses; ``"isolated"``: only a single
loss after three receipts, seed 001's Assumption 1, other losses are skipped) and
``inflate_r`` (false; **our own correction, not in seed 001**: an extrapolated value
``sum_j l_j Y_j`` carries the noise ``sum_j l_j v_j`` of variance ``g r`` with the Lagrange
noise gain ``g = sum_j l_j^2`` (19 for one step after three equally spaced receipts), so its
row of the update is divided by ``sqrt(g)``: the VB update then sees it with ``R`` scaled by
``g`` while the inverse-Wishart model of ``R`` keeps learning from unit-gain rows).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field, StrictBool, StrictFloat, StrictInt

from uwcosim.core.errors import FilterDivergence
from uwcosim.filters.base import FilterBase, register
from uwcosim.filters.gating import GateProbability, gate, gate_field
from uwcosim.filters.numerics import kalman_gain, linearize, nis, symmetrize
from uwcosim.filters.policies import Extrapolate
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field


@dataclass
class VBResult:
    """Outcome of :func:`vb_update` (the last iteration's quantities)."""

    x: np.ndarray  # posterior mean
    P: np.ndarray  # posterior covariance
    t: float  # dof and inverse scale of q(P_{k|k-1})
    T: np.ndarray
    u: float  # dof and inverse scale of q(R_k)
    U: np.ndarray
    P_hat: np.ndarray  # T / (t - n - 1)
    R_hat: np.ndarray  # U / (u - m - 1)
    K: np.ndarray
    S: np.ndarray  # H P_hat H' + R_hat
    A: np.ndarray  # A of the last iteration
    B: np.ndarray  # B of the last iteration
    innovation: np.ndarray  # z - h(x_{k|k-1})
    iterations: int
    cho: tuple


def vb_update(
    x: np.ndarray,
    P: np.ndarray,
    y: np.ndarray,
    H: np.ndarray,
    u: float,
    U: np.ndarray,
    tau: float = 3.0,
    iterations: int = 10,
    tol: float = 1e-6,
    counter: dict | None = None,
) -> VBResult:
    """Huang et al. (2018) Algorithm 1, measurement update (steps 3-13).

    ``x``, ``P``: predicted mean and nominal predicted covariance; ``y = z - h(x)``: the
    innovation at ``x``; ``H``: measurement matrix (Jacobian at ``x``); ``u``, ``U``: the
    predicted inverse-Wishart parameters of ``R`` (after forgetting).
    """
    n, m = x.size, y.size
    t_pred, T_pred = n + tau + 1.0, tau * P  # t = n + tau + 1, T = tau P
    u_pred, U_pred = float(u), U
    Ht = H.T
    eye = np.eye(n)
    xi, Pi = x, P
    done = 0
    tol2 = tol * tol
    while done < int(iterations):
        done += 1
        dx = xi - x
        A = Pi + dx[:, None] * dx  # A = P(i) + dx dx'
        t, T = t_pred + 1.0, A + T_pred  # t = t + 1, T = A + T
        e = y - H @ dx  # e = z - h(x) - H (x(i) - x)
        B = e[:, None] * e + H @ Pi @ Ht  # B = e e' + H P(i) H'
        uu, UU = u_pred + 1.0, B + U_pred  # u = u + 1, U = B + U
        P_hat = T / (t - n - 1.0)  # E[P_{k|k-1}] = T / (t - n - 1)
        R_hat = UU / (uu - m - 1.0)  # E[R] = U / (u - m - 1)
        PHt = P_hat @ Ht
        S = H @ PHt + R_hat  # S = H P^ H' + R^
        K, cho = kalman_gain(PHt, S, counter)  # K = P^ H' S^-1
        x_new = x + K @ y  # x = x + K (z - h(x))
        IKH = eye - K @ H
        P_new = IKH @ P_hat @ IKH.T + K @ R_hat @ K.T  # P = (I-KH) P^ (I-KH)' + K R^ K'
        P_new = 0.5 * (P_new + P_new.T)
        step = x_new - xi
        step *= step
        xi, Pi = x_new, P_new
        if (step / np.maximum(P_new.diagonal(), 1e-300)).max() < tol2:
            break
    return VBResult(xi, Pi, t, T, uu, UU, P_hat, R_hat, K, S, A, B, y, done, cho)


def partial_iw_update(U: np.ndarray, idx: np.ndarray, U_oo: np.ndarray) -> np.ndarray:
    """``U`` with its observed block ``U[idx, idx]`` replaced by ``U_oo``, positive definite.

    The congruence ``U' = M U M'`` with ``M = I`` except ``M_oo = L' L^-1`` (``L``, ``L'`` the
    Cholesky factors of the old and the new observed block): ``U'_oo = L' L'^T = U_oo``, the
    unobserved block ``U'_uu = U_uu`` and its Schur complement
    ``U_uu - U_uo U_oo^-1 U_ou`` are unchanged, the cross terms ``U'_ou = L' L^-1 U_ou`` keep
    the whitened cross term ``L^-1 U_ou``. ``M`` is invertible, so ``U'`` is positive definite
    when ``U`` and ``U_oo`` are. With a block-diagonal ``U`` (no cross terms) this is only the
    block's replacement. A block that is not positive definite
    raises :class:`~uwcosim.core.errors.FilterDivergence`.
    """
    o = np.ix_(idx, idx)
    try:
        L_old = np.linalg.cholesky(U[o])  # U_oo = L L'
        L_new = np.linalg.cholesky(symmetrize(U_oo))  # U'_oo = L' L''
    except np.linalg.LinAlgError:
        raise FilterDivergence("inverse-Wishart scale U of R not positive definite") from None
    M_oo = np.linalg.solve(L_old.T, L_new.T).T  # M_oo = L' L^-1
    out = U.copy()
    out[idx] = M_oo @ U[idx]  # rows of M U
    out[:, idx] = out[:, idx] @ M_oo.T  # columns of (M U) M': U'_uo = U_uo M_oo'
    out[o] = U_oo  # = M_oo U_oo M_oo' up to round-off
    return symmetrize(out)


@register("vbakf")
class VariationalBayesAKF(FilterBase):
    """VB adaptive Kalman filter with inaccurate ``Q`` and ``R`` (Huang et al. 2018).

    The default ``u0 = m + 2`` makes the nominal ``R`` weigh as one sample. The model's ``Q``
    and ``R`` are the nominal ``Q~`` and ``R~_0``.
    """

    class Settings(FilterSettings):
        tau: StrictFloat = Field(3.0, ge=0, description="tuning of the prior dof of P_{k|k-1}")
        rho: StrictFloat = Field(1.0 - math.exp(-4.0), gt=0, le=1,
                                 description="forgetting factor of the R estimate")
        iterations: StrictInt = Field(10, ge=1, description="maximum VB iterations per update")
        tol: StrictFloat = Field(1e-6, ge=0, description="stop when the state moves less than "
                                 "tol posterior standard deviations")
        u0: StrictFloat | None = Field(None, description="initial dof of R (default m + 2; "
                                       "must exceed m + 1)")
        measurements: Measurements = measurements_field()
        gate_probability: GateProbability = gate_field()  # filters.gating, with E[R]

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        s = self.settings
        m = model.nz
        u0 = m + 2.0 if s.u0 is None else s.u0
        if not u0 > m + 1:
            raise ValueError(f"u0 must exceed m + 1 = {m + 1}, got {u0}")
        self.tau, self.rho, self.tol = s.tau, s.rho, s.tol
        self.iterations = s.iterations
        self.u = u0
        self.U = (u0 - m - 1.0) * np.array(model.R, dtype=float)  # E[R_0] = R~_0 (Huang eq. 16)
        self.last: VBResult | None = None

    @property
    def R_hat(self) -> np.ndarray:
        """``E[R] = U / (u - m - 1)``."""
        return self.U / (self.u - self.model.nz - 1.0)

    def _gate_variances(self, idx: np.ndarray) -> np.ndarray:
        """The gate's ``R_ii``: the current estimate ``E[R]``, not the nominal ``R``."""
        return np.diag(self.R_hat)[idx]

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        F, Q = linearize(self.model, self.x, u, dt)
        self.x = self.model.f(self.x, u, dt)  # x = f(x, u)
        self.P = symmetrize(F @ self.P @ F.T + Q)  # P~ = F P F' + Q~
        m = self.model.nz
        self.u = self.rho * (self.u - m - 1.0) + m + 1.0  # u = rho (u - m - 1) + m + 1
        self.U = self.rho * self.U  # U = rho U
        self._check("prediction")

    def update(self, z, mask=None) -> None:
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        self._vb(np.asarray(z, dtype=float), idx)

    def _vb(self, z: np.ndarray, idx: np.ndarray, gain: np.ndarray | None = None) -> None:
        m, p = self.model.nz, idx.size
        full = p == m
        H = self.model.H(self.x)[idx]
        y = z[idx] - self.model.h(self.x)[idx]  # y = z - h(x)
        if gain is not None:  # rows of extrapolated values: noise variance g r (see above)
            scale = 1.0 / np.sqrt(gain[idx])
            H = H * scale[:, None]
            y = y * scale
        u_s = self.u - (m - p)  # marginal IW of the available block
        U_s = self.U if full else self.U[np.ix_(idx, idx)]
        res = vb_update(self.x, self.P, y, H, u_s, U_s, self.tau, self.iterations, self.tol,
                        self.diagnostics)
        self.x, self.P = res.x, res.P
        if full:
            self.u, self.U = res.u, res.U
        else:  # keep u; the block's mean becomes the subset posterior mean, U stays PD
            c = (self.u - m - 1.0) / (self.u - m)
            self.U = partial_iw_update(self.U, idx, c * res.U)
        self.last = res
        self.diagnostics["nis"] = nis(y, res.cho)
        self.diagnostics["nis_dof"] = float(p)
        self.diagnostics["vb_iterations"] = float(res.iterations)
        self._check("update")


@register("qivbf")
class ExtrapolatingVBAKF(VariationalBayesAKF):
    """``qivbf``, seed 001's QIVBF: the ``vbakf`` update after the ``extrapolate`` policy
    (eq. 28 extrapolation of lost components), built in.

    Uses ``est.t`` (set by the driver before ``update``) as the measurement time. Components
    with fewer than three received values so far are skipped. ``inflate_r`` is our correction
    (see the module docstring); ``diagnostics['extrapolated']`` counts the filled components.
    """

    class Settings(VariationalBayesAKF.Settings):
        """``qivbf`` = ``vbakf`` + the ``extrapolate`` policy built in: its settings plus
        these."""

        extrapolate: Literal["runs", "isolated"] = Field(
            "runs", description="extrapolate every lost component with three earlier receipts "
            "(runs), or only a single loss after three receipts (isolated, seed 001 "
            "Assumption 1)")
        inflate_r: StrictBool = Field(False, description="inflate R of an extrapolated "
                                      "component by the Lagrange noise gain (our correction, "
                                      "not the paper's)")

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        self.interpolator = Extrapolate(model.nz, self.settings.extrapolate)
        self.inflate_r = self.settings.inflate_r

    def update(self, z, mask=None) -> None:
        mask = self._use if mask is None else np.asarray(mask, dtype=bool) & self._use
        rejected = 0
        if self._gate_threshold is not None and z is not None:  # a gated value is a lost one
            mask, rejected = self._gate_received(np.asarray(z, dtype=float), mask)
        z, mask = self.interpolator(self.t, z, mask)  # eq. (28) for the lost components
        idx = self._begin_update(z, mask)  # gates the extrapolated values too
        self.diagnostics["extrapolated"] = float(self.interpolator.extrapolated)
        if rejected:
            self.diagnostics["gated"] = self.diagnostics.get("gated", 0.0) + rejected
        if idx is None:
            return
        filled = self.inflate_r and self.interpolator.extrapolated
        gain = self.interpolator.gain if filled else None
        self._vb(np.asarray(z, dtype=float), idx, gain)

    def _gate_received(self, z: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, int]:
        """``mask`` without the received components the gate rejects, and how many: they are
        then lost, extrapolated like the others, and kept out of the extrapolation's history."""
        received = (mask & np.isfinite(z)).nonzero()[0]
        if received.size == 0:
            return mask, 0
        kept, rejected = gate(self.model, self.x, self.P, z, received, self._gate_threshold,
                              self._gate_variances(received))
        if rejected == 0:
            return mask, 0
        mask = mask.copy()
        mask[received] = False
        if kept is not None:
            mask[kept] = True
        return mask, rejected
