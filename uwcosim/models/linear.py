"""Linear-Gaussian filter models: :class:`LinearModel` and the constant-velocity model.

``x' = F(dt) x + B(dt) u + w``, ``w ~ N(0, Q(dt))``; ``z = H x + v``, ``v ~ N(0, R)``, exposing
the :class:`~uwcosim.filters.base.StateSpaceModel` protocol (``f``, ``F``, ``Q``, ``h``, ``H``,
batch forms) plus ``FQ`` and ``linear = True`` (which the Kalman filter ``kf`` requires).

:func:`constant_velocity_model` is the filter model of the ``ConstantVelocity`` FMU
(:mod:`uwcosim.models.cv_equations`): state ``[px, vx, py, vy]`` in the FMU's (and seed 001's)
order, white noise ``w`` held over a step on every state derivative. With the noise held the
discretization is exact: per axis ``F = [[1, dt], [0, 1]]``, ``G = [[dt, dt^2/2], [0, dt]]`` and
``Q = G diag(psd/dt) G'``. Seed 001 Table 2 instead gives a fixed discrete
``Q = 1e-3 diag(1, 0.5, 1, 0.5)`` (with ``H = I``, ``R = I``, ``P0 = I``); pass it as ``Q``.

Measurements are named ``<sensor>.<state>_m`` (``gps.px_m``, ``dvl.vx_m``; ``x``/``y`` are
accepted for ``px``/``py``): each picks one state, which builds ``H``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from uwcosim.core.bicubic import Surface
from uwcosim.core.errors import ScenarioError
from uwcosim.models.protocol import CompiledForm

CV_STATE_NAMES = ("px", "vx", "py", "vy")
_ALIASES = {"x": "px", "y": "py"}

Matrix = np.ndarray | Callable[[float], np.ndarray]


class LinearModel:
    """A linear-Gaussian model with matrices (``F``, ``Q``, ``B`` may be functions of ``dt``)."""

    linear = True
    Q_depends_on_x = False

    def __init__(
        self,
        F: Matrix,
        H,
        Q: Matrix,
        R,
        B: Matrix | None = None,
        state_names: tuple[str, ...] | None = None,
        measurement_names: tuple[str, ...] | None = None,
    ) -> None:
        self._F, self._Q, self._B = F, Q, B
        self._H = np.atleast_2d(np.asarray(H, dtype=float))
        self.nz, self.nx = self._H.shape
        R = np.asarray(R, dtype=float)
        self.R = np.diag(R) if R.ndim == 1 else R
        if self.R.shape != (self.nz, self.nz):
            raise ValueError(f"R must be {self.nz}x{self.nz}, got {self.R.shape}")
        self.state_names = tuple(state_names or (f"x{i}" for i in range(self.nx)))
        self.measurement_names = tuple(measurement_names or (f"z{i}" for i in range(self.nz)))
        B0 = self._mat(B, 1.0) if B is not None else None
        self.nu = 0 if B0 is None else B0.shape[1]
        for name, M, shape in (("F", F, (self.nx, self.nx)), ("Q", Q, (self.nx, self.nx))):
            if self._mat(M, 1.0).shape != shape:
                raise ValueError(f"{name} must be {shape[0]}x{shape[1]}")
        self._key: float | None = None

    @staticmethod
    def _mat(M: Matrix, dt: float) -> np.ndarray:
        return np.asarray(M(dt) if callable(M) else M, dtype=float)

    def _mats(self, dt: float):
        if dt != self._key:
            B = None if self._B is None else self._mat(self._B, dt)
            self._cache = (self._mat(self._F, dt), self._mat(self._Q, dt), B)
            self._key = dt
        return self._cache

    def _drive(self, u, dt: float):
        B = self._mats(dt)[2]
        if B is None:
            return None
        return B @ np.asarray(u, dtype=float).reshape(self.nu)

    # transition ---------------------------------------------------------------------------
    def F(self, x, u, dt: float) -> np.ndarray:
        return self._mats(dt)[0].copy()

    def Q(self, x, u, dt: float) -> np.ndarray:
        return self._mats(dt)[1].copy()

    def FQ(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F, Q, _ = self._mats(dt)
        return F.copy(), Q.copy()

    def f(self, x, u, dt: float) -> np.ndarray:
        x = self._mats(dt)[0] @ np.asarray(x, dtype=float)  # x = F x (+ B u)
        b = self._drive(u, dt)
        return x if b is None else x + b

    def f_batch(self, X: np.ndarray, u, dt: float) -> np.ndarray:
        out = (self._mats(dt)[0] @ X.T).T  # column-major like the TAN fast path
        b = self._drive(u, dt)
        if b is not None:
            out += b
        return out

    # measurement --------------------------------------------------------------------------
    def h(self, x) -> np.ndarray:
        return self._H @ np.asarray(x, dtype=float)

    def H(self, x=None) -> np.ndarray:
        return self._H.copy()

    def h_batch(self, X: np.ndarray) -> np.ndarray:
        return (self._H @ X.T).T

    def compiled_form(self) -> CompiledForm:
        """The model for the compiled Kalman steps: the transition copies ``F(dt)``,
        ``Q(dt)`` and ``b = B(dt) u`` (nothing of a linear model needs compiling), every
        measurement row linear (``H0 = H``), no surface row."""

        def transition(u, dt, F, b, Q):
            Fd, Qd, _ = self._mats(dt)
            F[:] = Fd
            Q[:] = Qd
            drive = self._drive(u, dt)
            b[:] = 0.0 if drive is None else drive

        return CompiledForm(transition, self._H.copy(), -1, (0, 0),
                            Surface(0.0, 0.0, 1.0, 1.0, 2, 2), np.zeros((16, 1)))


def _axis_blocks(per_axis: np.ndarray) -> np.ndarray:
    """Block-diagonal 4x4 from a 2x2 per-axis block in the order ``[px, vx, py, vy]``."""
    M = np.zeros((4, 4))
    M[:2, :2] = per_axis
    M[2:, 2:] = per_axis
    return M


def cv_transition(dt: float) -> np.ndarray:
    """``F`` of the constant-velocity model, state ``[px, vx, py, vy]``."""
    return _axis_blocks(np.array([[1.0, dt], [0.0, 1.0]]))


def cv_noise_gain(dt: float) -> np.ndarray:
    """``G = df/dw`` for noise held over ``dt`` on ``[px', vx', py', vy']``."""
    return _axis_blocks(np.array([[dt, 0.5 * dt * dt], [0.0, dt]]))


def measurement_matrix(names: tuple[str, ...], state_names=CV_STATE_NAMES) -> np.ndarray:
    """``H`` selecting the state named by each ``<sensor>.<state>_m`` measurement."""
    H = np.zeros((len(names), len(state_names)))
    for row, name in enumerate(names):
        var = name.rsplit(".", 1)[-1]
        var = var[:-2] if var.endswith("_m") else var
        var = _ALIASES.get(var, var)
        if var not in state_names:
            raise ScenarioError(
                f"measurement {name!r} names no state of the constant-velocity model "
                f"(expected <sensor>.<state>_m with state in {', '.join(state_names)})"
            )
        H[row, state_names.index(var)] = 1.0
    return H


def constant_velocity_model(
    q_psd=None,
    R=None,
    measurement_names: tuple[str, ...] | None = None,
    Q=None,
    H=None,
) -> LinearModel:
    """The constant-velocity filter model, state ``[px, vx, py, vy]``.

    ``q_psd``: PSDs of the held noise on ``[px', vx', py', vy']`` (FMU-matched, exact
    discretization), or ``Q``: a fixed discrete covariance (seed 001 Table 2). ``H`` defaults to
    the matrix built from ``measurement_names`` or, with no names, to ``I`` (seed 001).
    """
    if (q_psd is None) == (Q is None):
        raise ValueError("give exactly one of q_psd (continuous PSDs) or Q (discrete)")
    if q_psd is not None:
        psd = np.broadcast_to(np.asarray(q_psd, dtype=float), (4,)).copy()

        def Qf(dt: float) -> np.ndarray:
            G = cv_noise_gain(dt)
            return (G * (psd / dt)) @ G.T  # Q = G diag(psd/dt) G'

        Qm: Matrix = Qf
    else:
        Qm = np.asarray(Q, dtype=float)
        Qm = np.diag(Qm) if Qm.ndim == 1 else Qm
    if H is None:
        if measurement_names is None:
            H = np.eye(4)
            measurement_names = tuple(f"{s}_m" for s in CV_STATE_NAMES)
        else:
            H = measurement_matrix(tuple(measurement_names))
    H = np.atleast_2d(np.asarray(H, dtype=float))
    if R is None:
        R = np.eye(H.shape[0])
    return LinearModel(cv_transition, H, Qm, R, state_names=CV_STATE_NAMES,
                       measurement_names=measurement_names)


def seed001_model() -> LinearModel:
    """Seed 001 Table 2: ``H = I``, ``Q = 1e-3 diag(1, 0.5, 1, 0.5)``, ``R = I`` (``P0 = I``)."""
    return constant_velocity_model(Q=1e-3 * np.diag([1.0, 0.5, 1.0, 0.5]), R=np.eye(4))
