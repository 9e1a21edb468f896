"""SSP files: reading (flat and nested systems, parameter sets, units, linear transformations,
default experiment), running them (with our sensors and estimators on top, or alone), export
and read-back, and the one-line errors for what we do not support.

Every SSP here is written by the test (its own SystemStructure.ssd and .ssv text) around the
project's FMUs.
"""

from __future__ import annotations

import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from uwcosim.api import run_scenario
from uwcosim.cli import main
from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.adapter import sha256_file
from uwcosim.master.master import Master
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario, to_system
from uwcosim.scenario.ssp.read import read_ssp

ROOT = Path(__file__).resolve().parents[1]
NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
      'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
      'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"')
FMU = 'type="application/x-fmu-sharedlibrary"'


def ssd(system: str, extra: str = "", name: str = "test") -> str:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<ssd:SystemStructureDescription {NS} version="1.0" name="{name}">\n'
            f"{system}\n{extra}\n</ssd:SystemStructureDescription>\n")


def ssv(params: dict[str, str], name: str = "set") -> str:
    """``params``: name -> the typed element, e.g. ``'<ssv:Real value="2" unit="km"/>'``."""
    body = "".join(f'<ssv:Parameter name="{k}">{v}</ssv:Parameter>' for k, v in params.items())
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet {NS} version="1.0" '
            f'name="{name}"><ssv:Parameters>{body}</ssv:Parameters></ssv:ParameterSet>\n')


def write_ssp(path: Path, ssd_text: str, fmus: dict[str, Path], files: dict[str, str] = {}):  # noqa: B006
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd_text)
        for member, src in fmus.items():
            zf.write(src, member)
        for member, text in files.items():
            zf.writestr(member, text)
    return path


def comp(name: str, source: str, connectors: str = "", bindings: str = "",
         attrs: str = "") -> str:
    conns = f"<ssd:Connectors>{connectors}</ssd:Connectors>" if connectors else ""
    binds = f"<ssd:ParameterBindings>{bindings}</ssd:ParameterBindings>" if bindings else ""
    return (f'<ssd:Component name="{name}" {FMU} source="resources/{source}" {attrs}>'
            f"{conns}{binds}</ssd:Component>")


def conn(a: str, b: str, inner: str = "", attrs: str = "") -> str:
    def ends(s: str, which: str) -> str:
        el, _, c = s.rpartition(".")
        return (f'{which}Element="{el}" ' if el else "") + f'{which}Connector="{c}"'
    return f"<ssd:Connection {ends(a, 'start')} {ends(b, 'end')} {attrs}>{inner}</ssd:Connection>"


def cx(name: str, kind: str, unit: str | None = None) -> str:
    real = f'<ssc:Real unit="{unit}"/>' if unit else "<ssc:Real/>"
    return f'<ssd:Connector name="{name}" kind="{kind}">{real}</ssd:Connector>'


def experiment(stop: float, step: float | None = None) -> str:
    ann = ("" if step is None else
           f'<ssd:Annotations><ssc:Annotation type="org.uwcosim"><uwc:Experiment '
           f'xmlns:uwc="urn:uwcosim:ssp:1" stepSize="{step}"/></ssc:Annotation></ssd:Annotations>')
    return f'<ssd:DefaultExperiment startTime="0" stopTime="{stop}">{ann}</ssd:DefaultExperiment>'


KM = ('<ssd:Units><ssc:Unit name="km"><ssc:BaseUnit m="1" factor="1000"/></ssc:Unit>'
      '<ssc:Unit name="degC"><ssc:BaseUnit K="1" offset="273.15"/></ssc:Unit>'
      '<ssc:Unit name="K"><ssc:BaseUnit K="1"/></ssc:Unit></ssd:Units>')


