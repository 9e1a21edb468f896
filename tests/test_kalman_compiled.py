"""The compiled Kalman steps (``compiled = true``) against the numpy steps, and dead reckoning
without terrain work.

The compiled steps (:mod:`uwcosim.filters.kalman_kernels`, :mod:`uwcosim.filters.sigma_kernels`)
sum in index order where the numpy steps call BLAS/LAPACK, so the two agree to round-off, not
bit for bit: over 400 TAN steps (positions near 1e4 m, a terrain likelihood that amplifies
differences) within 1e-8 m and 1e-9 relative in ``P``; measured 5e-13 m (EKF) to 8e-11 m
(CUKF). The parts that are the same arithmetic (the terrain row, ``F`` and ``b`` of the
transition) are checked bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core import bicubic, jit, kinematics
from uwcosim.core.errors import FilterDivergence, ScenarioError
from uwcosim.filters import kalman, sigma_point  # noqa: F401  (registers the filters)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.models import tan as tan_module
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.models.trajectory import simulate

needs_numba = pytest.mark.skipif(not jit.ENABLED, reason="Numba not installed or disabled")

STD0 = np.array([30.0, 30.0, 0.05, 0.05])
START = np.array([2000.0, 18000.0, 0.5, 0.0])
KINDS = ["ekf", "ukf", "ckf", "cukf", "dead_reckoning"]


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 100 else 0.0])


@pytest.fixture(scope="module")
def model():
    return tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7))


@pytest.fixture(scope="module")
def data(model):
    rng = np.random.default_rng(3)
    _, _, zs = simulate(model.symbolic, START, controls, 400, rng)
    return zs, START + STD0 * rng.standard_normal(4)


def run(model, kind, zs, x0, **settings):
    est = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), **settings)
    xs, Ps, nis = [], [], []
    for k, z in enumerate(zs):
        est.predict(controls(k), 1.0)
        mask = None if k % 3 else np.array([True, True, False])  # terrain lost every 3rd
        est.update(None if k % 17 == 5 else z, mask)  # and no data at all now and then
        xs.append(est.x.copy())
        Ps.append(est.P.copy())
        nis.append(est.diagnostics.get("nis", np.nan))
    return np.array(xs), np.array(Ps), np.array(nis), est


@needs_numba
@pytest.mark.parametrize("kind", KINDS)
def test_compiled_step_equals_numpy_step(model, data, kind):
    zs, x0 = data
    xn, Pn, nn, _ = run(model, kind, zs, x0)
    xc, Pc, nc, est = run(model, kind, zs, x0, compiled=True)
    assert est.workspace is not None
    np.testing.assert_allclose(xc, xn, rtol=0, atol=1e-8)
    np.testing.assert_allclose(Pc, Pn, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(nc, nn, rtol=1e-8, equal_nan=True)
    assert np.isnan(nn[5]) and np.isnan(nc[5])  # no data: no NIS
    assert est.diagnostics["pd_repairs"] == 0.0


@needs_numba
def test_terrain_row_and_transition_are_the_models_bits(model):
    surface, table = model.compiled_form().surface, model.compiled_form().table
    rng = np.random.default_rng(0)
    for x, y in zip(rng.uniform(-500, 25500, 300), rng.uniform(-500, 25500, 300), strict=True):
        h, gx, gy = bicubic.value_gradient(table, *surface, x, y)
        H = model.H(np.array([x, y, 0.0, 0.0]))
        assert (h, gx, gy) == (model.h(np.array([x, y, 0.0, 0.0]))[2], H[2, 0], H[2, 1])
        assert bicubic.value(table, *surface, x, y) == h
    F, b, Q = np.empty((4, 4)), np.empty(4), np.empty((4, 4))
    for k in range(50):
        u = controls(7 * k)
        kinematics.heading_step(u, 1.0, model.q_psd, F, b, Q)
        assert np.array_equal(F, model.F(START, u, 1.0))
        assert np.array_equal(b, model.f(np.zeros(4), u, 1.0))  # f(0) = F 0 + b = b
        Qn = model.Q(START, u, 1.0)  # BLAS's FMA leaves 1e-26 where the loops cancel to 0
        np.testing.assert_allclose(Q, Qn, rtol=1e-14, atol=1e-14 * np.abs(Qn).max())


def test_dead_reckoning_does_no_terrain_work(model, data, monkeypatch):
    """Its numpy step gives the bits of the EKF on the velocity rows, without one lookup."""
    zs, x0 = data
    dvl = ["dvl.vx_m", "dvl.vy_m"]
    xe, Pe, ne, _ = run(model, "ekf", zs[:100], x0, measurements=dvl)
    calls = []
    point = tan_module.FastTerrain.point
    monkeypatch.setattr(tan_module.FastTerrain, "point",
                        lambda self, x, y: calls.append(1) or point(self, x, y))
    xd, Pd, nd, _ = run(model, "dead_reckoning", zs[:100], x0)
    assert not calls
    assert np.array_equal(xd, xe) and np.array_equal(Pd, Pe)
    assert np.array_equal(nd, ne, equal_nan=True)
    if jit.ENABLED:
        xc, _, _, _ = run(model, "dead_reckoning", zs[:100], x0, compiled=True)
        np.testing.assert_allclose(xc, xd, rtol=0, atol=1e-9)
        assert not calls


@needs_numba
def test_compiled_needs_a_compiled_form(data):
    plain = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7),
                      control_psd=[1e-6, 1e-8])  # Q depends on x: no compiled form
    assert plain.compiled_form() is None
    cls = ESTIMATORS.get("ukf")
    with pytest.raises(ScenarioError, match="compiled = true needs a model with a compiled"):
        cls.from_settings(plain, START, np.diag(STD0**2), {"compiled": True}, where="[x]")


@needs_numba
@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_compiled_with_a_gate_is_refused(model, kind):
    """The chi-square gate (filters.gating) runs in the numpy step only: the pair is refused in
    one line rather than the gate silently skipped."""
    cls = ESTIMATORS.get(kind)
    with pytest.raises(ScenarioError, match="compiled = true has no chi-square gate"):
        cls.from_settings(model, START, np.diag(STD0**2),
                          {"compiled": True, "gate_probability": 0.999}, where="[x]")


@needs_numba
@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_compiled_divergence_is_the_numpy_error(model, data, kind):
    zs, x0 = data
    messages = []
    for compiled in (False, True):
        est = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), compiled=compiled)
        est.P[0, 0] = np.nan
        with pytest.raises(FilterDivergence) as err:
            est.predict(controls(0), 1.0)
        messages.append(str(err.value))
    if kind == "ekf":
        assert messages[0] == messages[1] == "ekf prediction contains NaN or inf"
    else:  # LAPACK's factorization may pass the NaN on; the loops' stops at it
        assert all(m.endswith("contains NaN or inf") for m in messages)


@needs_numba
def test_compiled_kalman_filter_on_a_linear_model():
    """``kf`` compiled on a linear model (its compiled form copies ``F``, ``Q``, ``B u``)."""
    from uwcosim.models.linear import seed001_model

    lin = seed001_model()
    rng = np.random.default_rng(5)
    zs = rng.standard_normal((200, lin.nz)) + np.linspace(0, 50, 200)[:, None]
    zs[::7, 0] = np.nan  # a component lost now and then
    out = []
    for compiled in (False, True):
        est = ESTIMATORS.get("kf")(lin, np.zeros(lin.nx), np.eye(lin.nx), compiled=compiled)
        xs = []
        for z in zs:
            est.predict(np.zeros(lin.nu), 1.0)
            est.update(z)
            xs.append(est.x.copy())
        out.append((np.array(xs), est.P.copy()))
    assert est.workspace is not None
    np.testing.assert_allclose(out[1][0], out[0][0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[1][1], out[0][1], rtol=1e-12, atol=1e-15)


def run_steps(model, kind, zs, x0, **settings):
    """As :func:`run`, through ``est.step`` (the bank's one call; compiled: one kernel)."""
    est = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), **settings)
    xs, Ps, diags = [], [], []
    for k, z in enumerate(zs):
        mask = None if k % 3 else np.array([True, True, False])
        est.step(controls(k), 1.0, None if k % 17 == 5 else z, mask, t=float(k + 1))
        assert est.t == float(k + 1)
        xs.append(est.x.copy())
        Ps.append(est.P.copy())
        diags.append(dict(est.diagnostics))
    return np.array(xs), np.array(Ps), diags, est


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("kind", KINDS)
def test_whole_step_is_predict_then_update(model, data, kind, compiled):
    """``step`` (the EKF's and the UKF/CKF's one compiled call) gives the bits and the
    diagnostics of ``predict`` then ``update``, numpy or compiled."""
    if compiled and not jit.ENABLED:
        pytest.skip("Numba not installed or disabled")
    zs, x0 = data
    xs, Ps, diags, est = run_steps(model, kind, zs, x0, compiled=compiled)
    ref = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), compiled=compiled)
    for k, z in enumerate(zs):
        ref.predict(controls(k), 1.0)
        mask = None if k % 3 else np.array([True, True, False])
        ref.update(None if k % 17 == 5 else z, mask)
        assert np.array_equal(xs[k], ref.x) and np.array_equal(Ps[k], ref.P), k
        assert diags[k] == ref.diagnostics, k
    assert "nis" not in diags[5] and "nis" in diags[6]


