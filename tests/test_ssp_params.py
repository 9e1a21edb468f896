"""SSP parameters and SSP 2.0: propagation of bound system connectors along connections (the
OMSimulator case of issue 21: gain k = 30 from the binding, input u = -20 -> -600), the
precedence of bindings, parameter mappings (inline and ``.ssm``), SSP 2.0 files (FMI 3 types,
arrays, 2.0 kinds) with their schema check, and ``ssp export --ssp-version 2.0``.

Every SSP here is written by the test around our own test FMUs (tests/data/event_fmus:
Feedthrough ``y = u``, ``yk = k*u``, ``iy = iu``, ``by = bu``; TypedBlock) and the project's.
"""

from __future__ import annotations

import logging
import zipfile

import numpy as np
import pytest

from uwcosim.cli import main
from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.adapter import sha256_file
from uwcosim.runlog import read_log
from uwcosim.scenario import load_scenario
from uwcosim.scenario.ssp.read import read_ssp
from uwcosim.scenario.ssp.schema import schema_problems

try:
    from event_fmus import event_fmus
    from test_ssp import ROOT, comp, conn, cx, experiment, write_ssp
except ImportError:  # tests/ imported as a package
    from tests.event_fmus import event_fmus
    from tests.test_ssp import ROOT, comp, conn, cx, experiment, write_ssp

__all__ = ["event_fmus"]  # fixture

NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
      'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
      'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
      'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"')


def ssd(system: str, extra: str = "", version: str = "1.0") -> str:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<ssd:SystemStructureDescription {NS} version="{version}" name="p">\n'
            f"{system}\n{extra}\n</ssd:SystemStructureDescription>\n")


def pset(params: dict[str, str], version: str = "1.0", decl: bool = True) -> str:
    body = "".join(f'<ssv:Parameter name="{k}">{v}</ssv:Parameter>' for k, v in params.items())
    head = '<?xml version="1.0" encoding="UTF-8"?>\n' if decl else ""
    return (f'{head}<ssv:ParameterSet {NS} version="{version}" name="set">'
            f"<ssv:Parameters>{body}</ssv:Parameters></ssv:ParameterSet>\n")


def inline(params: dict[str, str], version: str = "1.0", mapping: str = "") -> str:
    return (f"<ssd:ParameterBinding><ssd:ParameterValues>{pset(params, version, False)}"
            f"</ssd:ParameterValues>{mapping}</ssd:ParameterBinding>")


def binding(source: str, mapping: str = "", prefix: str = "") -> str:
    pre = f' prefix="{prefix}"' if prefix else ""
    return f'<ssd:ParameterBinding source="{source}"{pre}>{mapping}</ssd:ParameterBinding>'


def ssm(entries: str, version: str = "1.0", decl: bool = True) -> str:
    head = '<?xml version="1.0" encoding="UTF-8"?>\n' if decl else ""
    return f'{head}<ssm:ParameterMapping {NS} version="{version}">{entries}</ssm:ParameterMapping>'


def real(v, unit: str | None = None, t: str = "Real") -> str:
    return f'<ssv:{t} value="{v}"' + (f' unit="{unit}"' if unit else "") + "/>"


def system(body: str, connectors: str = "", bindings: str = "", conns: str = "",
           name: str = "root") -> str:
    c = f"<ssd:Connectors>{connectors}</ssd:Connectors>" if connectors else ""
    b = f"<ssd:ParameterBindings>{bindings}</ssd:ParameterBindings>" if bindings else ""
    k = f"<ssd:Connections>{conns}</ssd:Connections>" if conns else ""
    return f'<ssd:System name="{name}">{c}{b}<ssd:Elements>{body}</ssd:Elements>{k}</ssd:System>'


