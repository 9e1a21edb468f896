"""Tests of the project's FMUs (uwcosim.fmu): build, validation, simulation in FMI 2.0/3.0
co-simulation and model exchange, closed-form results, terrain maps, faults, instances, reset.
"""

from __future__ import annotations

import ctypes
import os
import time
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from uwcosim.core import paths
from uwcosim.core.errors import FMUError
from uwcosim.fmu import build_fmu, build_fmus, fmu_info, validate
from uwcosim.fmu.build import archive_name, compile_shared, is_up_to_date, prepare, targets
from uwcosim.fmu.specs import MODELS

try:
    from crasher import NAME as CRASH_MODEL
    from fault_injector import NAME as FAULT_MODEL
    from fmu_fixtures import CS, ME, Instance, fmu_dir, fmu_path
except ImportError:  # tests/ imported as a package
    from tests.crasher import NAME as CRASH_MODEL
    from tests.fault_injector import NAME as FAULT_MODEL
    from tests.fmu_fixtures import CS, ME, Instance, fmu_dir, fmu_path

__all__ = ["fmu_dir"]  # the session fixture, re-exported for pytest

VERSIONS = ("3.0", "2.0")
INTERFACES = (CS, ME)
ALL_FMUS = [(m, v) for m in MODELS for v in VERSIONS]


# ---- build -------------------------------------------------------------------------------

def test_build_names_every_fmu(fmu_dir):
    names = sorted(p.name for p in fmu_dir.glob("*.fmu"))
    expected = sorted(f"{m}{s}.fmu" for m in MODELS for s in ("", "_fmi2"))
    assert names == expected
    for m in MODELS:
        assert read_model_description(str(fmu_path(fmu_dir, m))).fmiVersion == "3.0"
        assert read_model_description(str(fmu_path(fmu_dir, m, "2.0"))).fmiVersion == "2.0"


def test_the_fmi_layer_knows_the_projects_fmus_by_their_build_names():
    """core.paths names the project's FMUs for the FMI layer's build hint (which cannot import
    the build tool): the same models as the specifications, the same file names as the build."""
    # the tests add their FaultInjector and Crasher
    shipped = [m for m in MODELS if m not in (FAULT_MODEL, CRASH_MODEL)]
    assert sorted(paths.PROJECT_MODELS) == sorted(shipped)
    for m in shipped:
        for v in VERSIONS:
            assert paths.is_project_fmu(f"/elsewhere/{archive_name(m, v)}")
    assert not paths.is_project_fmu("fmus/ThirdPartyVehicle.fmu")


def test_build_is_incremental(fmu_dir):
    mtimes = {p: p.stat().st_mtime_ns for p in fmu_dir.glob("*.fmu")}
    t0 = time.perf_counter()
    paths = build_fmus(fmu_dir)
    assert time.perf_counter() - t0 < 5.0
    assert {p: p.stat().st_mtime_ns for p in paths} == mtimes
    time.sleep(0.01)
    [dvl2] = build_fmus(fmu_dir, names=["DVL_fmi2"], force=True)
    assert dvl2.stat().st_mtime_ns != mtimes[dvl2]
    assert fmu_path(fmu_dir, "DVL").stat().st_mtime_ns == mtimes[fmu_path(fmu_dir, "DVL")]


def test_up_to_date_check_uses_source_hash(fmu_dir, tmp_path):
    src3, src2 = prepare("DVL", 3), prepare("DVL", "2.0")
    assert src3.digest != src2.digest and src3.guid != src2.guid
    assert src3.digest == prepare("DVL", "3.0").digest  # stable
    assert is_up_to_date(fmu_path(fmu_dir, "DVL"), src3)
    assert not is_up_to_date(fmu_path(fmu_dir, "DVL"), src2)
    assert read_model_description(str(fmu_path(fmu_dir, "DVL"))).guid == src3.guid
    broken = tmp_path / "DVL.fmu"
    broken.write_bytes(fmu_path(fmu_dir, "DVL").read_bytes()[:500])
    assert not is_up_to_date(broken, src3)
    assert not is_up_to_date(tmp_path / "missing.fmu", src3)


def test_build_fmu_single(tmp_path):
    path = build_fmu("ConstantVelocity", 2, tmp_path / "cv.fmu")
    assert validate(path) == []
    assert read_model_description(str(path)).fmiVersion == "2.0"