@needs_numba
def test_whole_step_takes_arrays_set_from_outside(model, data):
    """``x`` and ``P`` live in the compiled workspace during whole steps; arrays assigned to
    the filter are copied in at the next step, not ignored."""
    zs, x0 = data
    a = ESTIMATORS.get("ekf")(model, x0, np.diag(STD0**2), compiled=True)
    b = ESTIMATORS.get("ekf")(model, x0, np.diag(STD0**2))
    for k in range(20):
        if k == 10:
            a.x, a.P = b.x.copy() + 1.0, b.P.copy() * 2.0
            b.x, b.P = b.x + 1.0, b.P * 2.0
        a.step(controls(k), 1.0, zs[k])
        b.step(controls(k), 1.0, zs[k])
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.P, b.P, rtol=1e-12, atol=1e-15)


@needs_numba
@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_whole_step_divergence_is_the_numpy_error(model, kind):
    """A whole step that fails in its prediction says so, as ``predict`` does."""
    messages = []
    for compiled in (False, True):
        est = ESTIMATORS.get(kind)(model, START, np.diag(STD0**2), compiled=compiled)
        est.x[0] = np.inf
        with pytest.raises(FilterDivergence) as err, np.errstate(invalid="ignore"):
            est.step(controls(0), 1.0, None)
        messages.append(str(err.value))
    assert messages[0] == messages[1] == f"{kind} prediction contains NaN or inf"


