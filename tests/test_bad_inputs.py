"""Bad input, table-driven (issue 10): each case runs the command line (in this process, through
``uwcosim.cli.main``) and checks the exit status, a single line on stderr naming the file/key,
no traceback, and that nothing written contradicts what happened (no summary saying ``ok``, no
report or figures, no campaign table, no diff plots). Plus Hypothesis properties: arbitrary
TOML values in a scenario or a ``--set`` never give a traceback."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uwcosim.core.errors import ScenarioError
from uwcosim.scenario import load_scenario
from uwcosim.scenario.overrides import parse_overrides

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"
FAST = ["--no-figures", "--set", "run.duration=5", "--set", 'estimators={ekf={type="ekf"}}']


def _log(path: Path, cols: dict, meta: dict | None = None) -> Path:
    table = pa.table(cols)
    if meta is not None:
        table = table.replace_schema_metadata({"uwcosim": json.dumps(meta)})
    pq.write_table(table, path)
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory, project_fmus) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("bad")
    f: dict[str, Path] = {"dir": d}
    (d / "latin1.toml").write_bytes(SCEN.read_bytes().replace(b'name = "', b'name = "\xe9', 1))
    f["latin1"] = d / "latin1.toml"
    (d / "invalid.toml").write_text("[run\nduration = 5\n")
    f["invalid"] = d / "invalid.toml"
    x = np.linspace(0.0, 25_000.0, 20)
    depth = np.full((20, 20), 1000.0)
    np.savez(d / "strings.npz", x=x, y=x, depth=np.full((20, 20), "deep"))
    bad = depth.copy()
    bad[3, 4] = np.nan
    np.savez(d / "nan.npz", x=x, y=x, depth=bad)
    np.savez(d / "nodepth.npz", x=x, y=x, height=depth)
    np.savez(d / "tiny.npz", x=x[:3], y=x[:3], depth=depth[:3, :3])
    np.savez(d / "noaxes.npz", depth=depth)
    (d / "map.txt").write_text("1 2 3\n")
    (d / "garbage.npz").write_bytes(b"not a zip")
    src = project_fmus / "AUVKinematics.fmu"
    (d / "truncated.fmu").write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    (d / "text.fmu").write_text("not an archive")
    with zipfile.ZipFile(d / "empty.fmu", "w"):
        pass
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(d / "nomd.fmu", "w") as zout:
        for item in zin.infolist():
            if item.filename != "modelDescription.xml":
                zout.writestr(item, zin.read(item))
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(d / "other.fmu", "w") as zout:
        for item in zin.infolist():
            name = item.filename.replace("x86_64-linux", "aarch64-darwin")
            zout.writestr(name.replace(".so", ".dylib"), zin.read(item))
    # FMUs that cannot run: FMI 3 clocks, scheduled execution only, a binary that is no library
    def remake(name, md=None, binary=None):
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(d / name, "w") as zout:
            for item in zin.infolist():
                data = zin.read(item)
                if item.filename == "modelDescription.xml" and md is not None:
                    data = md(data.decode()).encode()
                if item.filename.endswith(".so") and binary is not None:
                    data = binary
                zout.writestr(item, data)

    remake("clocked.fmu", lambda t: t.replace(
        "<ModelVariables>", '<ModelVariables><Clock name="tick" valueReference="9000" '
        'causality="input" variability="discrete" intervalVariability="constant" '
        'intervalDecimal="0.5"/>'))
    remake("scheduled.fmu", lambda t: re.sub(
        r"<CoSimulation [^>]*/>", '<ScheduledExecution modelIdentifier="AUVKinematics"/>',
        re.sub(r"<ModelExchange [^>]*/>", "", t)))
    remake("junkbin.fmu", binary=b"\x7fELF" + b"\0" * 60)
    # issue 24, item 19: modelDescription.xml problems in Python's words before
    remake("fmi1.fmu", lambda t: t.replace('fmiVersion="3.0"', 'fmiVersion="1.0"'))
    remake("noversion.fmu", lambda t: t.replace('fmiVersion="3.0"', ""))
    # issue 24, item 19 (the leftovers): what fmpy reads with Python's words, e.g. "(6)" =
    # KeyError 6, a <ModelStructure> entry naming a value reference no variable has
    remake("dangling6.fmu", lambda t: t.replace('name="der(y)" valueReference="6"',
                                                'name="der(y)" valueReference="60"'))
    remake("novr.fmu", lambda t: t.replace('name="x" valueReference="1" ', 'name="x" '))
    remake("baddeps.fmu", lambda t: re.sub(r'(<Output valueReference="1" dependencies=)"[^"]*"',
                                           r'\1"a b"', t))
    remake("novars.fmu", lambda t: re.sub(r"<ModelVariables>.*</ModelVariables>", "", t,
                                          flags=re.S))
    remake("noname.fmu", lambda t: t.replace('<Float64 name="psi" ', "<Float64 "))
    remake("derivative.fmu", lambda t: t.replace('derivative="1"', 'derivative="99"'))
    remake("noident.fmu", lambda t: t.replace('<CoSimulation modelIdentifier="AUVKinematics"',
                                              "<CoSimulation"))
    remake("causality.fmu", lambda t: t.replace('name="psi" valueReference="9" description='
                                                '"Heading" causality="input"', 'name="psi" '
                                                'valueReference="9" description="Heading" '
                                                'causality="bogus"'))
    with zipfile.ZipFile(project_fmus / "AUVKinematics_fmi2.fmu") as zin, \
            zipfile.ZipFile(d / "fmi2as3.fmu", "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'fmiVersion="2.0"', b'fmiVersion="3.0"', 1)
            zout.writestr(item, data)
    with zipfile.ZipFile(project_fmus / "AUVKinematics_fmi2.fmu") as zin, \
            zipfile.ZipFile(d / "noguid2.fmu", "w") as zout:  # fmpy: None.encode() of the guid
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb'\s+guid="[^"]*"', b"", data)
            zout.writestr(item, data)
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(d / "latin1md.fmu", "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'description="', b'description="\xe9', 1)
            zout.writestr(item, data)
    # campaign specs
    variant = f'[[variants]]\nname = "v"\nscenario = "{SCEN}"\nset = ["run.duration=5"]\n'
    specs = {
        "c_ok": f"seed = 1\nruns = 1\n{variant}",
        "c_huge": f"seed = 1\nruns = 1000000000\n{variant}",
        "c_unknown": f"seed = 1\nrunz = 1\n{variant}",
        "c_noruns": f"seed = 1\nruns = 0\n{variant}",
        "c_seedstr": f'seed = "1"\n{variant}',
        "c_novariants": "seed = 1\nvariants = []\n",
        "c_dup": f"seed = 1\n{variant}{variant}",
        "c_missing_scen": '[[variants]]\nname = "v"\nscenario = "nope.toml"\n',
        "c_badname": f'[[variants]]\nname = "a b"\nscenario = "{SCEN}"\n',
        "c_badset": f'[[variants]]\nname = "v"\nscenario = "{SCEN}"\nset = ["run.bogus=1"]\n',
        "c_invalid": "seed = [\n",
    }
    for name, text in specs.items():
        (d / f"{name}.toml").write_text(text)
        f[name] = d / f"{name}.toml"
    (d / "c_latin1.toml").write_bytes(b"name = \"\xe9\"\n")
    f["c_latin1"] = d / "c_latin1.toml"
    # regression logs
    t = np.arange(10.0)
    meta = {"scenario_sha256": "a" * 64, "scenario_path": "s.toml"}
    f["run"] = _log(d / "run.parquet", {"time": t, "x": t * 2.0}, meta)
    f["base"] = _log(d / "base.parquet", {"time": t, "x": t * 2.0 + 1.0}, meta)
    f["strings"] = _log(d / "strings.parquet", {"time": t, "x": [str(v) for v in t]})
    f["other_cols"] = _log(d / "other_cols.parquet", {"time": t, "y": t})
    f["late"] = _log(d / "late.parquet", {"time": t + 100.0, "x": t})
    f["nontime"] = _log(d / "nontime.parquet", {"t": t, "x": t})
    f["decreasing"] = _log(d / "decreasing.parquet", {"time": t[::-1], "x": t})
    (d / "notparquet.parquet").write_text("hello")
    f["notparquet"] = d / "notparquet.parquet"
    # issue 24: deep nesting, odd scenario paths, outputs that cannot be written
    (d / "deep_arrays.toml").write_text("x = " + "[" * 500 + "]" * 500 + "\n")
    (d / "deep_tables.toml").write_text("x = " + "{a = " * 2000 + "1" + "}" * 2000 + "\n")
    (d / "folder.toml").mkdir()
    os.mkfifo(d / "fifo.toml")
    (d / "loop.toml").symlink_to(d / "loop.toml")
    plain = d / "plain_run"
    plain.mkdir()
    _log(plain / "log.parquet", {"time": t, "x": t * 2.0}, meta)
    ro = d / "ro_run"  # a run folder whose report.md cannot be written (root ignores modes)
    ro.mkdir()
    _log(ro / "log.parquet", {"time": t, "x": t * 2.0}, meta)
    (ro / "report.md").mkdir()
    forged = d / "forged"
    forged.mkdir()
    (forged / "campaign.json").write_text('{"sha256": 1, "fingerprint": "garbage"}')
    f["forged"] = forged
    return f


def S(*items: str) -> list[str]:
    """``--set`` arguments for the fast run of tan_terrain."""
    return ["run", str(SCEN), *[a for i in items for a in ("--set", i)]]


def MAP(f, name: str) -> list[str]:
    """A fast run with the map file ``name`` of the fixture folder."""
    return [*S(f'map={{kind="file", file="{f["dir"] / name}"}}'), *FAST]


def FMU(f, name: str) -> list[str]:
    """A fast run with the vehicle FMU ``name`` of the fixture folder."""
    return [*S(f'fmus.vehicle.path="{f["dir"] / name}"'), *FAST]


# (id, argv builder, exit status, text the message contains)
CASES = [
    # -- scenario keys: types, ranges, finiteness (refused at load) --
    ("duration-inf", lambda f: S("run.duration=inf"), 2, "key 'run.duration'"),
    ("duration-1e300", lambda f: S("run.duration=1e300"), 2, "steps, more than"),
    ("duration-negative", lambda f: S("run.duration=-5"), 2, "key 'run.duration'"),
    ("duration-string", lambda f: S('run.duration="50"'), 2, "key 'run.duration'"),
    ("duration-not-whole", lambda f: S("run.duration=10.5"), 2, "whole number of steps"),
    ("step-1e-300", lambda f: S("run.step=1e-300"), 2, "steps, more than"),
    ("step-zero", lambda f: S("run.step=0"), 2, "key 'run.step'"),
    ("start-time-nan", lambda f: S("run.start_time=nan"), 2, "key 'run.start_time'"),
    ("seed-float", lambda f: S("run.seed=1.5"), 2, "key 'run.seed'"),
    ("seed-string", lambda f: S('run.seed="3"'), 2, "key 'run.seed'"),
    ("fmu-timeout-negative", lambda f: S("run.fmu_timeout_s=-1"), 2, "key 'run.fmu_timeout_s'"),
    ("run-unknown-key", lambda f: S("run.stp=1"), 2, "key 'run.stp': unknown key"),
    ("q-psd-nan", lambda f: S("model.q_psd=nan"), 2, "key 'model.q_psd'"),
    ("q-psd-nan-entry", lambda f: S("model.q_psd=[nan,1.0,1.0,1.0]"), 2, "key 'model.q_psd.0'"),
    ("q-psd-negative", lambda f: S("model.q_psd=[-1.0,1.0,1.0,1.0]"), 2,
     "key 'model.q_psd.0'"),
    ("q-psd-inf", lambda f: S("model.q_psd=[1.0,inf,1.0,1.0]"), 2, "key 'model.q_psd.1'"),
    ("initial-std-inf", lambda f: S("estimation.initial_std=[inf,1.0,1.0,1.0]"), 2,
     "key 'estimation.initial_std.0'"),
    ("initial-std-zero", lambda f: S("estimation.initial_std=[0.0,1.0,1.0,1.0]"), 2,
     "key 'estimation.initial_std.0'"),
    ("position-bound-reversed", lambda f: S("estimation.position_bound=[1.0,0.0,0.0,1.0]"), 2,
     "'position_bound' must be"),
    ("map-extent-reversed", lambda f: S("map.extent=[25000.0,0.0,0.0,25000.0]"), 2,
     "'extent' must be"),
    ("map-too-many-cells", lambda f: S("map.resolution=0.01"), 2, "synthetic map"),
    ("map-resolution-zero", lambda f: S("map.resolution=0"), 2, "key 'map.resolution'"),
    ("noise-psd-nan", lambda f: S("noise.process.psd=[nan,1.0,1.0,1.0]"), 2,
     "key 'noise.process.psd.0'"),
    ("loss-probability", lambda f: S('sensors.depth.loss={model="bernoulli", p=1.5}'), 2,
     "key 'sensors.depth.loss.p'"),
    ("sensor-period-zero", lambda f: S("sensors.depth.period=0"), 2,
     "key 'sensors.depth.period'"),
    ("chunk-steps-string", lambda f: S('log.chunk_steps="10"'), 2, "key 'log.chunk_steps'"),
    ("figures-string", lambda f: S('output.figures="yes"'), 2, "key 'output.figures'"),
    ("timeout-zero", lambda f: S("fmus.vehicle.timeout_s=0"), 2,
     "key 'fmus.vehicle.timeout_s'"),
    ("set-without-equals", lambda f: S("run.duration"), 2, "expected KEY=VALUE"),
    ("set-into-a-value", lambda f: S("run.duration.x=1"), 2, "is not a table"),
    ("set-replaces-a-table", lambda f: S("run=1"), 2, "key 'run'"),
    # -- scenario keys checked against the FMUs and filters (after loading) --
    ("estimator-typo", lambda f: [*S('estimators.ekf.type="ekff"'), *FAST[:1]], 2,
     "unknown estimator 'ekff'"),
    ("point-mass-memory", lambda f: [*S('estimators={pm={type="point_mass", '
                                        'n_points=100000}}', "run.duration=5"), "--no-figures"],
     2, "GiB"),
    ("estimator-initial-std-nan", lambda f: S("estimators.ekf.initial_std=[nan,1.0,1.0,1.0]"),
     2, "key 'estimators.ekf.initial_std.0'"),
    ("unknown-variable", lambda f: [*S('connections=[["vehicle.xx", "dvl.vx"]]'), *FAST], 2,
     "has no variable 'xx'"),
    ("log-pattern-matches-nothing", lambda f: [*S('log.signals=["vehicle.*", "vehicle.xx"]'),
                                               *FAST], 2,
     "key 'log.signals': pattern 'vehicle.xx' matches no signal (nearest: vehicle.x"),
    ("log-pattern-names-an-input", lambda f: [*S('log.signals=["vehicle.psi"]'), *FAST], 2,
     "pattern 'vehicle.psi' matches no signal: 'vehicle.psi' has causality 'input'"),
    # -- files --
    ("scenario-missing", lambda f: ["run", str(f["dir"] / "nope.toml")], 2, "not found"),
    ("scenario-not-utf8", lambda f: ["run", str(f["latin1"])], 2, "not a UTF-8 text file"),
    ("scenario-invalid-toml", lambda f: ["run", str(f["invalid"])], 2, "invalid TOML"),
    ("map-string-depths", lambda f: MAP(f, "strings.npz"), 2, "strings.npz"),
    ("map-nan", lambda f: MAP(f, "nan.npz"),
     2, "nan.npz: bathymetry grid contains NaN"),
    ("map-no-depth", lambda f: MAP(f, "nodepth.npz"), 2, "no depth variable"),
    ("map-tiny", lambda f: MAP(f, "tiny.npz"), 2, "tiny.npz: "),
    ("map-no-axes", lambda f: MAP(f, "noaxes.npz"), 2, "no coordinate axes"),
    ("map-unknown-format", lambda f: MAP(f, "map.txt"), 2, "unknown map format"),
    ("map-garbage", lambda f: MAP(f, "garbage.npz"), 2, "cannot read map"),
    ("map-missing", lambda f: MAP(f, "no.npz"), 2, "map file not found"),
    ("map-file-without-file", lambda f: S('map={kind="file"}'), 2, "needs 'file'"),
    # -- FMU archives --
    ("fmu-missing", lambda f: FMU(f, "no.fmu"), 3,
     "FMU not found"),
    ("fmu-truncated", lambda f: FMU(f, "truncated.fmu"), 3, "not a valid FMU archive"),
    ("fmu-not-zip", lambda f: FMU(f, "text.fmu"),
     3, "not a valid FMU archive"),
    ("fmu-empty-zip", lambda f: FMU(f, "empty.fmu"), 3, "empty.fmu"),
    ("fmu-no-model-description", lambda f: FMU(f, "nomd.fmu"), 3, "nomd.fmu"),
    ("fmu-other-platform", lambda f: FMU(f, "other.fmu"), 3, "no binary for this platform"),
    ("fmu-info-missing", lambda f: ["fmu", "info", str(f["dir"] / "no.fmu")], 3, "no.fmu"),
    ("fmu-clocks", lambda f: FMU(f, "clocked.fmu"), 3,
     "cannot be run: it has FMI 3 clocks (tick)"),
    ("fmu-scheduled-execution-only", lambda f: FMU(f, "scheduled.fmu"), 3,
     "cannot be run: it needs scheduled execution"),
    ("fmu-binary-not-a-library", lambda f: FMU(f, "junkbin.fmu"), 3, "cannot instantiate"),
    ("start-unknown-variable", lambda f: S("fmus.vehicle.start.vxx=1"), 2,
     "key 'fmus.vehicle.start.vxx': FMU 'vehicle' (AUVKinematics.fmu) has no variable 'vxx' "
     "(nearest: vx)"),
    ("fmu-fmi-1.0", lambda f: FMU(f, "fmi1.fmu"), 3,
     "fmi1.fmu: invalid modelDescription.xml: fmiVersion '1.0': uwcosim runs FMI 2.0 and 3.0"),
    ("fmu-no-fmi-version", lambda f: FMU(f, "noversion.fmu"), 3,
     "noversion.fmu: invalid modelDescription.xml: no fmiVersion attribute"),
    ("fmu-xml-not-utf8", lambda f: FMU(f, "latin1md.fmu"), 3,
     "latin1md.fmu: invalid modelDescription.xml: not well-formed XML in its declared "
     "encoding"),
    ("estimation-initial-std-overflows",
     lambda f: [*S("estimation.initial_std=[1e200, 1e200, 0.05, 0.05]"), *FAST], 2,
     "key 'estimation.initial_std': 1e+200 squared is not a finite variance"),
    ("fmu-fmi2-no-guid", lambda f: FMU(f, "noguid2.fmu"), 3,
     "noguid2.fmu: FMU 'vehicle' cannot be run: its modelDescription.xml has no guid (FMI 2.0 "
     "requires one)"),
    ("fmu-check-fmi2-no-guid", lambda f: ["fmu", "check", str(f["dir"] / "noguid2.fmu"),
                                          "--role", "vehicle"], 3,
     "FMU 'noguid2' cannot be run: its modelDescription.xml has no guid"),
    ("fmu-md-dangling-value-reference", lambda f: FMU(f, "dangling6.fmu"), 3,
     "dangling6.fmu: invalid modelDescription.xml: line 56: <ContinuousStateDerivative ...>: "
     "valueReference 6 names no variable (no variable has value reference 6)"),
    ("fmu-md-no-value-reference", lambda f: FMU(f, "novr.fmu"), 3,
     "novr.fmu: invalid modelDescription.xml: line 30: <Float64 ...>: variable 'x' has "
     "valueReference=None, expected an unsigned 32-bit integer"),
    ("fmu-md-dependencies-not-integers", lambda f: FMU(f, "baddeps.fmu"), 3,
     "<Output ...>: dependencies='a' is not an integer"),
    ("fmu-md-no-model-variables", lambda f: FMU(f, "novars.fmu"), 3,
     "invalid modelDescription.xml: no <ModelVariables> element"),
    ("fmu-md-variable-without-name", lambda f: FMU(f, "noname.fmu"), 3,
     "invalid modelDescription.xml: line 38: <Float64 ...>: a variable without a name"),
    ("fmu-md-dangling-derivative", lambda f: FMU(f, "derivative.fmu"), 3,
     "line 34: <Float64 ...>: derivative 99 names no variable"),
    ("fmu-md-no-model-identifier", lambda f: FMU(f, "noident.fmu"), 3,
     "invalid modelDescription.xml: <CoSimulation> has no modelIdentifier (the name of its "
     "binary, binaries/x86_64-linux/NAME.so)"),
    ("fmu-md-schema", lambda f: FMU(f, "causality.fmu"), 3,
     "invalid modelDescription.xml: line 38: Element 'Float64', attribute 'causality': "
     "[facet 'enumeration'] The value 'bogus' is not an element of the set"),
    ("fmu-md-fmi2-variables-as-fmi3", lambda f: FMU(f, "fmi2as3.fmu"), 3,
     "invalid modelDescription.xml: line 29: <ScalarVariable ...>: a FMI 2.0 <ScalarVariable> "
     "element in <ModelVariables> of an FMU with fmiVersion='3.0'"),
    # -- command-line arguments --
    ("run-no-scenario", lambda f: ["run"], 2, "required: scenario"),
    ("run-seed-not-int", lambda f: ["run", str(SCEN), "--seed", "x"], 2, "--seed"),
    ("unknown-command", lambda f: ["bogus"], 2, "invalid choice"),
    ("out-is-a-file", lambda f: ["run", str(SCEN), "--out", str(f["invalid"])], 2,
     "not a directory"),
    # -- campaign specs and arguments --
    ("campaign-runs-negative", lambda f: ["campaign", str(f["c_ok"]), "--runs", "-1"], 2,
     "--runs -1"),
    ("campaign-runs-zero", lambda f: ["campaign", str(f["c_ok"]), "--runs", "0"], 2, "--runs 0"),
    ("campaign-workers-zero", lambda f: ["campaign", str(f["c_ok"]), "--workers", "0"], 2,
     "--workers 0"),
    ("campaign-missing", lambda f: ["campaign", str(f["dir"] / "no.toml")], 2, "not found"),
    ("campaign-invalid-toml", lambda f: ["campaign", str(f["c_invalid"])], 2, "invalid TOML"),
    ("campaign-not-utf8", lambda f: ["campaign", str(f["c_latin1"])], 2, "not a UTF-8"),
    ("campaign-unknown-key", lambda f: ["campaign", str(f["c_unknown"])], 2,
     "key 'runz': unknown key"),
    ("campaign-runs-zero-in-spec", lambda f: ["campaign", str(f["c_noruns"])], 2, "key 'runs'"),
    ("campaign-seed-string", lambda f: ["campaign", str(f["c_seedstr"])], 2, "key 'seed'"),
    ("campaign-no-variants", lambda f: ["campaign", str(f["c_novariants"])], 2,
     "key 'variants'"),
    ("campaign-duplicate-variants", lambda f: ["campaign", str(f["c_dup"])], 2, "unique"),
    ("campaign-scenario-missing", lambda f: ["campaign", str(f["c_missing_scen"])], 2,
     "key 'variants[0].scenario'"),
    ("campaign-variant-name", lambda f: ["campaign", str(f["c_badname"])], 2,
     "key 'variants.0.name'"),
    ("campaign-variant-override", lambda f: ["campaign", str(f["c_badset"])], 2,
     "key 'run.bogus'"),
    # -- regress arguments --
    ("regress-rtol-nan", lambda f: ["regress", str(f["run"]), str(f["base"]), "--rtol", "nan"],
     2, "--rtol nan"),
    ("regress-atol-nan", lambda f: ["regress", str(f["run"]), str(f["base"]), "--atol", "nan"],
     2, "--atol nan"),
    ("regress-ttol-nan", lambda f: ["regress", str(f["run"]), str(f["base"]), "--ttol", "nan"],
     2, "--ttol nan"),
    ("regress-rtol-negative", lambda f: ["regress", str(f["run"]), str(f["base"]), "--rtol",
                                         "-1"], 2, "--rtol -1"),
    ("regress-atol-inf", lambda f: ["regress", str(f["run"]), str(f["base"]), "--atol", "inf"],
     2, "--atol inf"),
    ("regress-baseline-missing", lambda f: ["regress", str(f["run"]), str(f["dir"] / "b.pq")],
     2, "baseline not found"),
    ("regress-run-missing", lambda f: ["regress", str(f["dir"] / "r.pq"), str(f["base"])], 2,
     "run log not found"),
    ("regress-not-parquet", lambda f: ["regress", str(f["notparquet"]), str(f["base"])], 2,
     "not a readable Parquet run log"),
    ("regress-string-columns", lambda f: ["regress", str(f["strings"]), str(f["base"])], 2,
     "column 'x' is not numeric"),
    ("regress-no-common-signals", lambda f: ["regress", str(f["other_cols"]), str(f["base"])], 2,
     "no signals in common"),
    ("regress-no-overlap", lambda f: ["regress", str(f["late"]), str(f["base"])], 2,
     "does not overlap"),
    ("regress-no-time", lambda f: ["regress", str(f["nontime"]), str(f["base"])], 2,
     "no 'time' column"),
    ("regress-time-decreasing", lambda f: ["regress", str(f["decreasing"]), str(f["base"])], 2,
     "non-decreasing"),
    ("regress-plots-unwritable", lambda f: ["regress", str(f["run"]), str(f["base"]),
                                            "--plots", "/proc/x"], 2,
     "/proc/x: cannot write the diff plots"),
    ("baseline-check-rtol-nan", lambda f: ["baseline", "check", "--rtol", "nan"], 2,
     "--rtol nan"),
    # -- issue 24, item 11: deep nesting (a RecursionError and 3000 lines of traceback) --
    ("deep-arrays-in-a-file", lambda f: ["run", str(f["dir"] / "deep_arrays.toml")], 2,
     "deep_arrays.toml: arrays or tables nested too deeply (at most 64 levels)"),
    ("deep-tables-in-a-file", lambda f: ["check", str(f["dir"] / "deep_tables.toml")], 2,
     "deep_tables.toml: arrays or tables nested too deeply"),
    ("deep-arrays-in-set", lambda f: S("run.duration=" + "[" * 500 + "]" * 500), 2,
     "the value is nested too deeply"),
    ("deep-tables-in-set", lambda f: S("run={" + "a={" * 2000 + "}" * 2001), 2,
     "the value is nested too deeply"),
    ("deep-but-parsable-in-set", lambda f: S("run.duration=" + "[" * 80 + "]" * 80), 2,
     "the value is nested too deeply (at most 64 levels)"),
    # -- item 8: memory estimated up front (5 GB and more before, in check as in run) --
    ("pf-memory-run", lambda f: [*S('estimators={pf={type="pf", n_particles=1000000000}}',
                                    "run.duration=5"), "--no-figures"], 2,
     "key 'estimators.pf': n_particles 1000000000 needs about 313 GiB (limit 4 GiB; raise it "
     "with UWCOSIM_MEMORY_LIMIT_GIB=N): use fewer particles"),
    ("pf-memory-check", lambda f: ["check", str(SCEN), "--set",
                                   'estimators={pf={type="rbpf", n_particles=1000000000}}'], 2,
     "key 'estimators.pf': n_particles 1000000000 needs about"),
    ("pfm-psi-memory-check", lambda f: ["check", str(SCEN), "--set",
                                        'estimators={p={type="pfm_psi", grid_factor=1e6}}'], 2,
     "key 'estimators.p': K 10, grid_factor 1e+06 (21093750^2 grid points) needs about"),
    ("pfm-psi-memory-run", lambda f: [*S('estimators={p={type="pfm_psi", K=100000}}'),
                                      "--no-figures"], 2, "use a smaller K or grid_factor"),
    ("campaign-runs-1e9", lambda f: ["campaign", str(f["c_ok"]), "--runs", "1000000000"], 2,
     "--runs 1000000000 (1000000000 runs of 1 variant: their tasks, futures and records) "
     "needs about 3.81e+03 GiB (limit 4 GiB"),
    ("campaign-runs-1e9-in-spec", lambda f: ["campaign", str(f["c_huge"])], 2,
     "c_huge.toml: key 'runs' = 1000000000 (1000000000 runs of 1 variant"),
    ("campaign-workers-1000-oversubscribed", lambda f: ["campaign", str(f["c_ok"]), "--workers",
                                                        "1000", "--oversubscribe"], 2,
     "--workers 1000 --oversubscribe (about 0.3 GiB per process) needs about 300 GiB"),
    # -- item 12: outputs that cannot be written (PermissionError/IsADirectoryError before) --
    ("report-out-unwritable", lambda f: ["report", str(f["dir"] / "plain_run"), "--out",
                                         "/proc/x"], 2, "/proc/x"),
    ("report-in-a-read-only-run", lambda f: ["report", str(f["dir"] / "ro_run")], 2,
     "report.md: cannot read or write (Is a directory)"),
    ("ssp-export-out-unwritable", lambda f: ["ssp", "export", str(SCEN), "--out",
                                             "/proc/x.ssp"], 2, "/proc/x.ssp: cannot"),
    ("ssp-export-out-a-folder", lambda f: ["ssp", "export", str(SCEN), "--out",
                                           str(f["dir"])], 2, "Is a directory"),
    ("fmu-build-out-unwritable", lambda f: ["fmu", "build", "--out", "/proc/x"], 2,
     "/proc/x: cannot"),
    ("verify-out-unwritable", lambda f: ["verify", "example1", "--out", "/proc/x"], 2,
     "/proc/x: cannot"),
    # -- item 13 --
    ("export-mat-string-column", lambda f: ["export", str(f["strings"]), "--mat"], 1,
     "column 'x' is not numeric or boolean; a .mat export holds numbers only (use --csv)"),
    ("export-mat-out-unwritable", lambda f: ["export", str(f["run"]), "--mat", "--out",
                                             "/proc/x.mat"], 1,
     "/proc/x.mat: cannot write (No such file"),
    ("campaign-scheduler-not-a-url", lambda f: ["campaign", str(f["c_ok"]), "--scheduler",
                                                "not a url"], 2,
     "--scheduler 'not a url': not a scheduler address (expected tcp://HOST:PORT"),
    ("campaign-resume-forged-manifest", lambda f: ["campaign", str(f["c_ok"]), "--resume",
                                                   "--out", str(f["forged"])], 2,
     "campaign.json: unreadable campaign manifest"),
    # -- item 19: a scenario path that is no file ("scenario file not found" before) --
    ("scenario-is-a-folder", lambda f: ["run", str(f["dir"] / "folder.toml")], 2,
     "folder.toml: is a folder; expected a scenario file"),
    ("scenario-is-a-fifo", lambda f: ["check", str(f["dir"] / "fifo.toml")], 2,
     "fifo.toml: not a regular file (a FIFO, socket or device)"),
    ("scenario-symlink-loop", lambda f: ["run", str(f["dir"] / "loop.toml")], 2,
     "loop.toml: a symbolic link to nothing (or a loop of links)"),
    # -- item 20: input silently ignored --
    ("set-value-with-a-newline", lambda f: S("run.duration=20\nstep=2.0"), 2,
     "the value is not one TOML value (a new line starts key 'step')"),
    ("set-bare-word-with-a-newline", lambda f: S("estimators.ekf.type=ekf\nx y"), 2,
     "the value is not one TOML value (it spans lines)"),
    ("out-empty", lambda f: ["run", str(SCEN), "--out", ""], 2, "--out '': an empty path"),
]


@pytest.fixture
def cli(capsys):
    """Run ``uwcosim.cli.main`` here: ``(status, stdout, stderr)``; signal handlers restored."""
    from uwcosim.cli import main

    saved = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}

    def run(argv):
        try:
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse
                code = exc.code
        finally:
            for s, h in saved.items():
                signal.signal(s, h)
        out, err = capsys.readouterr()
        return code, out, err

    return run


def _consistent(out: Path) -> None:
    """Nothing in ``out`` claims a success or shows results of a failed command."""
    if not out.exists():
        return
    summary = out / "summary.json"
    if summary.exists():
        assert json.loads(summary.read_text())["status"] != "ok"
    for name in ("report.md", "table.md", "runs.parquet", "regress"):
        assert not (out / name).exists(), name
    assert not list(out.glob("*.png"))
    assert not (out / "log.parquet.journal").exists()


@pytest.mark.parametrize(("argv", "code", "expected"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_leaves_a_consistent_state(files, cli, tmp_path, argv, code,
                                                             expected, monkeypatch):
    monkeypatch.chdir(tmp_path)  # default output folders (runs/...) land here
    args = argv(files)
    if args[0] in ("run", "campaign") and "--out" not in args:
        args += ["--out", str(tmp_path / "out")]
    status, _, err = cli(args)
    assert status == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and expected in lines[0], err
    _consistent(tmp_path / "out")
    _consistent(tmp_path)


@pytest.mark.parametrize(("name", "expected"), [
    ("clocked.fmu", "cannot be run by the master: it has FMI 3 clocks (tick)"),
    ("scheduled.fmu", "it needs scheduled execution (FMI 3 ScheduledExecution is its only"),
    ("junkbin.fmu", "AUVKinematics.so cannot be loaded"),
])
def test_fmu_check_says_incompatible_for_an_fmu_that_cannot_run(files, cli, name, expected):
    """``fmu check`` said "compatible" for these (issue 21, item 8)."""
    status, out, err = cli(["fmu", "check", str(files["dir"] / name), "--role", "vehicle"])
    assert status == 1, out + err
    assert "result: INCOMPATIBLE" in out and expected in out, out
    assert "result: compatible" not in out and "Traceback" not in out + err


def test_at_least_sixty_bad_inputs():
    assert len(CASES) >= 60 and len({c[0] for c in CASES}) == len(CASES)


def test_regress_warns_when_the_scenarios_differ(files, cli, tmp_path):
    other = _log(tmp_path / "o.parquet", {"time": np.arange(10.0), "x": np.arange(10.0) * 2},
                 {"scenario_sha256": "b" * 64, "scenario_path": "t.toml"})
    status, out, _ = cli(["regress", str(other), str(files["run"]), "--no-plots"])
    assert status == 0
    assert "warning: the run's scenario (sha256 bbbbbbbbbbbb, t.toml) differs" in out


def test_regress_never_passes_a_nan_tolerance_or_signal(files):
    from uwcosim.core.errors import RegressionInputError
    from uwcosim.regress.compare import compare_logs, compare_signal

    for kw in ({"rtol": float("nan")}, {"atol": float("nan")}, {"ttol": float("nan")}):
        with pytest.raises(RegressionInputError):
            compare_logs(files["run"], files["base"], **kw)
    t = np.arange(5.0)
    res, _ = compare_signal("x", t, t, t, t, float("nan"), 0.0, 0.0)  # direct API: NaN band
    assert not res.ok
    y = t.copy()
    y[2] = np.inf
    assert not compare_signal("x", t, t, t, y, 1e-6, 1e-9, 0.0)[0].ok


# -- --out of `run` ---------------------------------------------------------------------------
def test_run_refuses_a_non_empty_run_directory_and_force_replaces_it(cli, tmp_path,
                                                                     project_fmus):
    out = tmp_path / "r"
    out.mkdir()
    (out / "report.md").write_text("old report")
    (out / "trajectory.png").write_bytes(b"old")
    (out / "notes.txt").write_text("mine")
    status, _, err = cli(["run", str(SCEN), "--out", str(out), *FAST])
    assert status == 2 and "run directory is not empty" in err and "--force" in err
    assert (out / "report.md").read_text() == "old report"  # untouched
    status, _, err = cli(["run", str(SCEN), "--out", str(out), *FAST, "--force"])
    assert status == 0, err
    assert not (out / "report.md").exists() and not (out / "trajectory.png").exists()
    assert (out / "notes.txt").read_text() == "mine"  # not a run file: kept
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"


# -- campaigns ----------------------------------------------------------------------------------
def test_campaign_resume_refuses_a_changed_spec_and_reruns_truncated_records(files, cli,
                                                                             tmp_path):
    spec = tmp_path / "c.toml"
    spec.write_text(files["c_ok"].read_text().replace("runs = 1", "runs = 2"))
    out = tmp_path / "o"
    status, _, err = cli(["campaign", str(spec), "--out", str(out), "--workers", "1"])
    assert status == 0, err
    manifest = json.loads((out / "campaign.json").read_text())
    record = json.loads((out / "results" / "v__00001.json").read_text())
    assert record["scenario_sha256"] == manifest["fingerprint"]["variants"]["v"][
        "scenario_sha256"]
    # a truncated record (killed while writing) is not done: it runs again
    (out / "results" / "v__00001.json").write_text('{"variant": "v", "ru')
    status, _, err = cli(["campaign", str(spec), "--out", str(out), "--workers", "1",
                          "--resume"])
    assert status == 0 and "Traceback" not in err, err
    again = json.loads((out / "results" / "v__00001.json").read_text())
    assert again["seed"] == record["seed"] and again["status"] == "ok"
    assert again["estimators"]["ekf"]["rmse_position_m"] == \
        record["estimators"]["ekf"]["rmse_position_m"]
    # another seed, another duration: refused, nothing overwritten
    text = spec.read_text()
    for changed, what in ((text.replace("seed = 1", "seed = 2"), "seed 1 -> 2"),
                          (text.replace("run.duration=5", "run.duration=6"),
                           "variant 'v': overrides changed")):
        spec.write_text(changed)
        status, _, err = cli(["campaign", str(spec), "--out", str(out), "--resume"])
        assert status == 2 and what in err and len(err.strip().splitlines()) == 1, err
        assert json.loads((out / "campaign.json").read_text()) == manifest
        assert "seed = 1\n" in (out / "campaign.toml").read_text()


def test_a_failed_campaign_run_keeps_its_log_in_the_campaign_directory(tmp_path, cli,
                                                                       project_fmus):
    spec = tmp_path / "c.toml"
    chain = ('connections=[["vehicle.vx", "dvl.vx"], ["vehicle.vy", "dvl.vy"], '
             '["vehicle.x", "fault.u"], ["fault.y", "sounder.x"], ["vehicle.y", "sounder.y"]]')
    fault = 'fmus.fault={path="%s", parameters={fail_time=5.0}}' % (
        ROOT / "fmus" / "FaultInjector.fmu")
    spec.write_text(f'seed = 1\nruns = 1\n[[variants]]\nname = "v"\nscenario = "{SCEN}"\n'
                    f'set = {json.dumps([chain, fault, "run.duration=20"])}\n')
    out = tmp_path / "o"
    status, _, err = cli(["campaign", str(spec), "--out", str(out), "--workers", "1"])
    assert status == 1, err  # the FMU fails at t=5
    record = json.loads((out / "results" / "v__00000.json").read_text())
    kept = out / "failed" / "v" / "run_00000" / "log.parquet"
    assert f"kept in {kept}" in record["error"] and kept.is_file()
    assert "/tmp/uwcosim_run_" not in record["error"]


# -- long runs and divergence -----------------------------------------------------------------
def test_sources_do_not_depend_on_the_chunk_size(tan, tmp_path, monkeypatch):
    """Noise, losses and controls drawn in chunks: the same log for any chunk size."""
    from uwcosim.api import run_scenario
    from uwcosim.master import sources

    sets = ["run.duration=60", 'estimators={ekf={type="ekf"}}',
            'sensors.depth.loss={model="gilbert_elliott", p_good_to_bad=0.2, '
            'p_bad_to_good=0.3}']
    a = run_scenario(tan(sets), tmp_path / "a", figures=False).log_path
    monkeypatch.setattr(sources, "CHUNK_STEPS", 7)
    b = run_scenario(tan(sets), tmp_path / "b", figures=False).log_path
    assert a.read_bytes() == b.read_bytes()


def test_a_very_long_run_does_not_allocate_its_noise_up_front(tan):
    from uwcosim.master.master import Master
    from uwcosim.scenario import to_system

    m = Master(to_system(tan(["run.duration=1e8"])))
    try:
        assert m.n_steps == 100_000_000
        m.sources.row(0)
        assert m.sources.rows.nbytes < 50e6
        bank = m.sensors
        m.measurement()
        for table in (bank.masks, bank.additive, bank.inputs):
            assert table.rows.nbytes < 50e6
    finally:
        m.close()


def test_broken_covariances_are_flagged_as_divergence(tan, tmp_path):
    from uwcosim.api import run_scenario

    res = run_scenario(tan(["run.duration=30", "model.q_psd=[1e30,1e30,1e30,1e30]",
                            'estimators={ekf={type="ekf"}, pf={type="pf", n_particles=200},'
                            ' dr={type="dead_reckoning"}}']), tmp_path, figures=False)
    est = res.summary["estimators"]
    assert est["ekf"]["diverged"] and est["pf"]["diverged"]
    assert "outside the bound" in est["pf"]["error"]
    assert not est["dr"]["diverged"]  # the others go on


def test_divergence_checks():
    from uwcosim.run.divergence import DivergenceCheck, covariance_problem

    check = DivergenceCheck((0, 1), (0.0, 10.0, 0.0, 10.0))
    x, P = np.array([1.0, 2.0]), np.eye(2)
    assert check(x, P, 1.0, 1.0) == ""
    assert "NaN" in check(np.array([np.nan, 0.0]), P, 1.0, 1.0)
    assert "not symmetric" in covariance_problem(np.array([[1.0, 0.5], [0.0, 1.0]]))
    assert "not positive definite" in covariance_problem(np.diag([1.0, -1.0]))
    assert covariance_problem(np.diag([1.0, -1e-12])) == ""  # round-off tolerated
    assert "negative NIS" in check(x, P, -1.0, 1.0)
    assert "negative NEES" in check(x, P, 1.0, -1.0)
    assert "outside the bound" in check(np.array([11.0, 2.0]), P, 1.0, 1.0)


# -- property-based: the loader and --set never give a traceback ------------------------------
def _toml(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == np.inf else "-inf" if v == -np.inf
                                     else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {_toml(x)}" for k, x in v.items()) + "}"


VALUES = st.recursive(
    st.booleans() | st.integers(-2**63, 2**63 - 1) | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                max_size=3),
    max_leaves=8)
KEYS = ["run.duration", "run.step", "run.start_time", "run.seed", "run.fmu_timeout_s",
        "fmus.vehicle", "fmus.vehicle.path", "fmus.dvl.period", "fmus.sounder.parameters",
        "connections", "controls.psi", "noise.process.psd", "sensors.depth.loss",
        "sensors.dvl.sigma", "map", "map.extent", "map.resolution", "model.q_psd",
        "model.truth", "estimation.initial_std", "estimation.position_bound", "estimators",
        "estimators.ekf", "estimators.ekf.type", "log.signals", "log.chunk_steps",
        "output.density_snapshots", "name", "run"]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS) | st.text(max_size=12), value=VALUES)
def test_arbitrary_toml_values_never_give_a_traceback(key, value):
    try:
        load_scenario(SCEN, [f"{key}={_toml(value)}"])
    except ScenarioError:
        pass


@settings(max_examples=150, deadline=None)
@given(item=st.text(max_size=40))
def test_arbitrary_set_arguments_never_give_a_traceback(item):
    try:
        parse_overrides([item], "x")
        load_scenario(SCEN, [item])
    except ScenarioError:
        pass


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=st.dictionaries(st.sampled_from(["run", "fmus", "map", "model", "estimators", "log",
                                            "name", "connections"]), VALUES, max_size=4))
def test_arbitrary_scenario_files_never_give_a_traceback(tmp_path, doc):
    p = tmp_path / "s.toml"
    p.write_text("\n".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in doc.items()))
    try:
        load_scenario(p)
    except ScenarioError:
        pass


@pytest.mark.parametrize(("item", "key", "value"), [
    ('map={kind="file", file="maps/good.nc"}', ("map", "file"), "maps/good.nc"),
    ('fmus.dvl={path="fmus/DVL.fmu"}', ("fmus", "dvl", "path"), "fmus/DVL.fmu"),
    ('fmus={vehicle={path="v.fmu", map="m.npz"}}', ("fmus", "vehicle", "map"), "m.npz"),
    ("system.ssp=sys/a.ssp", ("system", "ssp"), "sys/a.ssp"),
    ('system={ssp="sys/a.ssp"}', ("system", "ssp"), "sys/a.ssp"),
])
def test_set_paths_inside_inline_tables_are_relative_to_the_current_folder(tmp_path, item, key,
                                                                           value):
    """Issue 24, item 17: a path in an inline table of ``--set`` was resolved against the
    scenario's folder (the dotted forms used the current folder, as the README says)."""
    from uwcosim.scenario.overrides import absolute_path_overrides, apply_override

    (out,) = absolute_path_overrides([item], tmp_path, "s.toml")
    data: dict = {}
    for keys, v in parse_overrides([out], "s.toml"):
        apply_override(data, keys, v, "s.toml")
    node = data
    for k in key:
        node = node[k]
    assert node == str((tmp_path / value).resolve()), out