def auv_ssp(path: Path, fmus: Path) -> Path:
    """The truth side of scenarios/tan_dead_reckoning.toml as an SSP: the vehicle's start
    values come from a parameter set bound on the system (prefix ``vehicle.``), x and y in km."""
    system = (
        '<ssd:System name="auv"><ssd:Connectors><ssd:Connector name="hs" kind="parameter">'
        "<ssc:Real/></ssd:Connector></ssd:Connectors><ssd:ParameterBindings>"
        '<ssd:ParameterBinding source="resources/start.ssv" prefix="vehicle."/>'
        "</ssd:ParameterBindings><ssd:Elements>"
        + comp("vehicle", "AUVKinematics.fmu",
               cx("x", "output") + cx("y", "output") + cx("vx", "output") + cx("vy", "output"))
        + comp("dvl", "DVL.fmu", cx("vx", "input") + cx("vy", "input"))
        + comp("sounder", "DepthSounder.fmu", cx("x", "input") + cx("y", "input"))
        + "</ssd:Elements><ssd:Connections>"
        + conn("vehicle.vx", "dvl.vx") + conn("vehicle.vy", "dvl.vy")
        + conn("vehicle.x", "sounder.x") + conn("vehicle.y", "sounder.y")
        + "</ssd:Connections></ssd:System>")
    start = ssv({"x": '<ssv:Real value="2" unit="km"/>', "y": '<ssv:Real value="18" unit="km"/>',
                 "vx": '<ssv:Real value="0.5"/>', "vy": '<ssv:Real value="0"/>'})
    return write_ssp(path, ssd(system, KM + experiment(50, step=1.0)),
                     {f"resources/{n}.fmu": fmus / f"{n}.fmu"
                      for n in ("AUVKinematics", "DVL", "DepthSounder")},
                     {"resources/start.ssv": start})


def test_read_flat_system_with_parameter_set_and_default_experiment(project_fmus, tmp_path):
    system = read_ssp(auv_ssp(tmp_path / "auv.ssp", project_fmus), tmp_path / "x")
    assert list(system.components) == ["vehicle", "dvl", "sounder"]
    assert system.components["vehicle"].start == {"x": 2000.0, "y": 18000.0, "vx": 0.5,
                                                  "vy": 0.0}
    assert [(c.src, c.dst, c.factor, c.offset) for c in system.connections] == [
        ("vehicle.vx", "dvl.vx", 1.0, 0.0), ("vehicle.vy", "dvl.vy", 1.0, 0.0),
        ("vehicle.x", "sounder.x", 1.0, 0.0), ("vehicle.y", "sounder.y", 1.0, 0.0)]
    assert (system.start_time, system.stop_time, system.step) == (0.0, 50.0, 1.0)
    assert sha256_file(system.components["dvl"].fmu) == sha256_file(project_fmus / "DVL.fmu")


def test_step_from_a_fixed_step_master_annotation(project_fmus, tmp_path):
    system = ('<ssd:System name="s"><ssd:Elements>' + comp("fi", "FaultInjector.fmu")
              + "</ssd:Elements></ssd:System>")
    other = ('<ssd:Annotations><ssc:Annotation type="org.example"><x:SimulationInformation '
             'xmlns:x="urn:example"><x:FixedStepMaster stepSize="0.25"/>'
             "</x:SimulationInformation></ssc:Annotation></ssd:Annotations>")
    path = write_ssp(tmp_path / "s.ssp", ssd(system, experiment(2.0) + other),
                     {"resources/FaultInjector.fmu": project_fmus / "FaultInjector.fmu"})
    loaded = load_scenario(path)
    assert (loaded.spec.run.step, loaded.spec.run.duration) == (0.25, 2.0)
    assert loaded.spec.connections == [] and list(loaded.spec.fmus) == ["fi"]


