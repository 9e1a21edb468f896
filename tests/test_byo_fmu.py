"""Bring your own vehicle FMU: variable maps (units, conventions), two third-party exporters
(pythonfmu FMI 2.0 CS, hand-written C FMI 3.0 CS built with CMake), ``uwcosim fmu check``."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from uwcosim.api import run_scenario
from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.varmap import parse_offset, unit_conversion
from uwcosim.fmu.check import check_fmu
from uwcosim.master.master import Master
from uwcosim.master.observer import Callback
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.runlog import read_log
from uwcosim.scenario import to_system

try:
    from thirdparty_fmus import FMI3_DIR, PYFMU_DIR, fmi3_vehicle, pythonfmu_vehicle
except ImportError:  # tests/ imported as a package
    from tests.thirdparty_fmus import FMI3_DIR, PYFMU_DIR, fmi3_vehicle, pythonfmu_vehicle

__all__ = ["fmi3_vehicle", "pythonfmu_vehicle"]  # fixtures
ROOT = Path(__file__).resolve().parents[1]
SIGNALS = ["vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy", "sounder.depth_m"]
TWO = ['estimators={dead_reckoning={type="dead_reckoning"}, ekf={type="ekf"}}']
# the pythonfmu vehicle has no process-noise inputs: the filters keep the scenario's Q
NO_NOISE = ["noise={}", "model.q_psd=[0.05, 0.05, 1e-5, 1e-5]"]
# the FMI 3 vehicle's map, inline this time ([fmus.vehicle.map] in the scenario)
C3_MAP = ['fmus.vehicle.map.x="pos.east"', 'fmus.vehicle.map.y="pos.north"',
          'fmus.vehicle.map.vx="speed.surge"', 'fmus.vehicle.map.vy="speed.sway"',
          'fmus.vehicle.map.psi={var="yaw", offset="pi/2"}', 'fmus.vehicle.map.a="accel"',
          'fmus.vehicle.map.w_x="w.east"', 'fmus.vehicle.map.w_y="w.north"',
          'fmus.vehicle.map.w_vx="w.surge"', 'fmus.vehicle.map.w_vy="w.sway"']


def _py(fmu: Path) -> list[str]:
    return [f'fmus.vehicle.path="{fmu}"', f'fmus.vehicle.map="{PYFMU_DIR / "map.toml"}"',
            *NO_NOISE]


def _c3(fmu: Path) -> list[str]:
    return [f'fmus.vehicle.path="{fmu}"', *C3_MAP]


@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    return str(synthetic_bathymetry(7).write_coefficients(tmp_path_factory.mktemp("m") / "m.bin"))


def _signals(loaded, map_file):
    m = Master(to_system(loaded))
    rows = []
    m.observers.append(Callback(lambda k, v: k and rows.append([v.signal(n) for n in SIGNALS])))
    m.initialize({"sounder": {"mapFile": map_file}})
    first = m.signals(SIGNALS).copy()
    m.run_until(1e9)
    m.close()
    return first, np.array(rows)


# -- units and offsets ------------------------------------------------------------------------
def test_unit_conversions_and_offsets():
    assert unit_conversion("knots", "m/s") == pytest.approx((1852 / 3600, 0.0), rel=1e-15)
    assert unit_conversion("kn", "m/s")[0] == unit_conversion("knots", "m/s")[0]
    assert unit_conversion("deg", "rad") == pytest.approx((math.pi / 180, 0.0))
    assert unit_conversion("km/h", "m/s")[0] == pytest.approx(1 / 3.6)
    assert unit_conversion("ft", "m")[0] == 0.3048 and unit_conversion("km", "m")[0] == 1000
    assert unit_conversion("m/s^2", "m/s2") == (1.0, 0.0)
    with pytest.raises(ValueError, match="cannot convert 'deg' \\(rad\\) to 'm' \\(m\\)"):
        unit_conversion("deg", "m")
    with pytest.raises(ValueError, match="unknown unit 'furlong'"):
        unit_conversion("furlong", "m")
    assert parse_offset("pi/2", "k") == math.pi / 2 and parse_offset("-pi", "k") == -math.pi
    assert parse_offset("2*pi/3", "k") == pytest.approx(2 * math.pi / 3)
    assert parse_offset(1.5, "k") == 1.5
    with pytest.raises(ScenarioError, match="multiple of pi"):
        parse_offset("tau", "k")


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_an_offset_map_leaves_the_run_unchanged(tan, map_file, interface):
    """Positions offset by the map (start values in our frame): the same truth, for model
    exchange too (inputs converted at every RK4 stage); unmapped variables keep their names."""
    base = ["estimators={}", "run.duration=60", f'fmus.vehicle.interface="{interface}"',
            "controls.psi.table=[[0, 0.0], [60, 0.6]]"]
    _, plain = _signals(tan(base), map_file)
    mapped = tan([*base, 'fmus.vehicle.map={x={var="x", offset=-500.0}, '
                         'y={var="y", scale=1.0, offset=250.0}}'])
    first, shifted = _signals(mapped, map_file)
    assert first[:2].tolist() == [2000.0, 18000.0]
    np.testing.assert_allclose(shifted, plain, rtol=0, atol=1e-9)


# -- third-party vehicles in the TAN scenario -------------------------------------------------
def test_pythonfmu_vehicle_reproduces_our_truth(tan, map_file, pythonfmu_vehicle):
    """North-east, compass heading in degrees, knots, start values as parameters: through the
    map it is our vehicle (eq. 54) to rounding, start values given under our role names."""
    base = [*NO_NOISE, "estimators={}", "run.duration=200"]
    first, ours = _signals(tan(base), map_file)
    first_theirs, theirs = _signals(tan([*base, *_py(pythonfmu_vehicle)]), map_file)
    np.testing.assert_allclose(first_theirs[:4], [2000.0, 18000.0, 0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(theirs[:, :2], ours[:, :2], rtol=0, atol=1e-7)
    np.testing.assert_allclose(theirs[:, 2:4], ours[:, 2:4], rtol=0, atol=1e-12)
    np.testing.assert_allclose(theirs[:, 4], ours[:, 4], rtol=0, atol=1e-7)


def test_fmi3_c_vehicle_reproduces_our_truth_with_process_noise(tan, map_file, fmi3_vehicle):
    """Feet, km/h (declared only through UnitDefinitions), yaw from north and noise inputs in
    ft/s: the same noise samples give our truth to rounding."""
    base = ["estimators={}", "run.duration=200"]
    _, ours = _signals(tan(base), map_file)
    loaded = tan([*base, *_c3(fmi3_vehicle)])
    m = Master(to_system(loaded))
    assert m.adapters["vehicle"].fmi3 and m.adapters["vehicle"].varmap.aliases["vx"].scale == \
        pytest.approx(1 / 3.6, rel=1e-15)
    m.close()
    _, theirs = _signals(loaded, map_file)
    np.testing.assert_allclose(theirs[:, :2], ours[:, :2], rtol=0, atol=1e-7)
    np.testing.assert_allclose(theirs[:, 2:4], ours[:, 2:4], rtol=0, atol=1e-12)


@pytest.mark.parametrize("which", ["pythonfmu", "fmi3c"])
def test_ekf_beats_dead_reckoning_with_a_third_party_vehicle(tan, tmp_path, which, request):
    fmu = request.getfixturevalue("pythonfmu_vehicle" if which == "pythonfmu" else
                                  "fmi3_vehicle")
    over = _py(fmu) if which == "pythonfmu" else _c3(fmu)
    res = run_scenario(tan([*over, *TWO, "run.duration=300"]), tmp_path, figures=False)
    est = res.summary["estimators"]
    assert res.status == "ok"
    assert np.isfinite(est["ekf"]["rmse_position_m"]) and np.isfinite(est["ekf"]["anees"])
    assert est["ekf"]["rmse_position_m"] < est["dead_reckoning"]["rmse_position_m"]
    cols, meta = read_log(res.log_path)
    assert {"vehicle.x", "vehicle.vy"} <= set(cols) and "vehicle.east" not in cols
    assert len(meta["fmus"]["vehicle"]) == 64
    assert meta["variable_maps"]["vehicle"]["vx"][0] in ("surge", "speed.surge")


def test_third_party_vehicle_runs_are_bit_identical(tan, tmp_path, fmi3_vehicle):
    over = [*_c3(fmi3_vehicle), *TWO, "run.duration=100"]
    run_scenario(tan(over), tmp_path / "a", figures=False)
    run_scenario(tan(over), tmp_path / "b", figures=False)
    assert (tmp_path / "a/log.parquet").read_bytes() == (tmp_path / "b/log.parquet").read_bytes()


@pytest.mark.parametrize(("overrides", "expected"), [
    (['fmus.vehicle.map.x="nope"'], "key 'fmus.vehicle.map.x': the FMU has no variable 'nope'"),
    (['fmus.vehicle.map.x="yaw"'],
     "key 'fmus.vehicle.map.x': 'yaw' has causality 'input', expected 'output'"),
    (['fmus.vehicle.map.x={var="pos.east", unit="deg"}'],
     "key 'fmus.vehicle.map.x': cannot convert 'deg' (rad) to 'm' (m)"),
    (['fmus.vehicle.map.x={var="pos.east", unti="ft"}'],
     "key 'fmus.vehicle.map.x.unti': unknown key"),
    (['fmus.vehicle.map.x={var="pos.east", unit="ft", scale=0.3}'],
     "key 'fmus.vehicle.map.x': give 'unit' or 'scale', not both"),
    (['fmus.vehicle.map.w_x="w.north"'],
     "key 'fmus.vehicle.map.w_y': variable 'w.north' already plays role 'w_x'"),
    (['fmus.vehicle.map="missing_map.toml"'], "variable map file"),
    (['fmus.vehicle.map={x="pos.east", y="pos.north", vx="speed.surge", vy="speed.sway", '
      'psi={var="yaw", offset="pi/2"}, a="accel"}'],
     "FMU 'vehicle' has no variable 'w_x' (fmus.vehicle.map gives roles"),
], ids=["variable", "causality", "unit", "key", "unit-and-scale", "twice", "file", "unmapped"])
def test_map_errors_name_the_file_and_key(tan, tmp_path, fmi3_vehicle, overrides, expected):
    with pytest.raises(ScenarioError) as info:
        run_scenario(tan([*_c3(fmi3_vehicle), *overrides]), tmp_path, figures=False)
    assert expected in str(info.value)
    assert "tan_terrain.toml" in str(info.value)
    assert not (tmp_path / "log.parquet").exists()


# -- uwcosim fmu check ------------------------------------------------------------------------
def test_fmu_check_reports_capabilities_map_and_smoke_run(fmi3_vehicle, pythonfmu_vehicle):
    rep = check_fmu(fmi3_vehicle, "vehicle", str(FMI3_DIR / "map.toml"))
    text = rep.text()
    assert rep.ok, text
    assert "FMI version       3.0" in text and "several instances yes" in text
    assert "kmph -> m/s" in text and "direction of motion        ok" in text
    rep = check_fmu(pythonfmu_vehicle, "vehicle", str(PYFMU_DIR / "map.toml"))
    assert rep.ok, rep.text()
    assert "knots -> m/s" in rep.text() and "-0.514444*theirs" in rep.text()
    # pythonfmu leaves ModelStructure/InitialUnknowns empty: a warning, not a refusal
    assert any("InitialUnknowns" in w for w in rep.warnings)


def test_fmu_check_finds_wrong_conventions(tmp_path, pythonfmu_vehicle, fmi3_vehicle):
    text = (PYFMU_DIR / "map.toml").read_text()
    no_negate = tmp_path / "heading.toml"
    no_negate.write_text(text.replace(
        'psi = { var = "heading", unit = "deg", negate = true, offset = "pi/2" }',
        'psi = { var = "heading", unit = "deg" }'))
    rep = check_fmu(pythonfmu_vehicle, "vehicle", str(no_negate))
    assert not rep.ok and "does not move along its heading" in rep.text()
    knots = tmp_path / "knots.toml"
    knots.write_text(text.replace('unit = "knots"', 'unit = "m/s"'))
    rep = check_fmu(pythonfmu_vehicle, "vehicle", str(knots))
    assert not rep.ok and "times as far as the speed says" in rep.text()
    rep = check_fmu(fmi3_vehicle, "vehicle", None)  # no map: the roles are missing
    assert not rep.ok and "role 'psi' (input, rad): no variable of that name" in rep.text()


def test_fmu_check_cli_exit_status(tmp_path, fmi3_vehicle, project_fmus):
    def cli(*args):
        return subprocess.run([sys.executable, "-m", "uwcosim", "fmu", "check", *args],
                              capture_output=True, text=True, cwd=ROOT, timeout=300)

    r = cli(str(fmi3_vehicle), "--role", "vehicle", "--map", str(FMI3_DIR / "map.toml"))
    assert r.returncode == 0 and "result: compatible" in r.stdout, r.stdout + r.stderr
    r = cli(str(project_fmus / "AUVKinematics_fmi2.fmu"), "--role", "vehicle",
            "--interface", "me")
    assert r.returncode == 0 and "model exchange, 10 s" in r.stdout, r.stdout + r.stderr
    r = cli(str(fmi3_vehicle), "--role", "vehicle")
    assert r.returncode == 1 and "INCOMPATIBLE" in r.stdout
    bad = tmp_path / "bad.fmu"
    bad.write_bytes(b"PK\x03\x04 truncated")
    r = cli(str(bad), "--role", "vehicle")
    assert r.returncode == 1 and "not a valid FMU archive" in r.stdout
    r = cli(str(fmi3_vehicle), "--map", str(tmp_path / "nope.toml"))
    assert r.returncode == 2 and "variable map file" in r.stderr and "Traceback" not in r.stderr
