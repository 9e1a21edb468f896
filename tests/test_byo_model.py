"""A user's model (docs/your_own_model.md): ``uwcosim.models.from_casadi`` against closed forms
(a linear-Gaussian model where the Kalman filter is exact: KF, EKF, UKF and PF on it; the TAN
model with the map's terrain in ``h``), ``[model] type`` builders and their one-line errors,
the example's model with every general filter, and what the structured filters say today."""

from __future__ import annotations

import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

try:
    from byo_example import SCENARIO, example_fmus
except ImportError:  # pragma: no cover - run from the project root as a package
    from tests.byo_example import SCENARIO, example_fmus

from uwcosim.core.errors import ScenarioError
from uwcosim.filters.base import build
from uwcosim.models import ModelContext, from_casadi
from uwcosim.models.linear import constant_velocity_model
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.run.preflight import check_scenario
from uwcosim.run.simulate import simulate
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario

__all__ = ["example_fmus"]  # the fixture

ROOT = Path(__file__).resolve().parents[1]
TAN = ROOT / "scenarios" / "tan_terrain.toml"
PSD = [0.02, 1e-3, 0.02, 1e-3]
NAMES = ("gps.px_m", "gps.py_m")


# -- closed form: a linear-Gaussian model, where the Kalman filter is exact -----------------
def _cv_symbols():
    return [ca.SX.sym(n) for n in ("px", "vx", "py", "vy")]


def cv_continuous():
    px, vx, py, vy = _cv_symbols()
    return from_casadi(states=[px, vx, py, vy], f=[vx, 0, vy, 0], h=[px, py], Q=PSD,
                       R=[4.0, 4.0], measurements=NAMES)


def cv_discrete():
    px, vx, py, vy = _cv_symbols()
    dt = ca.SX.sym("dt")
    G = ca.vertcat(ca.horzcat(dt, dt**2 / 2, 0, 0), ca.horzcat(0, dt, 0, 0),
                   ca.horzcat(0, 0, dt, dt**2 / 2), ca.horzcat(0, 0, 0, dt))
    Q = G @ ca.diag(ca.SX(PSD) / dt) @ G.T  # the exact discrete covariance of held noise
    return from_casadi(states=[px, vx, py, vy], f=[px + dt * vx, vx, py + dt * vy, vy],
                       h=[px, py], Q=Q, R=np.diag([4.0, 4.0]), measurements=NAMES,
                       time="discrete", dt=dt)


def reference():
    return constant_velocity_model(q_psd=PSD, R=np.diag([4.0, 4.0]), measurement_names=NAMES)


def _data(n=150, dt=1.0, seed=5):
    rng = np.random.default_rng(seed)
    ref = reference()
    x = np.array([0.0, 1.0, 0.0, 0.5])
    zs = []
    for _ in range(n):
        x = ref.f(x, np.zeros(0), dt) + rng.multivariate_normal(np.zeros(4), ref.Q(x, 0, dt))
        z = x[[0, 2]] + rng.normal(0.0, 2.0, 2)
        if rng.random() < 0.2:
            z[rng.integers(2)] = np.nan  # lost components
        zs.append(z)
    return zs


def _filter(est, zs, dt=1.0):
    X, P = [], []
    for z in zs:
        est.predict(np.zeros(0), dt)
        est.update(z, np.isfinite(z))
        X.append(est.x.copy())
        P.append(est.P.copy())
    return np.array(X), np.array(P)


@pytest.mark.parametrize("make", [cv_continuous, cv_discrete])
def test_from_casadi_reproduces_the_linear_gaussian_model(make):
    m, ref = make(), reference()
    assert m.linear and not m.Q_depends_on_x and m.nu == 0
    assert m.state_names == ("px", "vx", "py", "vy") and m.measurement_names == NAMES
    rng = np.random.default_rng(0)
    u = np.zeros(0)
    for dt in (0.5, 1.0, 2.0):
        x = rng.normal(size=4)
        np.testing.assert_allclose(m.f(x, u, dt), ref.f(x, u, dt), atol=1e-12)
        np.testing.assert_allclose(m.F(x, u, dt), ref.F(x, u, dt), atol=1e-12)
        np.testing.assert_allclose(m.Q(x, u, dt), ref.Q(x, u, dt), rtol=1e-12, atol=1e-15)
        X = rng.normal(size=(7, 4))
        np.testing.assert_allclose(m.f_batch(X, u, dt), ref.f_batch(X, u, dt), atol=1e-12)
        np.testing.assert_allclose(m.h_batch(X), ref.h_batch(X), atol=1e-12)
    np.testing.assert_array_equal(m.H(x), ref.H(x))
    np.testing.assert_array_equal(m.R, ref.R)