def test_ssp_truth_with_our_sensors_gives_the_same_log_as_the_toml(project_fmus, tmp_path):
    auv_ssp(tmp_path / "auv.ssp", project_fmus)
    data = tomllib.loads((ROOT / "scenarios/tan_dead_reckoning.toml").read_text())
    for key in ("fmus", "connections"):
        del data[key]
    data["run"] = {"seed": 1}  # start, duration (50 s) and step come from the SSP
    data["system"] = {"ssp": "auv.ssp"}
    data["estimators"] = {"ekf": {"type": "ekf"}}
    data["output"] = {"figures": False}
    (tmp_path / "auv.toml").write_text(tomli_w.dumps(data))
    a = run_scenario(load_scenario(tmp_path / "auv.toml"), tmp_path / "a")
    b = run_scenario(load_scenario(ROOT / "scenarios/tan_dead_reckoning.toml",
                                   ["run.duration=50", 'estimators={ekf={type="ekf"}}',
                                    "output.figures=false", "output.density_snapshots=[]"]),
                     tmp_path / "b")
    (ta, meta_a), (tb, _) = read_log(a.log_path), read_log(b.log_path)
    assert len(ta["time"]) == len(tb["time"]) == 51
    assert list(ta) == list(tb) and "est.ekf.x" in ta
    for name in ta:  # every value, bit for bit (NaN where a measurement was lost)
        np.testing.assert_array_equal(ta[name], tb[name], err_msg=name)
    assert "[system]" in meta_a["scenario_text"]
    rmse = [r.summary["estimators"]["ekf"]["rmse_position_m"] for r in (a, b)]
    assert rmse[0] == rmse[1]


def nested_ssp(path: Path, fmus: Path) -> Path:
    """vehicle at the root; sub-system nav holds dvl and sub-system inner holds sounder;
    signals reach them through system connectors; parameters bound at three levels."""
    inner = (
        '<ssd:System name="inner"><ssd:Connectors>' + cx("x", "input") + cx("y", "input")
        + "</ssd:Connectors><ssd:Elements>"
        + comp("sounder", "DepthSounder.fmu", cx("x", "input") + cx("y", "input"))
        + "</ssd:Elements><ssd:Connections>"
        + conn("x", "sounder.x") + conn("y", "sounder.y") + "</ssd:Connections></ssd:System>")
    nav = (
        '<ssd:System name="nav"><ssd:Connectors>' + cx("vx", "input") + cx("x", "input")
        + cx("y", "input") + cx("vx_m", "output")
        + "</ssd:Connectors><ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
        + ssv({"inner.sounder.mapFile": '<ssv:String value="nav.bin"/>'}).split("?>", 1)[1]
        + "</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings><ssd:Elements>"
        + comp("dvl", "DVL.fmu", cx("vx", "input") + cx("vx_m", "output")) + inner
        + "</ssd:Elements><ssd:Connections>"
        + conn("vx", "dvl.vx") + conn("x", "inner.x") + conn("inner.y", "y")
        + conn("dvl.vx_m", "vx_m") + "</ssd:Connections></ssd:System>")
    root = (
        '<ssd:System name="auv"><ssd:Connectors><ssd:Connector name="hs" kind="parameter">'
        "<ssc:Real/></ssd:Connector></ssd:Connectors><ssd:ParameterBindings>"
        '<ssd:ParameterBinding source="resources/root.ssv"/></ssd:ParameterBindings>'
        "<ssd:Elements>"
        + comp("vehicle", "AUVKinematics.fmu", cx("x", "output") + cx("y", "output")
               + cx("vx", "output"),
               '<ssd:ParameterBinding source="resources/vehicle.ssv"/>')
        + comp("fi", "FaultInjector.fmu",
               cx("u", "input") + cx("y", "output") + cx("hang_seconds", "parameter"))
        + nav + "</ssd:Elements><ssd:Connections>"
        + conn("vehicle.vx", "nav.vx") + conn("vehicle.x", "nav.x") + conn("nav.y", "vehicle.y")
        + conn("nav.vx_m", "fi.u")
        + conn("hs", "fi.hang_seconds", '<ssc:LinearTransformation factor="2"/>')
        + "</ssd:Connections></ssd:System>")
    files = {
        # the component's own set, then the system's: the system's value wins for x
        "resources/vehicle.ssv": ssv({"x": '<ssv:Real value="1.0"/>',
                                      "vx": '<ssv:Real value="0.5"/>',
                                      "y": '<ssv:Real value="18000"/>',
                                      "max_internal_step": '<ssv:Real value="0.05"/>'}),
        "resources/root.ssv": ssv({"vehicle.x": '<ssv:Real value="3000"/>',
                                   "nav.inner.sounder.mapFile": '<ssv:String value="root.bin"/>',
                                   "hs": '<ssv:Real value="7"/>',  # to fi, times 2
                                   "vehicle.no_such": '<ssv:Real value="1"/>'}),
    }
    return write_ssp(path, ssd(root, experiment(20)),
                     {f"resources/{n}.fmu": fmus / f"{n}.fmu"
                      for n in ("AUVKinematics", "DVL", "DepthSounder", "FaultInjector")}, files)


