"""The classical fourth-order Runge-Kutta step, written once.

:func:`rk4` is plain arithmetic on ``x`` and ``deriv(t, x)``, so the same code integrates
numbers (numpy: the master's model-exchange fast path, :mod:`uwcosim.fmi.solvers`) and
symbols (CasADi: the filters' discrete transition, :func:`uwcosim.models.auv_equations.rk4_step`).
The C form (``rk4`` in ``uwcosim/fmu/templates/uwc_model.c``, the FMUs' co-simulation step)
is tested against it (``tests/test_rk4.py``).
"""

from __future__ import annotations


def rk4(deriv, x, t, h, substeps: int):
    """``substeps`` classical Runge-Kutta steps of ``dx/dt = deriv(t, x)`` from ``t`` to
    ``t + h`` (equal steps ``h / substeps``)."""
    dt = h / substeps
    for i in range(substeps):
        ti = t + i * dt
        k1 = deriv(ti, x)
        k2 = deriv(ti + dt / 2, x + dt / 2 * k1)
        k3 = deriv(ti + dt / 2, x + dt / 2 * k2)
        k4 = deriv(ti + dt, x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x