@pytest.mark.parametrize("make", [cv_continuous, cv_discrete])
def test_kf_ekf_and_ukf_on_it_are_the_exact_kalman_filter(make):
    m, zs = make(), _data()
    x0, P0 = np.array([0.0, 0.0, 0.0, 0.0]), np.diag([100.0, 1.0, 100.0, 1.0])
    Xr, Pr = _filter(build("kf", reference(), x0, P0, {}), zs)
    for kind, tol in (("kf", 1e-9), ("ekf", 1e-9), ("ukf", 1e-7), ("ckf", 1e-7)):
        X, P = _filter(build(kind, m, x0, P0, {}), zs)
        np.testing.assert_allclose(X, Xr, rtol=tol, atol=tol, err_msg=kind)
        np.testing.assert_allclose(P, Pr, rtol=tol, atol=tol, err_msg=kind)


def test_pf_on_it_converges_to_the_kalman_filter():
    m, zs = cv_continuous(), _data(n=100)
    x0, P0 = np.array([0.0, 0.0, 0.0, 0.0]), np.diag([100.0, 1.0, 100.0, 1.0])
    Xr, Pr = _filter(build("kf", reference(), x0, P0, {}), zs)
    X, P = _filter(build("pf", m, x0, P0, {"n_particles": 5000},
                         rng=np.random.default_rng(1)), zs)
    var = np.diagonal(Pr, axis1=1, axis2=2)
    # the particle mean is within a fraction of the exact posterior's standard deviation
    assert np.mean((X - Xr) ** 2 / var) < 0.05
    ratio = np.diagonal(P, axis1=1, axis2=2)[10:] / var[10:]
    assert 0.7 < np.median(ratio) < 1.3


def test_kf_refuses_a_nonlinear_model():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    m = from_casadi(states=[x, y], f=[0, 0], h=[ca.sqrt(x**2 + y**2)], Q=[1, 1], R=[1])
    assert not m.linear
    with pytest.raises(ValueError, match="needs a linear model"):
        build("kf", m, np.ones(2), np.eye(2), {})


# -- closed form: the TAN model written with from_casadi, terrain from the context ----------
TAN_BUILDER = '''
"""The TAN model of seed 000 eq. 54-55 written by a user with from_casadi."""
import casadi as ca

from uwcosim.models import from_casadi


def build(context):
    x, y, vx, vy = (ca.MX.sym(n) for n in ("x", "y", "vx", "vy"))
    psi, a = ca.MX.sym("psi"), ca.MX.sym("a")
    c, s = ca.cos(psi), ca.sin(psi)
    h = [vx, vy]
    if len(context.measurement_names) == 3:
        h.append(context.terrain(ca.vertcat(x, y)))
    return from_casadi(states=[x, y, vx, vy], controls=[psi, a],
                       f=[vx * c - vy * s, vy * c + vx * s, a * c, a * s], h=h,
                       Q=context.q_psd, R=context.R, measurements=context.measurement_names)


def raises(context):
    raise RuntimeError("nope")


def wrong_names(context):
    m = build(context)
    m.measurement_names = ("a", "b", "c")
    return m


def three_states(context):
    x, y, z = (ca.SX.sym(n) for n in "xyz")
    return from_casadi(states=[x, y, z], f=[0, 0, 0], h=[x, y, z], Q=[1, 1, 1],
                       R=context.R, measurements=context.measurement_names,
                       controls=[ca.SX.sym("psi"), ca.SX.sym("a")])


def not_a_model(context):
    return 42


def discrete(context):
    x, y, vx, vy = (ca.SX.sym(n) for n in ("x", "y", "vx", "vy"))
    dt = ca.SX.sym("dt")
    u = ca.SX.sym("u", 2)
    return from_casadi(states=[x, y, vx, vy], controls=u, f=[x + dt * vx, y + dt * vy, vx, vy],
                       h=[vx, vy, x + y], Q=[1.0, 1.0, 1e-4, 1e-4], R=context.R,
                       measurements=context.measurement_names, time="discrete", dt=dt)


class Hand:
    """A model of the protocol written in numpy (no CasADi)."""

    def __init__(self, base):
        self._b = base
        self.nx, self.nz, self.R = base.nx, base.nz, base.R
        self.state_names, self.measurement_names = base.state_names, base.measurement_names

    def f(self, x, u, dt):
        return self._b.f(x, u, dt)

    def F(self, x, u, dt):
        return self._b.F(x, u, dt)

    def Q(self, x, u, dt):
        return self._b.Q(x, u, dt)

    def h(self, x):
        return self._b.h(x)

    def H(self, x):
        return self._b.H(x)

    def f_batch(self, X, u, dt):
        return self._b.f_batch(X, u, dt)

    def h_batch(self, X):
        return self._b.h_batch(X)


def hand(context):
    return Hand(build(context))
'''