def test_nested_systems_are_flattened(project_fmus, tmp_path):
    system = read_ssp(nested_ssp(tmp_path / "n.ssp", project_fmus), tmp_path / "x")
    assert sorted(system.components) == ["fi", "nav_dvl", "nav_inner_sounder", "vehicle"]
    assert system.components["nav_inner_sounder"].path == "nav.inner.sounder"
    assert sorted((c.src, c.dst) for c in system.connections) == [
        ("nav_dvl.vx_m", "fi.u"), ("vehicle.vx", "nav_dvl.vx"),
        ("vehicle.x", "nav_inner_sounder.x"), ("vehicle.y", "nav_inner_sounder.y")]
    v = system.components["vehicle"]
    # the root's binding overrides the vehicle's own
    assert v.start == {"x": 3000.0, "vx": 0.5, "y": 18000.0}
    assert v.parameters == {"max_internal_step": 0.05}
    # bound on nav and on the root: the higher level wins
    assert system.components["nav_inner_sounder"].parameters == {"mapFile": "root.bin"}
    assert system.components["fi"].parameters == {"hang_seconds": 14.0}
    assert system.step is None and system.stop_time == 20.0
    assert system.ignored == ["resources/root.ssv: vehicle.no_such"]  # SSP 1.0: ignored


def test_nested_ssp_runs_through_the_command_line(project_fmus, tmp_path, capsys, monkeypatch):
    path = nested_ssp(tmp_path / "n.ssp", project_fmus)
    monkeypatch.chdir(tmp_path)
    # the sounder reads the map file named by the root's parameter set
    from uwcosim.models.terrain import synthetic_bathymetry

    synthetic_bathymetry(7).write_coefficients(tmp_path / "root.bin")
    assert main(["run", str(path), "--set", "run.step=0.5", "--out", "r"]) == 0
    t = read_log(tmp_path / "r" / "log.parquet")[0]
    assert len(t["time"]) == 41 and t["time"][-1] == 20.0
    np.testing.assert_array_equal(t["nav_dvl.vx_m"], t["vehicle.vx"])  # no DVL noise
    np.testing.assert_array_equal(t["fi.y"], t["nav_dvl.vx_m"])
    assert t["vehicle.x"][0] == 3000.0
    assert main(["run", str(path), "--out", "r2"]) == 2  # no step anywhere
    assert "key 'run.step'" in capsys.readouterr().err