def gain_ssp(path, fmu, own_k: str | None = "7", direct_k: str | None = None):
    """OMSimulator's case: the top-level system has a parameter connector ``k`` connected to the
    gain's parameter ``k`` and an input connector ``u`` connected to its input ``u``; the
    system's parameter set binds ``k = 30`` and ``u = -20``; the component binds its own ``k``
    (and the FMU declares k = 2)."""
    own = inline({"k": real(own_k)}) if own_k is not None else ""
    values = {"k": real(30), "u": real(-20)}
    if direct_k is not None:
        values["gain.k"] = real(direct_k)
    s = system(comp("gain", "Feedthrough.fmu", cx("u", "input") + cx("k", "parameter")
                    + cx("yk", "output"), own),
               connectors=cx("k", "parameter") + cx("u", "input"),
               bindings=binding("resources/root.ssv"),
               conns=conn("k", "gain.k") + conn("u", "gain.u"))
    return write_ssp(path, ssd(s, experiment(1.0, step=0.1)),
                     {"resources/Feedthrough.fmu": fmu}, {"resources/root.ssv": pset(values)})


# ---- propagation along connections ------------------------------------------------------------

@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_top_level_parameter_binding_propagates_to_the_component(event_fmus, tmp_path,
                                                                  monkeypatch, version):
    """k = 30 and u = -20 bound on the top-level connectors reach gain.k and gain.u: yk = -600
    in every row (it was 0: the bound input connector was ignored and k came from the
    component)."""
    path = gain_ssp(tmp_path / "gain.ssp", event_fmus[("Feedthrough", version)])
    flat = read_ssp(path, tmp_path / "x")
    assert flat.components["gain"].parameters == {"k": 30.0}
    assert flat.components["gain"].start == {"u": -20.0}
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(path), "--out", "r"]) == 0
    cols = read_log(tmp_path / "r" / "log.parquet")[0]
    assert len(cols["time"]) == 11
    np.testing.assert_array_equal(cols["gain.yk"], -600.0)
    np.testing.assert_array_equal(cols["gain.y"], -20.0)


def test_a_direct_binding_does_not_beat_the_connected_system_parameter(event_fmus, tmp_path):
    path = gain_ssp(tmp_path / "gain.ssp", event_fmus[("Feedthrough", "3.0")], direct_k="5")
    assert read_ssp(path, tmp_path / "x").components["gain"].parameters == {"k": 30.0}
    # without the system's value the component's own binding holds, then the FMU's start
    path = gain_ssp(tmp_path / "g2.ssp", event_fmus[("Feedthrough", "3.0")])
    text = pset({"u": real(-20)})
    p2 = tmp_path / "g3.ssp"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(p2, "w") as dst:
        for m in src.namelist():
            dst.writestr(m, text if m == "resources/root.ssv" else src.read(m))
    assert read_ssp(p2, tmp_path / "y").components["gain"].parameters == {"k": 7.0}


def test_propagation_through_a_subsystem_with_units_and_transformation(event_fmus, tmp_path):
    """A parameter in km on the root, through a sub-system connector in m and a linear
    transformation (factor 2), reaches the component's k; a bound connector that reaches
    nothing is listed as ignored."""
    sub = system(comp("g", "Feedthrough.fmu", cx("k", "parameter")),
                 connectors=cx("kk", "parameter", "m"),
                 conns=conn("kk", "g.k", '<ssc:LinearTransformation factor="2"/>'), name="sub")
    s = system(sub, connectors=cx("k", "parameter", "km") + cx("lonely", "parameter"),
               bindings=inline({"k": real(0.5, "km"), "lonely": real(1)}),
               conns=conn("k", "sub.kk"))
    units = ('<ssd:Units><ssc:Unit name="km"><ssc:BaseUnit m="1" factor="1000"/></ssc:Unit>'
             '<ssc:Unit name="m"><ssc:BaseUnit m="1"/></ssc:Unit></ssd:Units>')
    path = write_ssp(tmp_path / "s.ssp", ssd(s, units),
                     {"resources/Feedthrough.fmu": event_fmus[("Feedthrough", "2.0")]})
    flat = read_ssp(path, tmp_path / "x")
    assert flat.components["sub_g"].parameters == {"k": 1000.0}
    assert any("lonely" in i and "no parameter or input" in i for i in flat.ignored)


