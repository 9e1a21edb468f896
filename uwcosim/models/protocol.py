"""The state-space model as the filters see it: the :class:`StateSpaceModel` protocol.

This is the one module of :mod:`uwcosim.models` the filters import (``lint-imports`` checks
it): a filter uses whatever model it is given through these names, and which implementation
that is (the closed-form TAN model, a CasADi model, a linear model, a user's own) is decided
where the model is built (:mod:`uwcosim.run.factory`). A model may also offer its
:class:`CompiledForm` for the compiled Kalman steps.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np

from uwcosim.core.bicubic import Surface


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


class CompiledForm(NamedTuple):
    """A model in the form the compiled Kalman steps evaluate (``model.compiled_form()``,
    optional: a model without it, or returning None, runs the numpy steps only).

    The transition is affine in the state for a given ``(u, dt)``: ``x' = F x + b + w``,
    ``w ~ N(0, Q)``; ``transition(u, dt, F, b, Q)`` writes ``F``, ``b`` and ``Q`` into the
    caller's arrays (the model's compiled ``f`` and ``F``). The measurements are rows linear in
    the state, ``h_r(x) = H0[r] x``, except at most one row ``surface_row`` that is a surface of
    the two states ``surface_states`` stored as per-cell bicubic polynomials
    (:mod:`uwcosim.core.bicubic`: ``table`` and its ``surface`` geometry), the terrain depth of
    a TAN model; ``-1`` for none (``table`` is then a dummy).

    ``motion`` names the transition when it is one of the compiled transitions of
    :mod:`uwcosim.core.kinematics` (its code, with its ``params``): a compiled step then
    evaluates it inside its own call; :data:`~uwcosim.core.kinematics.GIVEN` (the default): the
    step calls ``transition`` first.
    """

    transition: Callable[..., None]
    H0: np.ndarray
    surface_row: int
    surface_states: tuple[int, int]
    surface: Surface
    table: np.ndarray
    motion: int = 0  #: a transition code of :mod:`uwcosim.core.kinematics` (0: GIVEN)
    params: tuple[float, ...] = ()  #: the parameters of ``motion``