def test_targets_and_unknown_names():
    assert targets(["AUVKinematics"]) == [("AUVKinematics", "3.0"), ("AUVKinematics", "2.0")]
    assert targets(["DVL_fmi2.fmu", "DVL"]) == [("DVL", "2.0"), ("DVL", "3.0")]
    with pytest.raises(FMUError, match="unknown FMU 'Sonar'.*AUVKinematics"):
        targets(["Sonar"])
    with pytest.raises(FMUError, match="unsupported FMI version"):
        build_fmu("DVL", 1, "x.fmu")


def test_compile_error_reports_first_error_line(tmp_path):
    bad = tmp_path / "bad.c"
    bad.write_text("int f(void) { return undefined_symbol; }\n")
    with pytest.raises(FMUError, match=r"bad\.so: compilation failed: .*error.*undefined_symbol"):
        compile_shared([bad], tmp_path / "bad.so")


# ---- validation and info -----------------------------------------------------------------

@pytest.mark.parametrize(("model", "version"), ALL_FMUS)
def test_fmus_validate(fmu_dir, model, version):
    path = fmu_path(fmu_dir, model, version)
    assert validate_fmu(str(path)) == []
    assert validate(path) == []
    md = read_model_description(str(path))
    assert md.coSimulation is not None and md.modelExchange is not None
    for iface in (md.coSimulation, md.modelExchange):
        assert not iface.canBeInstantiatedOnlyOncePerProcess


def test_fmu_info(fmu_dir):
    text = fmu_info(fmu_path(fmu_dir, "DepthSounder"))
    assert "FMI version       3.0" in text
    assert "CoSimulation (DepthSounder), ModelExchange (DepthSounder)" in text
    assert "several instances yes" in text and "get/set state yes" in text
    assert "directional derivatives no" in text
    assert any(line.split()[:5] == ["mapFile", "parameter", "fixed", "String", "''"]
               for line in text.splitlines())
    # value reference 16: after the inputs, parameters and map extent (issue 25's error inputs)
    assert any(line.split() == ["depth_m", "output", "continuous", "Float64", "m", "16"]
               for line in text.splitlines())
    text2 = fmu_info(fmu_path(fmu_dir, "AUVKinematics", "2.0"))
    assert "FMI version       2.0" in text2 and "continuous states 4" in text2


def test_validate_reports_broken_archives(fmu_dir, tmp_path):
    good = fmu_path(fmu_dir, "DVL").read_bytes()
    truncated = tmp_path / "truncated.fmu"
    truncated.write_bytes(good[: len(good) // 2])
    not_zip = tmp_path / "text.fmu"
    not_zip.write_text("hello")
    for path in (truncated, not_zip, tmp_path / "missing.fmu"):
        problems = validate(path)
        assert problems and all(isinstance(p, str) for p in problems)
        assert str(path.name) in problems[0]
        with pytest.raises(FMUError):
            fmu_info(path)


def test_validate_reports_missing_platform_binary(fmu_dir, tmp_path):
    foreign = tmp_path / "DVL.fmu"
    with zipfile.ZipFile(fmu_path(fmu_dir, "DVL")) as src, zipfile.ZipFile(foreign, "w") as dst:
        for item in src.infolist():
            if item.filename.startswith("binaries/"):
                dst.writestr("binaries/aarch64-darwin/DVL.dylib", b"\0")
            else:
                dst.writestr(item, src.read(item))
    [problem] = validate(foreign)
    assert "no binary for this platform" in problem and "aarch64-darwin" in problem


# ---- stand-alone simulation --------------------------------------------------------------

@pytest.mark.parametrize("interface", INTERFACES)
@pytest.mark.parametrize(("model", "version"), ALL_FMUS)
def test_simulates_standalone(fmu_dir, model, version, interface):
    result = simulate_fmu(str(fmu_path(fmu_dir, model, version)), fmi_type=interface,
                          stop_time=1.0, output_interval=0.1)
    assert len(result) == 11
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name])), name


def _auv_closed_form(t, x0, y0, vx0, vy0, psi, a, w):
    c, s = np.cos(psi), np.sin(psi)
    ax, ay = a * c + w[2], a * s + w[3]  # constant velocity rates
    x = x0 + (vx0 * c - vy0 * s + w[0]) * t + (ax * c - ay * s) * t**2 / 2
    y = y0 + (vy0 * c + vx0 * s + w[1]) * t + (ay * c + ax * s) * t**2 / 2
    return x, y, vx0 + ax * t, vy0 + ay * t


