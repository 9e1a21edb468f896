"""The Modelica package ``models/UWCoSim`` against the project's own models.

rumoca 0.10 (the Python Modelica compiler used here) simulates a compiled model with diffsol;
it cannot take time-varying inputs at ``simulate()`` and this wheel cannot export FMUs, so the
vehicle is exercised through ``UWCoSim.Examples.VehicleHarness``, whose inputs are equations of
time. Its trajectory is compared with the CasADi ODE of :mod:`uwcosim.models.auv_equations`
integrated by scipy with the same closed-form inputs.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from uwcosim.master.observer import Callback
from uwcosim.models.auv_equations import vehicle_ode

rumoca = pytest.importorskip("rumoca", reason="rumoca (Modelica compiler) not installed")

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
PACKAGE_DIR = MODELS_DIR / "UWCoSim"
HARNESS = "UWCoSim.Examples.VehicleHarness"
T_END = 100.0
DT = 0.1

# Interface of each model as exposed by the project's FMUs: (inputs, outputs).
INTERFACES = {
    "UWCoSim.AUVKinematics": (
        {"psi", "a", "w_x", "w_y", "w_vx", "w_vy", "w_psi", "w_a"},
        {"x", "y", "vx", "vy", "psi_out"},
    ),
    "UWCoSim.DVL": ({"vx", "vy", "e_vx", "e_vy", "w_bvx", "w_bvy", "w_scale", "altitude"},
                    {"vx_m", "vy_m", "bottom_lock"}),
    "UWCoSim.DepthSounder": ({"x", "y", "e_h", "offset_h", "u_o", "e_o"},
                             {"depth_m", "altitude"}),
    "UWCoSim.ConstantVelocity": ({"w_px", "w_vx", "w_py", "w_vy"}, {"px", "vx", "py", "vy"}),
    HARNESS: (set(), {"vehicle.psi_out", "dvl.vx_m", "dvl.vy_m", "dvl.bottom_lock",
                      "sounder.depth_m", "sounder.altitude"}),
}


def _class_name(path: Path) -> str:
    rel = path.relative_to(MODELS_DIR).with_suffix("")
    return ".".join(rel.parts)


def _model_classes() -> list[str]:
    """Every ``model``/``block`` of the package that has its own file."""
    header = re.compile(r"^\s*(?:partial\s+)?(model|block)\s+(\w+)", re.MULTILINE)
    names = []
    for path in sorted(PACKAGE_DIR.rglob("*.mo")):
        head = header.search(path.read_text())
        if path.name != "package.mo" and head is not None:
            names.append(_class_name(path))
    return names


MO_FILES = sorted(PACKAGE_DIR.rglob("*.mo"))
MODEL_CLASSES = _model_classes()


def compile_model(name: str) -> rumoca.Model:
    """Compile class ``name`` of the ``UWCoSim`` package with rumoca.

    One class per file, as Modelica's directory mapping prescribes. The paths are absolute on
    purpose: with a relative file path, rumoca 0.10 sees the file and its copy found through the
    source root as two classes ("Duplicate class ... non-identical definition") on the second
    ``load`` of a session.
    """
    path = PACKAGE_DIR.joinpath(*name.split(".")[1:]).with_suffix(".mo")
    session = rumoca.Session(roots=[str(MODELS_DIR)])
    return session.load(str(path), model=name)


def simulate(
    model: rumoca.Model,
    t_end: float,
    dt: float,
    *,
    solver: str = "rk-like",
    rtol: float = 1e-12,
    atol: float = 1e-12,
) -> dict[str, np.ndarray]:
    """Simulate ``model`` on ``[0, t_end]``, output every ``dt``; returns ``{name: series}``.

    rumoca's defaults (solver ``auto`` = diffsol BDF, rtol = atol = 1e-6, 500 output
    intervals) leave ~1e-6 relative error on the vehicle's displacement; the explicit
    Runge-Kutta solver ``rk-like`` at 1e-12 brings it to ~1e-11.
    """
    config = rumoca.SimConfig(solver=solver, rtol=rtol, atol=atol)
    result = model.simulate(t=(0.0, t_end), dt=dt, config=config)
    series = {name: np.asarray(result[name], dtype=float) for name in result.names}
    series["time"] = np.asarray(result.time, dtype=float)
    return series


def seafloor_depth(x, y, mean_depth=1000.0, slope=0.01, amplitude=60.0, wavelength=5000.0):
    """Python copy of ``UWCoSim.Functions.seafloorDepth`` (the analytic stand-in for h_d)."""
    k = 2.0 * np.pi / wavelength
    return mean_depth + slope * (x - 12500.0) + amplitude * np.sin(k * x) * np.cos(k * y)


@pytest.fixture(scope="module")
def harness() -> rumoca.Model:
    return compile_model(HARNESS)


@pytest.fixture(scope="module")
def harness_run(harness) -> dict[str, np.ndarray]:
    return simulate(harness, T_END, DT)


def _parameter(model: rumoca.Model, name: str) -> float:
    return float(model.parameters[name].value)


def _reference(harness: rumoca.Model, t_eval: np.ndarray) -> np.ndarray:
    """``vehicle_ode`` with the harness's inputs, by scipy DOP853 at rtol = 1e-12."""
    psi_rate = _parameter(harness, "psiRate")
    a_amp = _parameter(harness, "aAmplitude")
    a_freq = _parameter(harness, "aFrequency")
    x0 = [_parameter(harness, f"vehicle.{p}") for p in ("x0", "y0", "vx0", "vy0")]
    f = vehicle_ode()
    w = np.zeros(4)

    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        u = [psi_rate * t, a_amp * np.sin(a_freq * t)]
        return f(x, u, w).full().ravel()

    sol = solve_ivp(rhs, (0.0, T_END), x0, method="DOP853", t_eval=t_eval, rtol=1e-12, atol=1e-12)
    assert sol.success, sol.message
    return sol.y


