"""RK4 is written once in Python (:func:`uwcosim.core.integrators.rk4`, numeric and CasADi); the C
template's co-simulation step (``rk4`` in ``uwc_model.c``) is tested against it here, on a
nonlinear test model (a pendulum) for which RK4 is not exact."""

from __future__ import annotations

import casadi as ca
import numpy as np

from uwcosim.core.integrators import rk4
from uwcosim.fmu import build_fmu, specs
from uwcosim.fmu.specs import ModelSpec, Var
from uwcosim.models.auv_equations import rk4_step

try:
    from fmu_fixtures import CS, Instance
except ImportError:  # tests/ imported as a package
    from tests.fmu_fixtures import CS, Instance

X0 = np.array([1.0, 0.0])


def _pendulum(x, u, p, z):
    return ca.vertcat(x[1], -ca.sin(x[0])), ca.SX(0, 1)


def _spec() -> ModelSpec:  # units of length: the FMU units table has no rad/s
    return ModelSpec(
        name="Pendulum", description="Test model: th' = om, om' = -sin(th)",
        equations=_pendulum,
        states=(Var("th", "m", X0[0], "Angle (rad)", der_unit="m/s"),
                Var("om", "m/s", X0[1], "Angular rate (rad/s)", der_unit="m/s2")),
        params=(specs._MAX_STEP,))


def test_c_template_rk4_equals_the_python_rk4(tmp_path, monkeypatch):
    monkeypatch.setitem(specs.MODELS, "Pendulum", _spec)
    ode = _spec().functions()[0]
    h, max_step = 1.0, 0.25  # four internal steps per doStep

    def deriv(t, x):
        return np.array(ode(x, [], [max_step])).ravel()

    expected = rk4(deriv, X0, 0.0, h, 4)
    symbolic = np.array(rk4_step(ode, 4)(X0, [], [max_step], h)).ravel()
    np.testing.assert_allclose(symbolic, expected, rtol=1e-14, atol=1e-15)
    # RK4 is not exact here: a formula error of the C form would show
    assert np.max(np.abs(rk4(deriv, X0, 0.0, h, 64) - expected)) > 1e-7

    inst = Instance(build_fmu("Pendulum", "3.0", tmp_path / "Pendulum.fmu"), CS)
    try:
        inst.set(max_internal_step=max_step)
        inst.init()
        inst.step(0.0, h)
        np.testing.assert_allclose(inst.get("th", "om"), expected, rtol=1e-14, atol=1e-15)
    finally:
        inst.free()