@pytest.mark.parametrize("interface", INTERFACES)
@pytest.mark.parametrize("version", VERSIONS)
def test_vehicle_matches_closed_form(fmu_dir, version, interface):
    start = {"x": 10.0, "y": -4.0, "vx": 1.5, "vy": -0.25}
    u = {"psi": 0.7, "a": 0.12, "w_x": 0.01, "w_y": -0.02, "w_vx": 0.003, "w_vy": -0.004}
    t_end = 20.0
    signal = np.array([(0.0, *u.values()), (t_end, *u.values())],
                      dtype=[("time", float)] + [(k, float) for k in u])
    result = simulate_fmu(str(fmu_path(fmu_dir, "AUVKinematics", version)), fmi_type=interface,
                          stop_time=t_end, output_interval=0.5, input=signal,
                          start_values={**start, "max_internal_step": 0.25},
                          relative_tolerance=1e-11)
    t = result["time"]
    assert t[-1] == pytest.approx(t_end)
    expected = _auv_closed_form(t, *start.values(), u["psi"], u["a"], list(u.values())[2:])
    atol = 1e-9 if interface == CS else 1e-7  # RK4 is exact for the quadratic; CVode is not
    for name, ref in zip(("x", "y", "vx", "vy"), expected, strict=True):
        np.testing.assert_allclose(result[name], ref, rtol=1e-12, atol=atol, err_msg=name)
    np.testing.assert_allclose(result["psi_out"], u["psi"], rtol=0, atol=1e-15)  # fmpy interp.


@pytest.mark.parametrize("max_step", [0.0, 0.03, 10.0])
def test_vehicle_internal_steps_do_not_change_exact_result(fmu_dir, max_step):
    inst = Instance(fmu_path(fmu_dir, "AUVKinematics"))
    inst.init(vx=2.0, max_internal_step=max_step)
    inst.set(psi=-0.3, a=0.5)
    t = 0.0
    for h in (0.1, 0.7, 2.2):  # variable communication steps
        inst.step(t, h)
        t += h
    expected = _auv_closed_form(t, 0.0, 0.0, 2.0, 0.0, -0.3, 0.5, [0, 0, 0, 0])
    np.testing.assert_allclose(inst.get("x", "y", "vx", "vy"), expected, rtol=1e-12, atol=1e-12)
    inst.free()


@pytest.mark.parametrize("interface", INTERFACES)
def test_constant_velocity_matches_closed_form(fmu_dir, interface):
    w = {"w_px": 0.1, "w_vx": -0.05, "w_py": 0.0, "w_vy": 0.02}
    signal = np.array([(0.0, *w.values()), (10.0, *w.values())],
                      dtype=[("time", float)] + [(k, float) for k in w])
    result = simulate_fmu(str(fmu_path(fmu_dir, "ConstantVelocity", "2.0")), fmi_type=interface,
                          stop_time=10.0, output_interval=1.0, input=signal,
                          start_values={"px": 1.0, "vx": 2.0, "py": 3.0, "vy": -1.0},
                          relative_tolerance=1e-11)
    t = result["time"]
    atol = 1e-10 if interface == CS else 1e-7
    np.testing.assert_allclose(result["px"], 1 + (2 + 0.1) * t - 0.05 * t**2 / 2, atol=atol)
    np.testing.assert_allclose(result["vx"], 2 - 0.05 * t, atol=atol)
    np.testing.assert_allclose(result["py"], 3 - t + 0.02 * t**2 / 2, atol=atol)
    np.testing.assert_allclose(result["vy"], -1 + 0.02 * t, atol=atol)