@pytest.mark.parametrize("path", MO_FILES, ids=[str(p.relative_to(MODELS_DIR)) for p in MO_FILES])
def test_modelica_file_parses(path: Path) -> None:
    errors = [d.message for d in rumoca.validate(str(path)) if d.level == "error"]
    assert errors == []


def test_every_model_is_checked() -> None:
    assert set(MODEL_CLASSES) == set(INTERFACES)


@pytest.mark.parametrize("name", MODEL_CLASSES, ids=MODEL_CLASSES)
def test_modelica_model_compiles(name: str) -> None:
    model = compile_model(name)
    structure = model.structure()
    assert structure.is_balanced and structure.is_matched
    inputs, outputs = INTERFACES[name]
    assert set(model.inputs.names) == inputs
    # rumoca lists an output that is also a state (e.g. x) among the states only
    assert outputs <= set(model.outputs.names) | set(model.states.names)
    assert set(model.outputs.names) <= outputs


def test_modelica_harness_matches_casadi_ode(harness, harness_run) -> None:
    run = harness_run
    np.testing.assert_allclose(run["time"], np.linspace(0.0, T_END, 1001), rtol=0, atol=1e-9)
    ref = _reference(harness, run["time"])
    names = ("vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy")
    got = np.vstack([run[n] for n in names])
    # positions (~2e3 and ~1.8e4 m) to 1e-6 relative ...
    np.testing.assert_allclose(got[:2], ref[:2], rtol=1e-6, atol=0)
    # ... which alone would hide errors on the ~50 m displacement: 0.1 um and 1 nm/s absolute
    np.testing.assert_allclose(got[:2], ref[:2], rtol=0, atol=1e-7)
    np.testing.assert_allclose(got[2:], ref[2:], rtol=0, atol=1e-9)
    assert np.ptp(ref[0]) > 10.0 and np.ptp(ref[1]) > 10.0  # the vehicle does move and turn


def test_modelica_harness_sensors(harness, harness_run) -> None:
    run = harness_run
    psi_rate = _parameter(harness, "psiRate")
    np.testing.assert_allclose(run["vehicle.psi_out"], psi_rate * run["time"], atol=1e-12)
    np.testing.assert_array_equal(run["dvl.vx_m"], run["vehicle.vx"])
    np.testing.assert_array_equal(run["dvl.vy_m"], run["vehicle.vy"])
    params = {
        key: _parameter(harness, f"sounder.{name}")
        for key, name in (
            ("mean_depth", "meanDepth"),
            ("slope", "slope"),
            ("amplitude", "amplitude"),
            ("wavelength", "wavelength"),
        )
    }
    expected = seafloor_depth(run["vehicle.x"], run["vehicle.y"], **params)
    np.testing.assert_allclose(run["sounder.depth_m"], expected, rtol=1e-12)


def test_modelica_matches_vehicle_fmu_through_master(harness, harness_run, project_fmus):
    """The vehicle FMU (model exchange) driven by our master with the harness's inputs.

    The master evaluates table controls at the RK4 stage times, so psi = psiRate*t is exact
    and a = A sin(w t) is a piecewise-linear table on a 0.02 s grid: its interpolation error,
    at most A w^2 h^2 / 8 = 1.25e-10 m/s^2, integrates to at most 1.25e-8 m/s in 100 s (the
    velocity bound below) and to well under 1e-6 m in position.
    """
    from uwcosim.master.master import Master
    from uwcosim.scenario import load_scenario, to_system

    psi_rate = _parameter(harness, "psiRate")
    a_amp = _parameter(harness, "aAmplitude")
    a_freq = _parameter(harness, "aFrequency")
    tt = np.linspace(0.0, T_END, int(round(T_END / 0.02)) + 1)
    a_table = ", ".join(f"[{float(t)!r}, {float(a_amp * np.sin(a_freq * t))!r}]" for t in tt)
    loaded = load_scenario(
        MODELS_DIR.parent / "scenarios" / "tan_terrain.toml",
        [f"run.duration={T_END}", f"run.step={DT}", "estimators={}",
         "noise.process.psd=[0.0, 0.0, 0.0, 0.0]", 'fmus.vehicle.interface="me"',
         "fmus.vehicle.substeps=2", f"controls.psi.table=[[0.0, 0.0], [{T_END}, "
         f"{psi_rate * T_END}]]", f"controls.a.table=[{a_table}]",
         "sensors.dvl.sigma=[0.0, 0.0]", "sensors.depth.sigma=[0.0]"],
    )
    master = Master(to_system(loaded))
    rows = []
    master.observers.append(Callback(lambda k, v: k and rows.append(
        [v.signal(f"vehicle.{s}") for s in ("x", "y", "vx", "vy")])))
    master.initialize({"sounder": {"mapFile": ""}})
    master.run_until(T_END)
    master.close()
    ours = np.array(rows)
    ref = np.stack([harness_run[f"vehicle.{v}"] for v in ("x", "y", "vx", "vy")], axis=1)
    ref = ref[1: ours.shape[0] + 1]
    np.testing.assert_allclose(ours[:, :2], ref[:, :2], rtol=1e-6)
    # and far tighter than the relative bound: the displacement is only about 50 m
    np.testing.assert_allclose(ours[:, :2], ref[:, :2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(ours[:, 2:], ref[:, 2:], rtol=0, atol=1.25e-8)
