"""Sigma-point Kalman filters: UKF (``ukf``), CKF (``ckf``) and the CUKF of seed 001 (``cukf``).

All three propagate a deterministic point set through the model (``f_batch``/``h_batch``, one
call per set) and differ in the rule that places and weights the points:

- UKF: scaled unscented transform (Julier 2002; Wan & van der Merwe 2000) with ``alpha``,
  ``beta``, ``kappa``: ``lambda = alpha^2 (n + kappa) - n``, points ``x`` and
  ``x +- sqrt(n + lambda) L_i`` (``P = L L'``), mean weights ``lambda/(n + lambda)`` and
  ``1/(2(n + lambda))``, covariance centre weight ``+ 1 - alpha^2 + beta``.
- CKF: third-degree spherical-radial cubature rule (Arasaratnam & Haykin 2009): ``2n`` points
  ``x +- sqrt(n) L_i`` with equal weights ``1/(2n)``.
- CUKF: see :class:`CubatureUnscentedKalmanFilter`.

Additive noise: the predicted covariance adds ``Q(x, u, dt)`` at the prior mean and the update
redraws the points from the predicted ``(x, P)`` (so on a linear model every rule reproduces the
Kalman filter). Weighted means are taken relative to the first point to avoid cancellation with
large weights; ``P = P - K S K'`` is symmetrized and repaired when the next factorization needs
it (counted in ``diagnostics['pd_repairs']``).

As in :mod:`uwcosim.filters.kalman`, the steps keep the number of numpy calls low (they are
bound by numpy's per-call overhead on 4-state models): the point set as one product with a
constant matrix, ``np.dot``, symmetrization in place, the gain and the NIS from one solve.
``compiled = true`` runs the same steps compiled on the model's compiled form
(:mod:`uwcosim.filters.sigma_kernels`; equal to round-off, see :mod:`uwcosim.filters.kalman`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import Field, StrictBool, StrictFloat

from uwcosim.filters import sigma_kernels
from uwcosim.filters.base import FilterBase, register
from uwcosim.filters.gating import GateProbability, gate_field
from uwcosim.filters.kalman import CompiledUpdate, compiled_field
from uwcosim.filters.kalman_kernels import (
    F8,
    Workspace,
    compiled_workspace,
    exact,
    raise_for_status,
)
from uwcosim.filters.numerics import factor, gain_and_nis, symmetrize_
from uwcosim.filters.settings import FilterSettings, Measurements, measurements_field


@dataclass(frozen=True)
class SigmaRule:
    """Points ``x + s [0, L, -L]`` (the centre only if ``center``) and their weights."""

    n: int
    scale: float  # s: points at x +- s * column_i(L)
    wm: np.ndarray
    wc: np.ndarray
    center: bool

    def __post_init__(self) -> None:
        n, c = self.n, int(self.center)
        E = np.zeros((2 * n + c, n))  # X = x + E L': rows 0, s e_i, -s e_i
        E[c : c + n] = self.scale * np.eye(n)
        E[c + n :] = -self.scale * np.eye(n)
        object.__setattr__(self, "_E", E)
        #: the covariance weights as a column (``wc[:, None]``), for the weighted products
        object.__setattr__(self, "wc_col", self.wc[:, None].copy())

    def points(self, x: np.ndarray, L: np.ndarray) -> np.ndarray:
        """The point set as rows, ``(2n + center, n)``: ``x + s L_i`` as ``x + (E L')_i``,
        whose only non-zero term is ``+-s L_ji`` (the same numbers as scaling ``L``)."""
        X = np.dot(self._E, L.T)
        X += x
        return X

    def moments(self, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Weighted mean, covariance and deviations ``Y - mean`` of transformed points."""
        ref = Y[0]
        D = Y - ref
        m = np.dot(self.wm, D)  # mean = sum wm_i Y_i, computed relative to Y_0
        m += ref
        D = Y - m
        return m, np.dot((self.wc_col * D).T, D), D  # P = sum wc_i (Y_i - m)(Y_i - m)'


def unscented_rule(n: int, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0):
    """The scaled unscented rule (``2n + 1`` points)."""
    if not alpha > 0:
        raise ValueError(f"alpha must be positive, got {alpha}")
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    if not c > 0:
        raise ValueError(f"need alpha^2 (n + kappa) > 0, got n={n}, kappa={kappa}")
    wm = np.full(2 * n + 1, 0.5 / c)
    wc = wm.copy()
    wm[0] = lam / c
    wc[0] = lam / c + 1.0 - alpha**2 + beta
    return SigmaRule(n, math.sqrt(c), wm, wc, True)


def cubature_rule(n: int) -> SigmaRule:
    """The third-degree spherical-radial cubature rule (``2n`` points, equal weights)."""
    w = np.full(2 * n, 0.5 / n)
    return SigmaRule(n, math.sqrt(n), w, w, False)


def cukf_unscented_rule(n: int, a: float) -> SigmaRule:
    """Seed 001 eq. (7): ``x +- (a sqrt(n P))_i``, ``w_0 = 1 - 1/a^2``, ``w_i = 1/(2 n a^2)``.

    The same weights for mean and covariance (no ``beta`` term), i.e. the scaled rule with
    ``alpha = a``, ``kappa = 0``, ``beta = 0``.
    """
    if not a > 0:
        raise ValueError(f"a must be positive, got {a}")
    w = np.full(2 * n + 1, 0.5 / (n * a * a))
    w[0] = 1.0 - 1.0 / (a * a)
    return SigmaRule(n, a * math.sqrt(n), w, w, True)


class SigmaPointFilter(CompiledUpdate, FilterBase):
    """Predict/update of a sigma-point filter for the :class:`SigmaRule` of
    :meth:`sigma_rule`."""

    whole_step = (sigma_kernels, "sigma_step")

    class Settings(FilterSettings):
        measurements: Measurements = measurements_field()
        compiled: StrictBool = compiled_field()
        gate_probability: GateProbability = gate_field()  # filters.gating

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        self.rule = self.sigma_rule(model.nx)
        #: the compiled step's workspace for :attr:`rule` (None: the numpy step)
        self.workspace = self.rule_workspace(self.rule)

    def rule_workspace(self, rule: SigmaRule) -> Workspace | None:
        """The compiled step's workspace for ``rule`` (None unless ``compiled``)."""
        npts = rule.wm.size
        w = compiled_workspace(self, self.model, self._use,
                               sigma_kernels.rule_fields(rule.n, npts))
        if w is not None:
            s = w.ws[0]
            s["wm"], s["wc"], s["scale"], s["center"] = rule.wm, rule.wc, rule.scale, rule.center
        return w

    def _compiled_predict(self, w: Workspace, u, dt: float) -> None:
        w.transition(u, float(dt), w.F, w.b, w.Q)  # F, b, Q of the step (the model's)
        kernel = sigma_kernels.sigma_predict  # Y_i = f(X_i, u)
        if exact(self.x, F8, 1) and exact(self.P, F8, 2):
            status, repairs = w.call(kernel, self.x, self.P)
        else:  # the dispatcher types (and checks) them
            status, repairs = kernel(w.ws, self.x, self.P)
        if repairs:
            self.diagnostics["pd_repairs"] += repairs
        if status:
            raise_for_status(status, f"{self.kind} prediction")

    def sigma_rule(self, n: int) -> SigmaRule:
        """The rule of ``n`` states this filter uses (its settings are known)."""
        raise NotImplementedError

    def _points(self, rule: SigmaRule) -> np.ndarray:
        self.P, L = factor(self.P, self.diagnostics)
        return rule.points(self.x, L)

    def _propagate(self, X: np.ndarray, rule: SigmaRule, u, dt: float) -> np.ndarray:
        Q = self.model.Q(self.x, u, dt)
        Y = np.asarray(self.model.f_batch(X, u, dt))  # Y_i = f(X_i, u)
        self.x, P, _ = rule.moments(Y)  # x = sum wm_i Y_i
        P += Q
        self.P = symmetrize_(P)  # P = sum wc_i (Y_i - x)(Y_i - x)' + Q
        self._check("prediction")
        return Y

    def _correct(self, X: np.ndarray, rule: SigmaRule, z, idx: np.ndarray) -> None:
        Z = np.asarray(self.model.h_batch(X))  # Z_i = h(X_i)
        z = np.asarray(z, dtype=float)
        if idx.size != Z.shape[1]:
            Z, z = Z[:, idx], z[idx]
        zhat, Pzz, DZ = rule.moments(Z)
        S = Pzz
        S += self._R(idx)  # S = Pzz + R
        DX = X - self.x
        Pxz = np.dot((rule.wc_col * DX).T, DZ)  # Pxz = sum wc_i (X_i - x)(Z_i - z)'
        y = z - zhat  # y = z - zhat
        K, self.diagnostics["nis"] = gain_and_nis(Pxz, S, y, self.diagnostics)  # K = Pxz S^-1
        self.x = self.x + np.dot(K, y)  # x = x + K y
        P = self.P - np.dot(np.dot(K, S), K.T)
        self.P = symmetrize_(P)  # P = P - K S K'
        self.diagnostics["nis_dof"] = float(idx.size)
        self._check("update")

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        if self.workspace is not None:
            self._compiled_predict(self.workspace, u, dt)
            return
        self._propagate(self._points(self.rule), self.rule, u, dt)

    def update(self, z, mask=None) -> None:
        if self.workspace is not None:
            self._compiled_update(sigma_kernels.sigma_update, self.workspace, z, mask, False)
            return
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        self._correct(self._points(self.rule), self.rule, z, idx)


@register("ukf")
class UnscentedKalmanFilter(SigmaPointFilter):
    """Additive-noise UKF with the scaled unscented transform.

    ``alpha = 1`` (the default) spreads the points over the whole uncertainty ellipsoid, which a
    terrain likelihood needs; 1e-3 as in Wan & van der Merwe makes it nearly an EKF.
    """

    class Settings(FilterSettings):
        alpha: StrictFloat = Field(1.0, gt=0, description="spread of the sigma points (1: the "
                                   "whole uncertainty ellipsoid; 1e-3 nearly an EKF)")
        beta: StrictFloat = Field(2.0, description="prior knowledge of the distribution "
                                  "(2: optimal for Gaussian priors)")
        kappa: StrictFloat = Field(0.0, description="secondary scaling parameter")
        measurements: Measurements = measurements_field()
        compiled: StrictBool = compiled_field()
        gate_probability: GateProbability = gate_field()  # filters.gating

    def sigma_rule(self, n: int) -> SigmaRule:
        s = self.settings
        return unscented_rule(n, s.alpha, s.beta, s.kappa)


@register("ckf")
class CubatureKalmanFilter(SigmaPointFilter):
    """Cubature Kalman filter (third-degree spherical-radial rule, ``2n`` points)."""

    def sigma_rule(self, n: int) -> SigmaRule:
        return cubature_rule(n)


@register("cukf")
class CubatureUnscentedKalmanFilter(SigmaPointFilter):
    """The cubature unscented Kalman filter of seed 001, section 3.2, steps 1-8.

    One pass through steps 1-7 consumes two filter cycles: steps 1-3 are an unscented cycle
    (time k) and steps 4-7 a cubature cycle (time k+1); step 8 repeats. The filter therefore
    alternates the two rules, starting with the unscented one (``diagnostics['cubature_step']``
    is 1 on the cubature cycles). Choices where the extracted text is garbled or wrong:

    - eq. (7): sigma points ``x +- (a sqrt(L P))_i`` with the Cholesky factor and weights
      ``w_0 = 1 - 1/a^2``, ``w_i = 1/(2 L a^2)`` for both mean and covariance, as printed.
      The text calls ``a`` "a small positive value"; without a ``beta`` term a small ``a``
      makes covariances of even mildly nonlinear functions indefinite (for ``y = x^2`` the
      rule gives ``var = 4 m^2 p + (a^2 L - 1) p^2``, negative for ``m = 0``, ``a^2 L < 1``).
      Default ``a = sqrt(3/L)`` (``a^2 L = 3``, Julier's choice matching the Gaussian's fourth
      moment, exact ``2 p^2`` above); ``a = 1`` reduces steps 1-3 to the cubature rule.
    - eqs. (8)-(9): propagate and add ``Q`` as printed.
    - eqs. (10)-(13): the measurement points are the propagated points ``chi_{k|k-1}`` (not
      redrawn), as printed; ``redraw=True`` redraws them from ``(x_{k|k-1}, P_{k|k-1})`` instead.
      With the printed choice ``Q`` is missing from ``P_xz`` and ``P_zz``, so on a linear model
      with process noise the CUKF is NOT the Kalman filter; with ``redraw=True`` (or ``Q = 0``)
      it is.
    - eq. (14): ``K = P_xz P_zz^-1`` (Cholesky solve).
    - eq. (16): printed ``P = P + K P_z K'``; the sign is wrong, we use ``P = P - K P_zz K'``.
    - eqs. (17)-(19): ``A_k`` is the Cholesky factor ``S_k`` of the posterior and ``xi_j`` the
      ``2L`` cubature points ``sqrt(L) [I, -I]``; the measurement propagation ``pi_j`` of (19)
      is never used and is skipped.
    - eq. (20): ``N`` is ``L`` (``2L`` points); the covariance is computed in the central form
      ``sum w (mu - x)(mu - x)'``, algebraically equal to the printed raw-moment form, which
      cancels catastrophically at positions of 1e4 m.
    - eqs. (21)-(25): refactorize, redraw, predicted measurement and ``P_zz`` as printed; the
      duplicated first line of (25) is read as the cross covariance
      ``P_xz = 1/(2L) sum (xi - x)(pi* - z)'``.
    - eq. (26): printed ``K = P_zz P_zz^-1``; we use ``K = P_xz P_zz^-1`` and
      ``P = P - K P_zz K'`` (sign as in (16)).
    """

    whole_step = None  # predict, then update: the cycles alternate

    class Settings(FilterSettings):
        a: StrictFloat | None = Field(None, gt=0, description="sigma-point scale of eq. (7) "
                                      "(default sqrt(3/L))")
        redraw: StrictBool = Field(False, description="redraw the measurement points from "
                                   "the predicted moments (eqs. 10-13)")
        measurements: Measurements = measurements_field()
        compiled: StrictBool = compiled_field()
        gate_probability: GateProbability = gate_field()  # filters.gating

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        self.cubature = cubature_rule(model.nx)
        self.redraw = self.settings.redraw
        self._cycle = -1
        self._propagated: np.ndarray | None = None
        #: the compiled step's workspace for the cubature cycles (None: the numpy step)
        self.cubature_workspace = self.rule_workspace(self.cubature)
        self._stored = False  # compiled: the unscented update uses the propagated points

    @property
    def _unscented_cycle(self) -> bool:
        return self._cycle % 2 == 0

    def predict(self, u, dt: float) -> None:
        self._begin_predict()
        self._cycle += 1
        if self.workspace is not None:
            unscented = self._unscented_cycle
            self._compiled_predict(self.workspace if unscented else self.cubature_workspace,
                                   u, dt)  # steps 1-2 / 4-5
            self._stored = unscented and not self.redraw
            self.diagnostics["cubature_step"] = 0.0 if unscented else 1.0
            return
        rule = self.rule if self._unscented_cycle else self.cubature  # steps 1-2 / 4-5
        Y = self._propagate(self._points(rule), rule, u, dt)
        self._propagated = Y if self._unscented_cycle and not self.redraw else None
        self.diagnostics["cubature_step"] = 0.0 if self._unscented_cycle else 1.0

    def sigma_rule(self, n: int) -> SigmaRule:
        a = self.settings.a
        return cukf_unscented_rule(n, math.sqrt(3.0 / n) if a is None else a)

    def update(self, z, mask=None) -> None:
        if self.workspace is not None:
            unscented, stored, self._stored = self._unscented_cycle, self._stored, False
            w = self.workspace if unscented else self.cubature_workspace
            self._compiled_update(sigma_kernels.sigma_update, w, z, mask, stored and unscented)
            return
        idx = self._begin_update(z, mask)
        if idx is None:
            return
        if self._unscented_cycle:  # step 3, eqs. (10)-(16)
            X = self._propagated if self._propagated is not None else self._points(self.rule)
            self._propagated = None
            self._correct(X, self.rule, z, idx)
        else:  # steps 6-7, eqs. (21)-(26)
            self._correct(self._points(self.cubature), self.cubature, z, idx)