@pytest.fixture(scope="session")
def tan_copy(tmp_path_factory) -> Path:
    """``tan_terrain.toml`` without ``kind`` (absolute FMU paths) beside the builders of
    ``byo_tan_models``; the folder is the scenario's, so it is searched for them."""
    d = tmp_path_factory.mktemp("tan_user")
    (d / "byo_tan_models.py").write_text(TAN_BUILDER)
    text = TAN.read_text().replace('kind = "tan"\n', 'type = "byo_tan_models:build"\n')
    text = text.replace('path = "../fmus/', f'path = "{ROOT}/fmus/')
    (d / "tan_user.toml").write_text(text)
    return d / "tan_user.toml"


def _context(bathy):
    names = ("dvl.vx_m", "dvl.vy_m", "sounder.depth_m")
    return ModelContext(measurement_names=names,
                        sigma={"dvl.vx_m": 0.05, "dvl.vy_m": 0.05, "sounder.depth_m": 1.0},
                        q_psd=(0.05, 0.05, 1e-5, 1e-5), controls=("psi", "a"),
                        bathymetry=bathy)


def test_terrain_in_h_reproduces_the_tan_model(tan_copy):
    import importlib
    import sys

    sys.path.insert(0, str(tan_copy.parent))
    try:
        builders = importlib.import_module("byo_tan_models")
    finally:
        sys.path.remove(str(tan_copy.parent))
    bathy = synthetic_bathymetry(3, (0.0, 5000.0, 0.0, 5000.0), 50.0)
    ctx = _context(bathy)
    m = builders.build(ctx)
    ref = tan_model([0.05, 0.05, 1e-5, 1e-5], [0.05, 0.05], 1.0, bathy, ctx.measurement_names)
    assert not m.linear and m.nu == 2 and ctx.terrain is ctx.terrain  # built once
    rng = np.random.default_rng(2)
    for _ in range(5):
        x = np.array([rng.uniform(500, 4500), rng.uniform(500, 4500), rng.normal(), rng.normal()])
        u, dt = np.array([rng.uniform(-3, 3), rng.normal() * 1e-3]), 1.0
        np.testing.assert_allclose(m.f(x, u, dt), ref.f(x, u, dt), rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(m.F(x, u, dt), ref.F(x, u, dt), atol=1e-12)
        np.testing.assert_allclose(m.Q(x, u, dt), ref.Q(x, u, dt), rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(m.h(x), ref.h(x), rtol=1e-10)
        np.testing.assert_allclose(m.H(x), ref.H(x), rtol=1e-8, atol=1e-10)
    X = np.column_stack([rng.uniform(500, 4500, 50), rng.uniform(500, 4500, 50),
                         rng.normal(size=50), rng.normal(size=50)])
    np.testing.assert_allclose(m.h_batch(X), ref.h_batch(X), rtol=1e-10)
    np.testing.assert_allclose(m.f_batch(X, u, dt), ref.f_batch(X, u, dt), rtol=1e-12,
                               atol=1e-9)


def test_a_user_model_in_the_tan_scenario_gives_the_built_in_models_estimates(project_fmus,
                                                                              tan_copy,
                                                                              tmp_path):
    est = 'estimators={ekf={type="ekf"}, ukf={type="ukf"}, pf={type="pf", n_particles=300}}'
    common = ["run.duration=100", "output.density_snapshots=[]", est]
    user = simulate(load_scenario(tan_copy, common), tmp_path / "user", seed=3)
    ours = simulate(load_scenario(TAN, common), tmp_path / "ours", seed=3)
    cu, meta = read_log(user / "log.parquet")
    co, _ = read_log(ours / "log.parquet")
    assert meta["user_code"]["model"]["type"] == "byo_tan_models:build"
    for kind in ("ekf", "ukf"):
        for s in ("x", "y", "vx", "vy"):
            np.testing.assert_allclose(cu[f"est.{kind}.{s}"], co[f"est.{kind}.{s}"],
                                       rtol=1e-7, atol=1e-6, err_msg=(kind, s))
    s = json.loads((user / "summary.json").read_text())["estimators"]
    o = json.loads((ours / "summary.json").read_text())["estimators"]
    # the particle filter draws other numbers (a Cholesky factor of Q, not the TAN model's
    # closed-form factor): another realization of the same filter
    assert not s["pf"]["diverged"]
    assert s["pf"]["rmse_position_m"] < 10 * o["ekf"]["rmse_position_m"]


# -- [model] type: builders and their one-line errors ---------------------------------------
@pytest.mark.parametrize("override, expected", [
    ('model.type="byo_tan_models:raises"', "key 'model.type': building the model with "
     "'byo_tan_models:raises' failed: RuntimeError: nope (byo_tan_models.py:"),
    ('model.type="byo_tan_models:wrong_names"', "key 'model.type': the model built by "
     "'byo_tan_models:wrong_names' measures ['a', 'b', 'c']; expected the outputs of "
     "model.sensors in order: ['dvl.vx_m', 'dvl.vy_m', 'sounder.depth_m']"),
    ('model.type="byo_tan_models:three_states"', "key 'model.truth': 4 signals; expected one "
     "per state of the model 'byo_tan_models:three_states' (x, y, z)"),
    ('model.type="byo_tan_models:not_a_model"', "key 'model.type': the model built by "
     "'byo_tan_models:not_a_model' (int) has no nx, nz, state_names"),
    ('model.parameters={nope=1}', "key 'model.type': building the model with "
     "'byo_tan_models:build' failed: TypeError: build() got an unexpected keyword argument "
     "'nope'"),
])
def test_builder_problems_are_one_line(project_fmus, tan_copy, override, expected):
    report = check_scenario(tan_copy, [override])
    assert report.exit_code == 2 and len(report.problems) == 1, report.problems
    msg = report.problems[0].message
    assert expected in msg and "\n" not in msg, msg


@pytest.mark.parametrize("override, expected", [
    ('model.type="byo_tan_models:nowhere"', "key 'model.type': type "
     "'byo_tan_models:nowhere': module 'byo_tan_models' ("),
    ('model.type="no_such_builder"', "key 'model.type': unknown model builder "
     "'no_such_builder' (entry points of uwcosim.models: "),
    ('model.kind="tan"', "key 'model': Value error, give 'kind' (a built-in model) or 'type' "
     "(a model of yours), not both"),
])
def test_model_type_errors_at_load(tan_copy, override, expected):
    with pytest.raises(ScenarioError) as info:
        load_scenario(tan_copy, [override])
    assert expected in str(info.value), str(info.value)


def test_parameters_need_a_type():
    with pytest.raises(ScenarioError, match="'parameters' are the keyword arguments of a model "
                       "builder: they need 'type'"):
        load_scenario(TAN, ["model.parameters={a=1}"])


# -- which filters run on a general model, and what the structured ones say today -----------
GENERAL = ("dead_reckoning", "ekf", "ukf", "ckf", "cukf", "pf", "rpf", "rbpf", "vbakf", "qivbf")


def test_every_general_filter_builds_on_the_example_model(example_fmus):
    ests = ", ".join(f'{k}={{type="{k}"}}' for k in GENERAL)
    report = check_scenario(SCENARIO, [f"estimators={{{ests}}}"])
    assert report.problems == [] and report.exit_code == 0


def test_every_general_filter_runs_on_the_example_model(example_fmus, tmp_path):
    ests = ", ".join(f'{k}={{type="{k}"{", n_particles=300" if "pf" in k else ""}}}'
                     for k in GENERAL)
    out = simulate(load_scenario(SCENARIO, ["run.duration=8", f"estimators={{{ests}}}"]),
                   tmp_path / "all", seed=1)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and set(summary["estimators"]) == set(GENERAL)
    for k in GENERAL:
        assert np.isfinite(summary["estimators"][k]["rmse_position_m"]), k


@pytest.mark.parametrize("scenario_override, kind, expected", [
    # the example: a structure the grid filters find, with too many gridded states
    (None, "pfm_psi", "4 gridded states ['x', 'y', 'cx', 'cy']; at most 3 are supported (set "
     "'states' to the nonlinear ones; a state is taken as a Kalman state only if its dynamics "
     "are affine and independent of the gridded states and a linear measurement row observes "
     "it)"),
    (None, "point_mass", "4 gridded states ['x', 'y', 'cx', 'cy']; at most 3 are supported"),
    # a discrete model and a numpy model have no CasADi ODE form
    ('model.type="byo_tan_models:discrete"', "pfm_psi", "the projection and point-mass "
     "filters need the CasadiModel (its CasADi functions), not a numpy fast path: a "
     "continuous-time model with constant noise PSDs (a CasadiModel, "
     "from_casadi(time='continuous'), or a model whose 'symbolic' is one)"),
    ('model.type="byo_tan_models:hand"', "point_mass", "the projection and point-mass filters "
     "need the CasadiModel (its CasADi functions), not a numpy fast path: a continuous-time"),
    ('model.type="byo_tan_models:hand"', "kf", "estimator 'kf' needs a linear model "
     "(model.linear); use 'ekf', 'ukf' or 'ckf'"),
])
def test_what_the_structured_filters_say_on_a_general_model(example_fmus, tan_copy,
                                                            scenario_override, kind, expected):
    scenario = SCENARIO if scenario_override is None else tan_copy
    sets = [f'estimators={{e={{type="{kind}"}}}}']
    if scenario_override:
        sets.append(scenario_override)
    report = check_scenario(scenario, sets)
    assert len(report.problems) == 1, report.problems
    assert expected in report.problems[0].message, report.problems[0].message


def test_grid_filters_run_on_the_example_when_told_the_gridded_states(example_fmus, tmp_path):
    ests = ('estimators={pfm_psi={type="pfm_psi", states=["x", "y"]}, point_mass={type='
            '"point_mass", states=["x", "y"], n_points=41}}')
    out = simulate(load_scenario(SCENARIO, ["run.duration=30", ests]), tmp_path / "g", seed=1)
    summary = json.loads((out / "summary.json").read_text())
    for k in ("pfm_psi", "point_mass"):
        assert not summary["estimators"][k]["diverged"], k


def test_rbpf_splits_the_example_model_by_its_structure(example_fmus):
    """The current is not measured: the RBPF's split puts it with the position (particles);
    ``linear_states`` moves it to the Kalman filters."""
    from uwcosim.filters.rbpf import RaoBlackwellizedPF
    from uwcosim.run.factory import build_model

    model = build_model(load_scenario(SCENARIO), None)
    rb = RaoBlackwellizedPF(model, np.zeros(6), np.eye(6), n_particles=10)
    assert [model.state_names[i] for i in rb.ip] == ["x", "y", "cx", "cy"]
    assert [model.state_names[i] for i in rb.ik] == ["vx", "vy"]
    rb = RaoBlackwellizedPF(model, np.zeros(6), np.eye(6), n_particles=10,
                            linear_states=["vx", "vy", "cx", "cy"])
    assert [model.state_names[i] for i in rb.ip] == ["x", "y"]


# -- from_casadi's own errors ---------------------------------------------------------------
@pytest.mark.parametrize("kwargs, expected", [
    ({"f": ["vx", "y"]}, "f uses y: not among its symbols (f takes dt, vx, x)"),
    ({"f": ["vx"]}, "f: 1 rows for 2 states"),
    ({"h": ["x * z"]}, "h uses z: not among its symbols (h takes vx, x)"),
    ({"Q": [1.0]}, "Q (the noise PSDs): expected 2 values or a 2x2 matrix"),
    ({"Q": [[1.0, 2.0], [2.0, 1.0]]}, "Q (the noise PSDs): not positive semi-definite"),
    ({"R": [0.0]}, "R: not positive definite"),
    ({"measurements": ["a", "b"]}, "measurements: 2 names for 1 rows of h"),
    ({"time": "hybrid"}, "time: expected 'continuous' or 'discrete'"),
    ({"states": [1.0, 2.0]}, "states: entry 0 is not a scalar CasADi symbol"),
])
def test_from_casadi_errors_are_one_line(kwargs, expected):
    x, vx, y, z = (ca.SX.sym(n) for n in ("x", "vx", "y", "z"))
    env = {"x": x, "vx": vx, "y": y, "z": z}
    args = {"states": [x, vx], "f": [vx, 0], "h": [x], "Q": [1.0, 1.0], "R": [1.0]}
    for k, v in kwargs.items():
        args[k] = [eval(e, {}, env) if isinstance(e, str) and k in "fh" else e for e in v] \
            if isinstance(v, list) and k in ("f", "h") else v
    with pytest.raises(ValueError) as info:
        from_casadi(**args)
    assert expected in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_rbpf_says_which_structure_it_needs():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    m = from_casadi(states=[x, y], f=[0, 0], h=[ca.sqrt(x**2 + y**2), ca.atan2(y, x)],
                    Q=[1, 1], R=[1, 0.01])
    with pytest.raises(ValueError, match=r"^rbpf: the model has no linear-Gaussian sub-state "
                       r"\(states with linear dynamics of their own, measured only by linear "
                       r"rows\); name them in linear_states, or use 'pf'$"):
        build("rbpf", m, np.array([10.0, 1.0]), np.eye(2), {"n_particles": 10},
              rng=np.random.default_rng(0))