@needs_numba
def test_whole_step_on_a_linear_model():
    """The linear model's transition is not compiled in (``GIVEN``): the whole step calls it
    first, then its one kernel; equal to the numpy step to round-off."""
    from uwcosim.models.linear import seed001_model

    lin = seed001_model()
    rng = np.random.default_rng(5)
    zs = rng.standard_normal((200, lin.nz)) + np.linspace(0, 50, 200)[:, None]
    zs[::7, 0] = np.nan
    out = []
    for compiled in (False, True):
        est = ESTIMATORS.get("kf")(lin, np.zeros(lin.nx), np.eye(lin.nx), compiled=compiled)
        xs = []
        for z in zs:
            est.step(np.zeros(lin.nu), 1.0, z)
            xs.append(est.x.copy())
        out.append((np.array(xs), est.P.copy()))
    assert est.workspace.given
    np.testing.assert_allclose(out[1][0], out[0][0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[1][1], out[0][1], rtol=1e-12, atol=1e-15)


def test_exact_is_the_one_type_of_the_entry_points():
    """:func:`kalman_kernels.exact` accepts only what the entry points were resolved for: a
    native, C-contiguous, writeable, aligned array of the dtype and dimensions asked for."""
    from uwcosim.filters.kalman_kernels import BOOL, F8, exact

    a = np.zeros(4)
    readonly = np.zeros(4)
    readonly.flags.writeable = False
    assert exact(a, F8, 1) and exact(np.ones(3, dtype=bool), BOOL, 1)
    assert exact(np.zeros((4, 4)), F8, 2)
    for other, ndim in ((np.zeros(8)[::2], 1), (readonly, 1), (np.zeros(4, dtype=">f8"), 1),
                        (np.zeros(4, int), 1), (np.zeros((4, 1)), 1), ([0.0] * 4, 1),
                        (np.asfortranarray(np.ones((4, 3))), 2), (np.zeros(4, np.float32), 1)):
        assert not exact(other, F8, ndim), other
    assert not exact(np.zeros(3), BOOL, 1) and not exact(np.zeros((4, 4)), F8, 1)


@needs_numba
@pytest.mark.parametrize("kind", ["ekf", "ukf", "cukf"])
def test_entry_points_are_the_dispatchers_bits(model, data, kind):
    """The steps call their kernels' entry points (no dispatcher); arguments of another type
    (here a strided ``z`` and an F-ordered ``P``) go through the dispatcher: the same bits."""
    zs, x0 = data
    a = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), compiled=True)
    b = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), compiled=True)
    for k in range(60):
        mask = None if k % 3 else np.array([True, True, False])
        a.step(controls(k), 1.0, zs[k], mask)
        # from step 10 (the entry points are resolved at the first): the same values, strided
        z = zs[k] if k < 10 else np.repeat(zs[k], 2)[::2]
        if k == 30 and kind == "cukf":  # the halves take the filter's own P
            b.P = np.asfortranarray(b.P)
        b.step(controls(k), 1.0, z, mask)
        assert np.array_equal(a.x, b.x) and np.array_equal(a.P, b.P), k
    assert a.workspace.entries