# ---- parameter mappings ---------------------------------------------------------------------

def _mapped_ssp(tmp_path, fmu, where: str, version: str = "1.0"):
    entries = ('<ssm:MappingEntry source="gain" target="k">'
               '<ssc:LinearTransformation factor="10" offset="1"/></ssm:MappingEntry>'
               '<ssm:MappingEntry source="flag" target="bu">'
               '<ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>'
               '<ssc:MapEntry source="false" target="true"/></ssc:BooleanMappingTransformation>'
               '</ssm:MappingEntry>'
               '<ssm:MappingEntry source="level" target="iu">'
               '<ssc:IntegerMappingTransformation><ssc:MapEntry source="1" target="40"/>'
               '</ssc:IntegerMappingTransformation></ssm:MappingEntry>'
               '<ssm:MappingEntry source="missing" target="u"/>')
    values = {"gain": real(3), "flag": '<ssv:Boolean value="true"/>',
              "level": '<ssv:Integer value="1"/>', "u": real(0.25)}
    files = {"resources/p.ssv": pset(values, version)}
    if where == "file":
        files["resources/m.ssm"] = ssm(entries, version)
        b = binding("resources/p.ssv", '<ssd:ParameterMapping source="resources/m.ssm"/>')
    else:
        b = binding("resources/p.ssv", "<ssd:ParameterMapping>"
                    + ssm(entries, version, decl=False) + "</ssd:ParameterMapping>")
    s = system(comp("ft", "Feedthrough.fmu", bindings=b))
    return write_ssp(tmp_path / f"m_{where}.ssp", ssd(s, experiment(1, step=0.5), version),
                     {"resources/Feedthrough.fmu": fmu}, files)


@pytest.mark.parametrize("where", ["file", "inline"])
@pytest.mark.parametrize("version", ["1.0", "2.0"])
def test_parameter_mappings_rename_and_transform(event_fmus, tmp_path, caplog, where, version):
    path = _mapped_ssp(tmp_path, event_fmus[("Feedthrough", "3.0")], where, version)
    flat = read_ssp(path, tmp_path / "x")
    ft = flat.components["ft"]
    # gain -> k: 10 * 3 + 1; flag -> bu negated; level 1 -> iu 40; u not mapped: its own name
    assert ft.parameters == {"k": 31.0, "bu": False, "iu": 40}
    assert ft.start == {"u": 0.25}
    assert any("'missing'" in i for i in flat.ignored)
    with caplog.at_level(logging.WARNING):
        loaded = load_scenario(path)
    assert "mapping entry 'missing'" in caplog.text
    assert loaded.spec.fmus["ft"].parameters["k"] == 31.0