def transform_ssp(path: Path, fmus: Path) -> Path:
    """vehicle -> four FaultInjectors (y = u): a linear transformation, a unit conversion
    m -> km, an offset unit (degC -> K), and a linear transformation without unit conversion."""
    fi = [comp(f"fi{i}", "FaultInjector.fmu", cx("u", "input", unit)) for i, unit in
          enumerate([None, "km", "K", "km"])]
    system = (
        '<ssd:System name="t"><ssd:Elements>'
        + comp("vehicle", "AUVKinematics.fmu",
               cx("x", "output", "m") + cx("vx", "output") + cx("psi_out", "output", "degC"),
               "<ssd:ParameterBinding><ssd:ParameterValues>"
               + ssv({"x": '<ssv:Real value="1500"/>', "vx": '<ssv:Real value="0.25"/>'}
                     ).split("?>", 1)[1] + "</ssd:ParameterValues></ssd:ParameterBinding>")
        + "".join(fi) + "</ssd:Elements><ssd:Connections>"
        + conn("vehicle.vx", "fi0.u", '<ssc:LinearTransformation factor="2" offset="1"/>')
        + conn("fi1.u", "vehicle.x")  # start/end do not give the direction of flow
        + conn("vehicle.psi_out", "fi2.u")
        + conn("vehicle.x", "fi3.u", '<ssc:LinearTransformation factor="3"/>',
               'suppressUnitConversion="true"')
        + "</ssd:Connections></ssd:System>")
    return write_ssp(path, ssd(system, KM + experiment(4, step=1.0)),
                     {f"resources/{n}.fmu": fmus / f"{n}.fmu"
                      for n in ("AUVKinematics", "FaultInjector")})


def test_linear_transformations_and_unit_conversions(project_fmus, tmp_path):
    loaded = load_scenario(transform_ssp(tmp_path / "t.ssp", project_fmus),
                           ["fmus.vehicle.start.psi=0.3"])
    conns = {c[1]: c[2] if len(c) > 2 else None for c in loaded.spec.connections}
    assert (conns["fi0.u"].factor, conns["fi0.u"].offset) == (2.0, 1.0)
    assert conns["fi1.u"].factor == pytest.approx(1e-3) and conns["fi1.u"].offset == 0.0
    assert (conns["fi2.u"].factor, conns["fi2.u"].offset) == (1.0, 273.15)
    assert (conns["fi3.u"].factor, conns["fi3.u"].offset) == (3.0, 0.0)
    m = Master(to_system(loaded))
    try:
        m.initialize()
        for _ in range(3):
            m.step()
            x, vx, psi = m.signals(["vehicle.x", "vehicle.vx", "vehicle.psi_out"])
            assert x > 1500.0 and vx == 0.25
            assert m.signal("fi0.y") == 2.0 * vx + 1.0
            assert m.signal("fi1.y") == pytest.approx(x / 1000.0, rel=1e-15)
            assert m.signal("fi2.y") == psi + 273.15
            assert m.signal("fi3.y") == 3.0 * x
    finally:
        m.close()


def test_connection_factor_offset_in_a_toml_scenario(tan):
    loaded = tan(["connections=[['vehicle.vx', 'dvl.vx', {factor=2.0, offset=0.5}], "
                  "['vehicle.vy', 'dvl.vy'], ['vehicle.x', 'sounder.x'], "
                  "['vehicle.y', 'sounder.y']]", "run.duration=5", "estimators={}",
                  "sensors.dvl.sigma=[0.0, 0.0]"])
    m = Master(to_system(loaded))
    try:
        m.initialize()
        m.run_until(5.0)
        assert m.signal("dvl.vx_m") == 2.0 * m.signal("vehicle.vx") + 0.5
        assert m.signal("dvl.vy_m") == m.signal("vehicle.vy")
    finally:
        m.close()
    with pytest.raises(ScenarioError, match=r"key 'connections': .*entry 1: factr: Extra"):
        tan(["connections=[['vehicle.vx', 'dvl.vx'], ['vehicle.vy', 'dvl.vy', {factr=2.0}]]"])


