"""Compiled transitions ``x' = F x + b + w`` that models and the compiled Kalman steps share.

A model's :class:`~uwcosim.models.protocol.CompiledForm` names its transition by a code
(``motion``) with its parameters (``params``) when it is one of the kernels here, so that a
compiled Kalman step evaluates it inside its own compiled call (one call per step, no Python in
between), as :mod:`uwcosim.core.bicubic` is the terrain surface both sides evaluate. A
transition that is not here is :data:`GIVEN`: the model's Python ``transition`` writes ``F``,
``b``, ``Q`` before the filter's kernel runs. (Numba passes no function to a kernel cheaply:
a compiled function as an argument costs 8-16 us per call to type, against about 0.1 us for
an array, measured with Numba 0.68; hence codes, not functions.)

- :data:`HEADING`: the TAN model's step (:mod:`uwcosim.models.tan`): the exact step of
  ``x = [x, y, vx, vy]`` for the controls ``(psi, a)`` held over ``dt``, ``params`` the process
  noise PSDs; :func:`heading_step`.

``F`` and ``b`` of :func:`heading_step` are the numbers of ``TANModel._mats`` (the same scalar
operations); ``Q`` is summed by loops in index order where the numpy form calls BLAS, so it may
differ from ``TANModel.Q`` in the last bit (``tests/test_kalman_compiled.py``).
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit

GIVEN = 0  #: the caller writes F, b, Q (the model's Python transition)
HEADING = 1  #: :func:`heading_step`


@jit
def heading_step(u, dt, psd, F, b, Q):
    """Write ``F``, ``b``, ``Q`` of the TAN step over ``dt`` with the controls ``u = (psi, a)``
    and the process noise PSDs ``psd``."""
    psi = u[0]
    a = u[1]
    c = math.cos(psi)
    s = math.sin(psi)
    h2 = 0.5 * dt * dt
    F[:, :] = 0.0
    for i in range(4):
        F[i, i] = 1.0
    F[0, 2] = dt * c  # F = [[I, dt Rot], [0, I]]
    F[0, 3] = -dt * s
    F[1, 2] = dt * s
    F[1, 3] = dt * c
    G = np.zeros((4, 4))  # G = [[dt I, dt^2/2 Rot], [0, dt I]]
    G[0, 0] = dt
    G[1, 1] = dt
    G[0, 2] = h2 * c
    G[0, 3] = -h2 * s
    G[1, 2] = h2 * s
    G[1, 3] = h2 * c
    G[2, 2] = dt
    G[3, 3] = dt
    b[0] = h2 * a * (c * c - s * s)  # b = [dt^2/2 Rot a e, dt a e]
    b[1] = h2 * a * 2.0 * s * c
    b[2] = dt * a * c
    b[3] = dt * a * s
    for i in range(4):  # Q = G diag(psd/dt) G'
        for j in range(4):
            q = 0.0
            for k in range(4):
                q += G[i, k] * (psd[k] / dt) * G[j, k]
            Q[i, j] = q
    for i in range(4):  # Q = (Q + Q') / 2
        for j in range(i + 1, 4):
            v = 0.5 * (Q[i, j] + Q[j, i])
            Q[i, j] = v
            Q[j, i] = v


@jit
def write(motion, u, dt, params, F, b, Q):
    """``F``, ``b``, ``Q`` of the step for the transition ``motion`` (nothing for
    :data:`GIVEN`)."""
    if motion == HEADING:
        heading_step(u, dt, params, F, b, Q)