@pytest.mark.parametrize("interface", INTERFACES)
@pytest.mark.parametrize("version", VERSIONS)
def test_dvl_is_direct_feedthrough(fmu_dir, version, interface):
    path = fmu_path(fmu_dir, "DVL", version)
    md = read_model_description(str(path))
    deps = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md.outputs}
    # the error states (bias, scale factor) are zero unless their noise inputs drive them
    assert deps == {"vx_m": ["b_vx", "e_vx", "scale", "vx"],
                    "vy_m": ["b_vy", "e_vy", "scale", "vy"], "bottom_lock": ["altitude"],
                    "b_vx": ["b_vx"], "b_vy": ["b_vy"], "scale": ["scale"]}
    inst = Instance(path, interface)
    inst.init()
    rng = np.random.default_rng(1)
    for k in range(20):
        vx, vy, ex, ey = rng.normal(size=4)
        if interface == ME:
            inst.fmu.setTime(0.1 * k)
        inst.set(vx=vx, vy=vy, e_vx=ex, e_vy=ey)
        assert inst.get("vx_m", "vy_m") == [vx + ex, vy + ey]
        if interface == CS:
            inst.step(0.1 * k, 0.1)
    inst.free()
    result = simulate_fmu(str(path), fmi_type=interface, stop_time=1.0, output_interval=0.5,
                          start_values={"vx": 1.25, "e_vx": 0.5, "vy": -2.0, "e_vy": 0.25})
    assert np.all(result["vx_m"] == 1.75) and np.all(result["vy_m"] == -1.75)


# ---- FaultInjector -------------------------------------------------------------------------

@pytest.mark.parametrize("version", VERSIONS)
def test_fault_injector_fails_at_fail_time_cs(fmu_dir, version):
    inst = Instance(fmu_path(fmu_dir, "FaultInjector", version))
    inst.init(fail_time=0.5)
    t, failed_at = 0.0, None
    for k in range(10):
        try:
            inst.set(u=k)
            inst.step(t, 0.1)
            t = round(t + 0.1, 12)
            inst.get("y")
        except Exception:  # noqa: BLE001 - fmpy raises FMICallException
            failed_at = t
            break
    assert failed_at == pytest.approx(0.5)
    assert "injected failure at time t = 0.5" in inst.log
    with pytest.raises(Exception, match="failed with status 3"):
        inst.step(t, 0.1)  # the instance stays in the error state
    inst.free()


@pytest.mark.parametrize("version", VERSIONS)
def test_fault_injector_fails_at_fail_time_me(fmu_dir, version):
    path = fmu_path(fmu_dir, "FaultInjector", version)
    inst = Instance(path, ME)
    inst.init(fail_time=2.0)
    inst.fmu.setTime(1.999)
    assert inst.get("y") == [0.0]
    inst.fmu.setTime(2.0)
    with pytest.raises(Exception, match="failed with status 3"):
        inst.get("y")
    inst.free()
    with pytest.raises(Exception, match="status 3"):
        simulate_fmu(str(path), fmi_type=ME, stop_time=3.0, start_values={"fail_time": 1.0})


@pytest.mark.parametrize("interface", INTERFACES)
@pytest.mark.parametrize("version", VERSIONS)
def test_fault_injector_nan_after_nan_time(fmu_dir, version, interface):
    signal = np.array([(0.0, 2.0), (1.0, 2.0)], dtype=[("time", float), ("u", float)])
    result = simulate_fmu(str(fmu_path(fmu_dir, "FaultInjector", version)), fmi_type=interface,
                          stop_time=1.0, output_interval=0.1, input=signal,
                          start_values={"nan_time": 0.55})
    before = result["time"] < 0.55
    assert np.all(result["y"][before] == 2.0)
    assert np.all(np.isnan(result["y"][~before])) and np.any(~before)


@pytest.mark.parametrize("version", VERSIONS)
def test_fault_injector_hangs_at_hang_time(fmu_dir, version):
    inst = Instance(fmu_path(fmu_dir, "FaultInjector", version))
    starts = {v.name: v.start for v in inst.md.modelVariables}
    assert float(starts["hang_seconds"]) == 3600.0 and float(starts["fail_time"]) == 1e300
    inst.init(hang_time=0.2, hang_seconds=0.4)
    durations = []
    for k in range(3):
        t0 = time.perf_counter()
        inst.step(0.1 * k, 0.1)
        durations.append(time.perf_counter() - t0)
    assert durations[0] < 0.2 and durations[1] < 0.2
    assert durations[2] >= 0.39
    assert "injected hang of 0.4 s at time t = 0.2" in inst.log
    inst.free()


# ---- instances, reset, FMU state -------------------------------------------------------------