def test_a_mapping_file_that_does_not_follow_the_schema_is_one_line(event_fmus, tmp_path, capsys):
    path = _mapped_ssp(tmp_path, event_fmus[("Feedthrough", "3.0")], "file")
    bad = tmp_path / "bad.ssp"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(bad, "w") as dst:
        for m in src.namelist():
            data = src.read(m)
            if m == "resources/m.ssm":
                data = data.replace(b'target="k"', b"")
            dst.writestr(m, data)
    assert main(["run", str(bad), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "resources/m.ssm: does not follow the SSP 1.0 schema" in err
    assert "'target' is required" in err and "Traceback" not in err


# ---- SSP 2.0 ----------------------------------------------------------------------------------

def typed_ssp2(tmp_path, tb, ft) -> object:
    """An SSP 2.0 file: FMI 3 connector types, Int64/UInt64/Float32 parameters, an array
    parameter (with its ssc:Dimension), an Enumeration by item name, a String array form."""
    params = {"u64_in": '<ssv:UInt64 value="18446744073709551614"/>',
              "i64_in": '<ssv:Int64 value="4611686018427387905"/>',
              "f32_in": '<ssv:Float32 value="0.25"/>',
              "gains": '<ssv:Float64 value="1 2 4.5"/>',
              "mode_in": '<ssv:Enumeration value="fast"/>',
              "label": '<ssv:String><ssv:Value value="hi"/></ssv:String>'}
    tbc = ('<ssd:Connector name="y" kind="output"><ssc:Float64/></ssd:Connector>'
           '<ssd:Connector name="i32_out" kind="output"><ssc:Int32/></ssd:Connector>'
           '<ssd:Connector name="gains" kind="parameter"><ssc:Float64>'
           '<ssc:Dimension size="3"/></ssc:Float64></ssd:Connector>')
    ftc = ('<ssd:Connector name="u" kind="input"><ssc:Float64/></ssd:Connector>'
           '<ssd:Connector name="iu" kind="input"><ssc:Int32/></ssd:Connector>')
    s = system(comp("tb", "TypedBlock.fmu", tbc, binding("resources/tb.ssv"))
               + comp("ft", "Feedthrough.fmu", ftc),
               conns=conn("tb.y", "ft.u") + conn("tb.i32_out", "ft.iu"))
    return write_ssp(tmp_path / "t2.ssp", ssd(s, experiment(1, step=0.5), "2.0"),
                     {"resources/TypedBlock.fmu": tb, "resources/Feedthrough.fmu": ft},
                     {"resources/tb.ssv": pset(params, "2.0")})


def test_ssp2_file_with_fmi3_types_runs(event_fmus, tmp_path, monkeypatch):
    path = typed_ssp2(tmp_path, event_fmus[("TypedBlock", "3.0")],
                      event_fmus[("Feedthrough", "3.0")])
    flat = read_ssp(path, tmp_path / "x")
    assert flat.version == "2.0"
    tb = flat.components["tb"]
    assert tb.parameters == {"u64_in": 2**64 - 2, "i64_in": 2**62 + 1, "gains": [1.0, 2.0, 4.5],
                             "mode_in": "fast", "label": "hi"}
    assert tb.start == {"f32_in": 0.25}
    assert [(c.src, c.dst) for c in flat.connections] == [("tb.i32_out", "ft.iu"),
                                                          ("tb.y", "ft.u")]
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(path), "--out", "r"]) == 0
    cols = read_log(tmp_path / "r" / "log.parquet")[0]
    assert cols["tb.gain_sum"][0] == 7.5 and cols["tb.mode_out"][0] == 3
    assert int(cols["tb.u64_out"][0]) == 2**64 - 1  # exact: 2^64 - 2 + 1
    assert int(cols["tb.i64_out"][0]) == (2 * (2**62 + 1) + 2**63) % 2**64 - 2**63
    np.testing.assert_array_equal(cols["ft.iy"], cols["tb.i32_out"])


def test_ssp2_schema_check_maps_the_new_types_and_reports_what_it_cannot_check():
    from lxml import etree

    ok = etree.fromstring(pset({"a": '<ssv:Int64 value="-5000000000"/>',
                                "b": '<ssv:Float64 value="1 2 3"/>'}, "2.0").encode())
    assert schema_problems(ok, "ssv") == ([], [])
    bad = etree.fromstring(pset({"a": '<ssv:Int64 valu="1"/>'}, "2.0").encode())
    errors, _ = schema_problems(bad, "ssv")
    assert errors and "line 2" in errors[0] and "'valu' is not allowed" in errors[0] or \
        "'value' is required" in " ".join(errors)
    v1 = etree.fromstring(pset({"a": '<ssv:Int64 value="1"/>'}, "1.0").encode())
    assert schema_problems(v1, "ssv")[0]  # Int64 is not SSP 1.0