def test_export_reads_back_identically(project_fmus, tmp_path, capsys):
    scenario = ROOT / "scenarios/tan_terrain.toml"
    sets = ["fmus.vehicle.parameters={max_internal_step=0.05}", "fmus.dvl.interface='me'",
            "connections=[['vehicle.vx', 'dvl.vx', {factor=2.0, offset=0.5}], "
            "['vehicle.vy', 'dvl.vy'], ['vehicle.x', 'sounder.x'], ['vehicle.y', 'sounder.y']]",
            "run.start_time=10", "run.duration=30", "run.step=0.5"]
    args = ["ssp", "export", str(scenario), "--out", str(tmp_path / "e.ssp")]
    assert main([*args, *(a for s in sets for a in ("--set", s))]) == 0
    out = capsys.readouterr().out
    assert "note: [estimators] not exported" in out and out.strip().endswith("e.ssp")
    first = (tmp_path / "e.ssp").read_bytes()
    src = load_scenario(scenario, sets).spec
    loaded = load_scenario(tmp_path / "e.ssp")  # owns the extracted FMUs
    back = loaded.spec
    assert list(back.fmus) == list(src.fmus)
    for name, f in src.fmus.items():
        g = back.fmus[name]
        assert sha256_file(ROOT / "scenarios" / f.path) == sha256_file(Path(g.path))
        assert (g.interface, g.parameters, g.start) == (f.interface, f.parameters, f.start)
    def key(c):
        return c[0], c[1]

    assert sorted(back.connections, key=key) == sorted(src.connections, key=key)
    assert (back.run.start_time, back.run.duration, back.run.step) == (10.0, 30.0, 0.5)
    assert (back.name, back.description) == (src.name, src.description)
    # reproducible archive
    assert main([*args, *(a for s in sets for a in ("--set", s))]) == 0
    assert (tmp_path / "e.ssp").read_bytes() == first


def _unsupported_cases(fmus: Path):
    v = comp("vehicle", "AUVKinematics.fmu", cx("vx", "output"))
    d = comp("dvl", "DVL.fmu", cx("vx", "input"))

    def sys(body: str = "", conns: str = "", head: str = "") -> str:
        return (f'<ssd:System name="s">{head}<ssd:Elements>{v}{d}{body}</ssd:Elements>'
                f"<ssd:Connections>{conn('vehicle.vx', 'dvl.vx')}{conns}</ssd:Connections>"
                f"{{tail}}</ssd:System>")

    enum_map = ('<ssc:EnumerationMappingTransformation><ssc:MapEntry source="a" target="b"/>'
                "</ssc:EnumerationMappingTransformation>")
    return {
        "signal dictionary": (
            ssd(sys().replace("{tail}", '<ssd:SignalDictionaries><ssd:SignalDictionary '
                              'name="bus"><ssb:DictionaryEntry xmlns:ssb="http://ssp-standard.'
                              'org/SSP1/SystemStructureSignalDictionary" name="v"><ssc:Real/>'
                              "</ssb:DictionaryEntry></ssd:SignalDictionary>"
                              "</ssd:SignalDictionaries>")),
            "<ssd:SignalDictionary name='bus'>"),
        "enumeration mapping": (
            ssd(sys().replace("{tail}", "").replace(
                "</ssd:Connection>", enum_map + "</ssd:Connection>", 1)),
            "<ssc:EnumerationMappingTransformation>"),
        "parameter mapping of another type": (
            ssd(sys(head='<ssd:ParameterBindings><ssd:ParameterBinding source="p.ssv">'
                    '<ssd:ParameterMapping type="application/x-other" source="m.ssm"/>'
                    "</ssd:ParameterBinding></ssd:ParameterBindings>").replace("{tail}", "")),
            "<ssd:ParameterMapping type='application/x-other'> is not supported"),
        "SSP 3": (ssd(sys().replace("{tail}", "")).replace(' version="1.0" name=',
                                                            ' version="3.0" name='),
                  "version '3.0' is not supported"),
        "clock connector": (
            ssd(sys().replace("{tail}", "").replace(
                '<ssc:Real/></ssd:Connector>', '<ssc:Clock/></ssd:Connector>', 1)).replace(
                ' version="1.0" name=', ' version="2.0" name='),
            "clock connectors are not supported"),
        "not an FMU": (
            ssd(sys('<ssd:Component name="tool" type="application/x-ssp-package" '
                    'source="resources/AUVKinematics.fmu"/>').replace("{tail}", "")),
            "type 'application/x-ssp-package'"),
        "SSP 2": (
            ssd(sys().replace("{tail}", "")).replace("SSP1/SystemStructureDescription",
                                                     "SSP2/SystemStructureDescription"),
            "SSP2/SystemStructureDescription"),
        "schema": (ssd(sys().replace("{tail}", "").replace('name="s"', "")),
                   "does not follow the SSP 1.0 schema"),
    }