def test_a_utf8_bom_and_a_whole_value_with_newlines_are_read(tmp_path):
    """Issue 24, items 19 and 20: a byte-order mark gave "Invalid statement (line 1, col 1)";
    an array over several lines is one TOML value and is read whole."""
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + SCEN.read_bytes().replace(
        b'path = "../fmus/', b'path = "' + str(ROOT / "fmus").encode() + b"/"))
    loaded = load_scenario(bom, ["estimation.initial_std=[\n50.0,\n50.0, 1.0, 1.0]"])
    assert loaded.spec.estimation.initial_std == [50.0, 50.0, 1.0, 1.0]


def test_report_of_a_log_with_no_rows(tmp_path, cli):
    """Issue 24, item 13: ``report`` of a run whose log has no rows gave an IndexError
    traceback; it writes a report without figures."""
    from uwcosim.runlog import RunLogger

    run = tmp_path / "run"
    run.mkdir()
    meta = {"seed": 1, "states": ["px", "py", "vx", "vy"], "truth": ["vehicle.x", "vehicle.y",
                                                                    "vehicle.vx", "vehicle.vy"],
            "estimators": ["ekf"]}
    names = ["vehicle.x", "vehicle.y", "vehicle.vx", "vehicle.vy",
             *(f"est.ekf.{s}" for s in ("px", "py", "vx", "vy"))]
    RunLogger(run / "log.parquet", names, [], meta, chunk=4).close()
    status, out, err = cli(["report", str(run)])
    assert status == 0 and "Traceback" not in err, err
    assert (run / "report.md").is_file() and not list(run.glob("*.png"))


