"""Compiled transition of the TAN model (Numba, optional): ``F``, ``b`` and ``Q`` of a step.

:func:`transition` is the compiled ``f``/``F`` that :meth:`uwcosim.models.tan.TANModel.
compiled_form` hands to the compiled Kalman steps: the exact step of
:mod:`uwcosim.models.tan` (``x' = F x + b + G w``) for the controls ``(psi, a)`` held over
``dt``, with ``Q = G diag(psd/dt) G'``. ``F`` and ``b`` are the numbers of ``TANModel._mats``
(the same scalar operations); ``Q`` is summed by loops in index order where the numpy form calls
BLAS, so it may differ from ``TANModel.Q`` in the last bit (``tests/test_kalman_compiled.py``).
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit


@jit
def transition(u, dt, psd, F, b, Q):
    """Write ``F``, ``b``, ``Q`` of the step over ``dt`` with the controls ``u = (psi, a)``."""
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