def test_ssp2_elements_unknown_to_ssp1_are_warned_not_refused(event_fmus, tmp_path, caplog):
    s = system(comp("ft", "Feedthrough.fmu",
                    '<ssd:Connector name="u" kind="input"><ssc:Float64/>'
                    '<ssd:Future xmlns:ssd="http://ssp-standard.org/SSP1/'
                    'SystemStructureDescription"/></ssd:Connector>'))
    path = write_ssp(tmp_path / "f.ssp", ssd(s, experiment(1, step=0.5), "2.0"),
                     {"resources/Feedthrough.fmu": event_fmus[("Feedthrough", "3.0")]})
    with caplog.at_level(logging.WARNING):
        load_scenario(path)
    assert "only SSP 2.0 defines were not validated" in caplog.text
    # the same element in an SSP 1.0 file is a schema error
    path1 = write_ssp(tmp_path / "f1.ssp", ssd(s.replace("Float64", "Real"), experiment(1)),
                      {"resources/Feedthrough.fmu": event_fmus[("Feedthrough", "3.0")]})
    with pytest.raises(ScenarioError, match="does not follow the SSP 1.0 schema"):
        load_scenario(path1, ["run.step=0.5"])


# ---- export -----------------------------------------------------------------------------------

@pytest.mark.parametrize("version", ["1.0", "2.0"])
def test_export_writes_the_requested_version_and_reads_back(project_fmus, tmp_path, version):
    from lxml import etree

    scenario = ROOT / "scenarios/tan_terrain.toml"
    out = tmp_path / f"e{version}.ssp"
    sets = ["run.duration=20", "fmus.vehicle.parameters={max_internal_step=0.05}"]
    args = ["ssp", "export", str(scenario), "--out", str(out), "--ssp-version", version]
    assert main([*args, *(a for s in sets for a in ("--set", s))]) == 0
    with zipfile.ZipFile(out) as zf:
        root = etree.fromstring(zf.read("SystemStructure.ssd"))
        assert root.get("version") == version
        assert schema_problems(root, "ssd") == ([], [])
        for m in zf.namelist():
            if m.endswith(".ssv"):
                ps = etree.fromstring(zf.read(m))
                assert ps.get("version") == version and schema_problems(ps, "ssv") == ([], [])
        types = {el.tag.rpartition("}")[2] for el in root.iter()
                 if el.getparent() is not None and el.getparent().tag.endswith("}Connector")}
    assert types == ({"Float64"} if version == "2.0" else {"Real"})
    src = load_scenario(scenario, sets).spec
    loaded = load_scenario(out)  # owns the extracted FMUs
    back = loaded.spec
    for name, f in src.fmus.items():
        g = back.fmus[name]
        assert sha256_file(ROOT / "scenarios" / f.path) == sha256_file(g.path)
        assert (g.interface, g.parameters, g.start) == (f.interface, f.parameters, f.start)
    assert sorted(map(tuple, back.connections)) == sorted(map(tuple, src.connections))


def test_export_version_is_checked(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["ssp", "export", str(ROOT / "scenarios/tan_terrain.toml"), "--out",
              str(tmp_path / "e.ssp"), "--ssp-version", "3.0"])
    assert info.value.code == 2 and "--ssp-version" in capsys.readouterr().err
    assert not (tmp_path / "e.ssp").exists()


def test_export_of_array_parameters_needs_ssp2(event_fmus, tmp_path, capsys):
    from test_system import scenario

    sc = scenario(tmp_path, {"s": {"path": event_fmus[("Signals", "3.0")],
                                   "start": {"u": [1.0, 0.5, -2.0], "i64_in": 2**62 + 1}}},
                  1.0, 0.5)
    assert main(["ssp", "export", str(sc), "--out", str(tmp_path / "a1.ssp")]) == 0
    assert "fmus.s: u, i64_in not exported (arrays and integers beyond 32 bits need SSP 2.0" \
        in capsys.readouterr().out
    assert load_scenario(tmp_path / "a1.ssp").spec.fmus["s"].start == {}
    assert main(["ssp", "export", str(sc), "--out", str(tmp_path / "a2.ssp"),
                 "--ssp-version", "2.0"]) == 0
    loaded = load_scenario(tmp_path / "a2.ssp")
    assert loaded.spec.fmus["s"].start == {"u": [1.0, 0.5, -2.0]}
    assert loaded.spec.fmus["s"].parameters == {"i64_in": 2**62 + 1}