def test_campaign_workers_are_capped_at_the_cores(monkeypatch, caplog):
    """Issue 24, item 8: ``--workers 1000`` started about 40 processes and over 5 GB without
    finishing a run. More than the cores are capped (a warning says so) unless
    ``--oversubscribe``; never more than the runs."""
    from uwcosim.campaign.driver import worker_count

    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    assert worker_count(1000, 50) == 2 and "capped at the 2 cores" in caplog.text
    assert worker_count(None, 50) == 2 and worker_count(1, 50) == 1
    assert worker_count(None, 1) == 1
    assert worker_count(8, 50, oversubscribe=True) == 8
    with pytest.raises(ScenarioError, match="--workers 1000 --oversubscribe"):
        worker_count(1000, 5000, oversubscribe=True)


def test_the_numpy_kernels_are_recorded_and_reproduced(tmp_path):
    """Issue 24, item 20: ``UWCOSIM_NUMBA=0`` changes the log by about 1e-11 with the same
    metadata, so the report's reproduce command did not reproduce it. The metadata says
    ``kernels = "numpy"`` and the reproduce line starts with ``UWCOSIM_NUMBA=0``; a default run
    has no such key (its log is unchanged)."""
    import subprocess
    import sys

    from uwcosim.runlog import read_log

    env = {**os.environ, "UWCOSIM_NUMBA": "0"}
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out", str(out),
                        "--set", "run.duration=3", "--set", 'estimators={ekf={type="ekf"}}'],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert read_log(out / "log.parquet")[1]["kernels"] == "numpy"
    assert "UWCOSIM_NUMBA=0 uwcosim run " in (out / "report.md").read_text()
    from uwcosim.reports.reproduce import reproduce_command

    assert not reproduce_command({}, {"scenario_path": "s.toml"}).startswith("UWCOSIM")


def test_numpy_warnings_are_one_line_each_and_recorded(tmp_path):
    """Item 19: a zero measurement noise makes numpy warn in the particle filter (weights of
    a zero variance); the run prints no raw ``RuntimeWarning`` (and no source line under it),
    one line naming where, and ``summary.json`` counts it under ``warnings``."""
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out", str(out), "--no-figures",
         "--set", "run.duration=10", "--set", "sensors.depth.sigma=[0.0]", "--set",
         'estimators={pf={type="pf", n_particles=200}}'], cwd=ROOT, capture_output=True,
        text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "RuntimeWarning" not in proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if "numerical warning" in ln]
    assert len(lines) == 1 and "numerical warning at uwcosim/filters/particle.py:" in lines[0] \
        and "divide by zero encountered in divide" in lines[0], proc.stderr
    warned = json.loads((out / "summary.json").read_text())["warnings"]
    assert [w["message"] for w in warned] == ["divide by zero encountered in divide"]
    assert warned[0]["where"].startswith("uwcosim/filters/particle.py:")
    assert warned[0]["count"] >= 1