@pytest.mark.parametrize("case", ["signal dictionary", "enumeration mapping",
                                  "parameter mapping of another type", "not an FMU", "SSP 2",
                                  "SSP 3", "clock connector", "schema"])
def test_unsupported_element_is_one_line_exit_2(project_fmus, tmp_path, capsys, case):
    text, expected = _unsupported_cases(project_fmus)[case]
    path = write_ssp(tmp_path / "u.ssp", text,
                     {f"resources/{n}.fmu": project_fmus / f"{n}.fmu"
                      for n in ("AUVKinematics", "DVL")},
                     {"p.ssv": ssv({}), "m.ssm": ""})
    assert main(["run", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("uwcosim: error: ")
    assert expected in err and "Traceback" not in err
    with pytest.raises(ScenarioError):  # also from a scenario's [system] ssp
        (tmp_path / "s.toml").write_text('[system]\nssp = "u.ssp"\n[run]\nduration = 1.0\n'
                                         "step = 1.0\n")
        load_scenario(tmp_path / "s.toml")


def test_extracted_fmus_are_removed_with_the_scenario(project_fmus, tmp_path):
    import gc

    loaded = load_scenario(auv_ssp(tmp_path / "auv.ssp", project_fmus))
    folder = loaded.ssp.dir
    assert Path(loaded.spec.fmus["vehicle"].path).parent == folder and folder.is_dir()
    del loaded
    gc.collect()
    assert not folder.exists()


def test_a_self_connection_is_refused(project_fmus, tmp_path):
    """Issue 24, item 6: ``dvl.vx -> dvl.vx`` vanished from the generated scenario and the run
    was ok with ``dvl.vx`` undriven; the TOML form is refused, and so is this."""
    path = auv_ssp(tmp_path / "auv.ssp", project_fmus)
    with zipfile.ZipFile(path) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    members["SystemStructure.ssd"] = members["SystemStructure.ssd"].replace(
        conn("vehicle.vx", "dvl.vx").encode(), conn("dvl.vx", "dvl.vx").encode())
    assert b'startElement="dvl" startConnector="vx" endElement="dvl"' \
        in members["SystemStructure.ssd"]
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    with pytest.raises(ScenarioError, match=r"connection dvl\.vx -> dvl\.vx in system 'auv': "
                       r"connects dvl\.vx to itself; expected an output and an input"):
        load_scenario(path)


def test_a_corrupt_fmu_inside_an_ssp_is_named_by_the_ssp(project_fmus, tmp_path):
    """Issue 24, item 19: a corrupt FMU inside an SSP was named by its temporary copy."""
    from uwcosim.core.errors import FMUError

    bad = tmp_path / "DVL.fmu"
    bad.write_bytes((project_fmus / "DVL.fmu").read_bytes()[:3000])
    fmus = tmp_path / "fmus"
    fmus.mkdir()
    for n in ("AUVKinematics", "DepthSounder"):
        (fmus / f"{n}.fmu").write_bytes((project_fmus / f"{n}.fmu").read_bytes())
    (fmus / "DVL.fmu").write_bytes(bad.read_bytes())
    path = auv_ssp(tmp_path / "auv.ssp", fmus)
    with pytest.raises(FMUError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert f"{path}: component 'dvl' (resources/DVL.fmu)" in msg, msg
    assert "uwcosim_" not in msg and len(msg.splitlines()) == 1, msg