def test_several_instances_are_independent(fmu_dir):
    path3 = fmu_path(fmu_dir, "AUVKinematics")
    a = Instance(path3, name="auv_a")
    b = Instance(path3, name="auv_b", unzipdir=a.dir)  # same binary, same process
    c = Instance(fmu_path(fmu_dir, "AUVKinematics", "2.0"), name="auv_c")
    cases = {a: (1.0, 2.0, 0.5, 0.0, 0.3, 0.2), b: (-5.0, 0.0, 0.0, 1.0, -1.2, 0.05),
             c: (0.0, 0.0, 3.0, -1.0, 2.0, -0.1)}
    for inst, (x0, y0, vx0, vy0, psi, acc) in cases.items():
        inst.init(x=x0, y=y0, vx=vx0, vy=vy0)
        inst.set(psi=psi, a=acc)
    t = 0.0
    for _ in range(30):  # interleaved stepping
        for inst in cases:
            inst.step(t, 0.2)
        t += 0.2
    for inst, (x0, y0, vx0, vy0, psi, acc) in cases.items():
        expected = _auv_closed_form(t, x0, y0, vx0, vy0, psi, acc, [0, 0, 0, 0])
        np.testing.assert_allclose(inst.get("x", "y", "vx", "vy"), expected, rtol=1e-12,
                                   atol=1e-9)
    b.free()
    a.step(t, 0.1)  # freeing one instance leaves the other usable
    a.free()
    c.free()


@pytest.mark.parametrize("interface", INTERFACES)
@pytest.mark.parametrize("version", VERSIONS)
def test_reset_restores_start_values(fmu_dir, version, interface):
    inst = Instance(fmu_path(fmu_dir, "AUVKinematics", version), interface)
    for x0 in (5.0, -3.0):
        inst.init(x=x0, vx=1.0)
        inst.set(a=0.5)
        if interface == CS:
            inst.step(0.0, 2.0)
            assert inst.get("x", "vx") == pytest.approx([x0 + 2.0 + 0.5 * 4 / 2, 2.0])
        else:
            inst.fmu.setTime(1.0)
            dx = (ctypes.c_double * 4)()
            getter = inst.fmu.getContinuousStateDerivatives if inst.fmi3 else \
                inst.fmu.getDerivatives
            getter(dx, 4)
            assert list(dx) == [1.0, 0.0, 0.5, 0.0]
        inst.fmu.reset()
        assert inst.get("x", "y", "vx", "vy", "a", "max_internal_step") == [0, 0, 0, 0, 0, 0.1]
    inst.free()


@pytest.mark.parametrize("version", VERSIONS)
def test_fmu_state_get_set_and_serialize(fmu_dir, version):
    inst = Instance(fmu_path(fmu_dir, "AUVKinematics", version))
    inst.init(vx=1.0)
    inst.set(a=0.2, psi=0.1)
    inst.step(0.0, 1.0)
    state = inst.fmu.getFMUState() if inst.fmi3 else inst.fmu.getFMUstate()
    inst.step(1.0, 1.0)
    first = inst.get("x", "y", "vx", "vy")
    if inst.fmi3:
        data = inst.fmu.serializeFMUState(state)
        restored = inst.fmu.deserializeFMUState(data)
        inst.fmu.setFMUState(restored)
    else:
        data = inst.fmu.serializeFMUstate(state)
        restored = inst.fmu.deSerializeFMUstate(data)
        inst.fmu.setFMUstate(restored)
    assert inst.get("x")[0] < first[0]
    inst.step(1.0, 1.0)
    assert inst.get("x", "y", "vx", "vy") == first
    inst.free()


def test_wrong_token_is_rejected(fmu_dir):
    from fmpy import extract
    from fmpy.fmi3 import FMU3Slave

    path = fmu_path(fmu_dir, "DVL")
    md = read_model_description(str(path))
    fmu = FMU3Slave(guid="{not-the-token}", unzipDirectory=extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier)
    messages = []
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=lambda env, status, cat, msg: messages.append(msg.decode()))
    assert "does not match" in messages[0]


def test_fmus_folder_can_be_built_by_cli(tmp_path):
    from uwcosim.fmu.build import main

    assert main(["-o", str(tmp_path), "DVL_fmi2"]) == 0
    assert os.listdir(tmp_path) and (tmp_path / "DVL_fmi2.fmu").is_file()
    assert main(["-o", str(tmp_path), "Nope"]) == FMUError.exit_code
