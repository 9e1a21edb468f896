"""The state-space model as the filters see it: the :class:`StateSpaceModel` protocol.

This is the one module of :mod:`uwcosim.models` the filters import (``lint-imports`` checks
it): a filter uses whatever model it is given through these names, and which implementation
that is (the closed-form TAN model, a CasADi model, a linear model, a user's own) is decided
where the model is built (:mod:`uwcosim.run.factory`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class StateSpaceModel(Protocol):
    """Discrete-time model ``x' = f(x, u, dt) + noise``, ``z = h(x) + v`` seen by the filters.

    ``F``, ``H`` are Jacobians; ``Q(x, u, dt)`` the discrete process covariance and ``R`` the
    measurement covariance over the full measurement vector (components named in
    ``measurement_names``). Batch forms take ``X`` of shape ``(N, nx)``.
    """

    nx: int
    nz: int
    state_names: tuple[str, ...]
    measurement_names: tuple[str, ...]
    R: np.ndarray

    def f(self, x: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray: ...
    def F(self, x: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray: ...
    def Q(self, x: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray: ...
    def h(self, x: np.ndarray) -> np.ndarray: ...
    def H(self, x: np.ndarray) -> np.ndarray: ...
    def f_batch(self, X: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray: ...
    def h_batch(self, X: np.ndarray) -> np.ndarray: ...
