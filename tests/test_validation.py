"""One validation pass (issue 11, item 5): every problem at once, the filters' settings models,
``uwcosim check`` and its exit statuses, ``uwcosim schema`` (JSON Schema of the format)."""

from __future__ import annotations

import inspect
import json
import tomllib
from pathlib import Path
from typing import get_args

import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.filters import ESTIMATORS
from uwcosim.filters.base import settings_model
from uwcosim.run.preflight import check_scenario
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"


def _sets(*items: str) -> list[str]:
    return [a for i in items for a in ("--set", i)]


# -- every problem at once ---------------------------------------------------------------------
def test_three_independent_mistakes_give_three_lines(cli, project_fmus):
    code, out, err = cli("check", str(SCEN), *_sets(
        "run.stp=1", "sensors.depth.period=0", "estimators.pf.n_partcles=3"))
    assert code == 2, err
    assert len(err) == 3, err
    keys = ["key 'run.stp': unknown key", "key 'sensors.depth.period'",
            "key 'estimators.pf.n_partcles': unknown setting for estimator 'pf'"]
    for key in keys:
        assert sum(key in line for line in err) == 1, (key, err)
    assert all(line.startswith(str(SCEN)) for line in err)
    assert "3 problems" in out


def test_problems_against_the_fmus_are_all_reported(cli, project_fmus):
    code, _, err = cli("check", str(SCEN), *_sets(
        'connections=[["vehicle.xx", "dvl.vx"], ["vehicle.vy", "dvl.vyy"], '
        '["vehicle.x", "sounder.x"], ["vehicle.y", "sounder.y"]]',
        'controls.psi.target="vehicle.x"'))
    assert code == 2
    assert len(err) == 3, err
    assert any("FMU 'vehicle' has no variable 'xx'" in e for e in err)
    assert any("FMU 'dvl' has no variable 'vyy'" in e for e in err)
    assert any("key 'controls.psi.target'" in e and "causality 'output'" in e for e in err)


def test_filter_problems_found_by_building_the_filters(cli, project_fmus):
    code, out, err = cli("check", str(SCEN), *_sets(
        'estimators.pm={type="point_mass", n_points=100000}',
        'estimators.pf.measurements=["foo"]'))
    assert code == 2 and len(err) == 2, err
    assert any("key 'estimators.pm'" in e and "GiB" in e for e in err)
    assert any("key 'estimators.pf'" in e and "unknown measurements ['foo']" in e for e in err)
    assert "map and filters" in out


def test_run_says_how_many_more_problems_there_are(cli, tmp_path, project_fmus):
    code, _, err = cli("run", str(SCEN), "--out", str(tmp_path / "o"), *_sets(
        "run.stp=1", "sensors.depth.period=0", "estimators.pf.n_partcles=3"))
    assert code == 2 and len(err) == 1
    assert "key 'run.stp': unknown key" in err[0]
    assert err[0].endswith("(and 2 more; see uwcosim check)")
    assert not (tmp_path / "o").exists()  # refused at load, before anything is written


def test_load_reports_cross_references_without_fmus():
    """What used to be found by the estimator bank or the model factory (after the FMUs were
    opened) is found when the scenario is loaded, with the key named."""
    cases = [('model.controls=["psi", "rudder"]', "key 'model.controls': unknown control "
              "'rudder' (controls: psi, a)"),
             ('estimators.ekf.sensors=["gps"]', "key 'estimators.ekf.sensors': 'gps' is not "
              "among model.sensors (dvl, depth)"),
             ("model.q_psd=[1.0, 1.0]", "key 'model.q_psd': the TAN model needs 4"),
             ("sensors.depth.sigma=[]|sensors.depth.noise_inputs=[]",
              "key 'sensors.depth.sigma': the filter model needs one sigma per output (1)"),
             ('estimators.ekf.policy="guess"', "unknown lost-measurement policy 'guess'"),
             # these gave a traceback (numpy broadcasting) or named no key before
             ("estimation.initial_std=[1.0, 1.0]", "key 'estimation.initial_std': 2 values; "
              "expected one per state of the tan model (x, y, vx, vy)"),
             ("estimators.ekf.initial_std=[1.0]", "key 'estimators.ekf.initial_std': 1 values"),
             ('model.truth=["vehicle.x", "vehicle.y", "vehicle.vx"]', "key 'model.truth': 3 "
              "signals; expected one per state")]
    for override, expected in cases:
        with pytest.raises(ScenarioError) as info:
            load_scenario(SCEN, override.split("|"))
        assert expected in str(info.value), (override, str(info.value))


# -- the filters' settings models --------------------------------------------------------------
def test_unknown_setting_lists_the_valid_ones_and_rng_seed_are_not_settings():
    for key in ("n_partcles", "rng", "seed"):
        with pytest.raises(ScenarioError) as info:
            load_scenario(SCEN, [f"estimators.pf.{key}=3"])
        msg = str(info.value)
        assert f"key 'estimators.pf.{key}': unknown setting for estimator 'pf' (valid: " \
               "n_particles, resampling, ess_threshold, roughening, measurements, " \
               "student_t_nu)" in msg
    assert "rng" not in settings_model("pf").model_fields
    assert "seed" not in settings_model("pf").model_fields


@pytest.mark.parametrize(("override", "expected"), [
    ("estimators.pf.n_particles=1.5", "key 'estimators.pf.n_particles': Input should be a "
                                      "valid integer"),
    ('estimators.pf.n_particles="100"', "key 'estimators.pf.n_particles'"),
    ("estimators.pf.n_particles=1", "key 'estimators.pf.n_particles': Input should be greater "
                                    "than or equal to 2"),
    ('estimators.ukf.alpha="x"', "key 'estimators.ukf.alpha': Input should be a valid number"),
    ("estimators.ukf.alpha=nan", "key 'estimators.ukf.alpha'"),
    ('estimators.pf.resampling="sytematic"', "key 'estimators.pf.resampling': Input should be "
                                             "'systematic'"),
    ('estimators.pfm_psi.positivity="x"', "key 'estimators.pfm_psi.positivity'"),
    ("estimators.point_mass.n_points=[51, 5.5]", "key 'estimators.point_mass.n_points'"),
    ('estimators.ekf.measurements="dvl.vx_m"', "key 'estimators.ekf.measurements'"),
])
def test_wrong_setting_types_name_the_key(override, expected):
    with pytest.raises(ScenarioError) as info:
        load_scenario(SCEN, [override])
    assert expected in str(info.value)
    assert len(str(info.value).splitlines()) == 1


def test_every_project_filter_declares_its_settings_once_on_its_class():
    """The constructor takes exactly the declared settings (but ``rng``/``seed``, the
    master's) with the declared defaults: built with none, a filter holds
    ``Settings()``; an unknown keyword is refused naming the valid ones; only the filters that
    draw take the random stream."""
    from uwcosim.filters import Estimator
    from uwcosim.filters.settings import FilterSettings
    from uwcosim.models.linear import constant_velocity_model
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry

    tan = tan_model([0.01] * 4, [0.05, 0.05], 1.0,
                    synthetic_bathymetry(1, (0.0, 5000.0, 0.0, 5000.0), 50.0),
                    ("dvl.vx_m", "dvl.vy_m", "sounder.depth_m"))
    cv = constant_velocity_model(q_psd=[0.01], R=np.eye(2), measurement_names=("px", "py"))
    drawing = {"pf", "rbpf", "rpf"}
    for kind in ESTIMATORS.names():
        cls = ESTIMATORS.get(kind)
        if not cls.__module__.startswith("uwcosim.filters"):
            continue  # a filter registered by a test or a user
        assert issubclass(cls.Settings, FilterSettings), kind
        assert "Settings" in vars(cls) or any("Settings" in vars(b) for b in cls.__mro__[1:-1]
                                              if b is not Estimator), kind
        params = {n for n in inspect.signature(cls.__init__).parameters
                  if n not in ("self", "model", "x0", "P0")}
        assert params <= {"settings", "kw", "rng", "seed"}, (kind, params)  # no second list
        model = cv if kind == "kf" else tan
        x0 = np.array([1000.0, 0.0, 1000.0, 0.0]) if kind == "kf" else \
            np.array([2500.0, 2500.0, 1.0, 0.0])
        est = cls(model, x0, np.eye(4) * 25.0)
        assert est.settings == cls.Settings(), kind
        with pytest.raises(TypeError, match=f"unknown setting 'nope' for estimator '{kind}' "
                                            r"\(valid: "):
            cls(model, x0, np.eye(4) * 25.0, nope=1)
        assert cls.needs_rng == (kind in drawing), kind


def test_choices_match_the_registries():
    from uwcosim.filters.particle import RESAMPLERS
    from uwcosim.filters.projection.bayes import POSITIVITY

    pf = settings_model("pf").model_fields["resampling"].annotation
    assert sorted(get_args(pf)) == RESAMPLERS.names()
    psi = settings_model("pfm_psi").model_fields["positivity"].annotation
    assert get_args(psi) == POSITIVITY


def test_list_estimators_shows_declared_settings(cli):
    code, out, _ = cli("list", "estimators")
    assert code == 0
    assert "    n_particles=1000 (int): number of particles" in out
    assert "    resampling='systematic' ('systematic' | 'stratified'" in out
    assert "rng=" not in out and "seed=" not in out


# -- uwcosim check: exit statuses -------------------------------------------------------------
def test_check_exit_statuses(cli, project_fmus, tmp_path):
    code, out, err = cli("check", str(SCEN))
    assert (code, err) == (0, []) and "ok" in out
    code, _, err = cli("check", str(SCEN), "--set", "fmus.vehicle.path=nope.fmu")
    assert code == 3 and len(err) == 1 and "FMU not found" in err[0]
    code, _, err = cli("check", str(SCEN), *_sets("fmus.vehicle.path=nope.fmu", "run.seed=1.5"))
    assert code == 2 and len(err) == 1  # the schema first: the FMUs are not opened
    code, _, err = cli("check", str(SCEN), *_sets("fmus.vehicle.path=nope.fmu",
                                                  'model.controls=["nope"]'))
    assert code == 2 and len(err) == 2  # a scenario problem and an FMU problem: 2
    code, _, err = cli("check", str(tmp_path / "missing.toml"))
    assert code == 2 and "not found" in err[0]


def test_check_of_every_shipped_scenario_is_ok(project_fmus):
    for path in sorted((ROOT / "scenarios").glob("*.toml")):
        report = check_scenario(path)
        assert report.problems == [] and report.exit_code == 0, path


# -- uwcosim schema ----------------------------------------------------------------------------
def test_schema_validates_the_shipped_scenarios_and_refuses_mistakes(cli, tmp_path):
    jsonschema = pytest.importorskip("jsonschema")
    out = tmp_path / "scenario.schema.json"
    code, printed, _ = cli("schema", "--out", str(out))
    assert code == 0 and str(out) in printed
    schema = json.loads(out.read_text())
    code, printed, _ = cli("schema")
    assert json.loads(printed) == schema
    validator = jsonschema.Draft202012Validator(schema)
    jsonschema.Draft202012Validator.check_schema(schema)
    scenarios = sorted((ROOT / "scenarios").glob("*.toml"))
    assert scenarios
    for path in scenarios:
        data = tomllib.loads(path.read_text())
        assert list(validator.iter_errors(data)) == [], path
    data = tomllib.loads(SCEN.read_text())
    for mistake in ({"run": {**data["run"], "stp": 1}},
                    {"estimators": {"pf": {"type": "pf", "n_partcles": 3}}},
                    {"estimators": {"pf": {"type": "pf", "rng": 3}}},
                    {"estimators": {"pf": {"type": "pff"}}},
                    {"estimators": {"pf": {"type": "pf", "n_particles": "100"}}},
                    {"sensors": {"depth": {"outputs": ["sounder.depth"], "period": 0}}}):
        assert list(validator.iter_errors({**data, **mistake})), mistake


def test_schema_covers_every_key_and_every_filter():
    from uwcosim.scenario.json_schema import scenario_json_schema
    from uwcosim.scenario.schema import Scenario

    schema = scenario_json_schema()
    assert set(schema["properties"]) == set(Scenario.model_fields)
    for kind in ESTIMATORS.names():
        props = schema["$defs"][f"Estimator_{kind}"]["properties"]
        assert set(props) >= set(settings_model(kind).model_fields) | {"type", "policy"}


def test_check_of_an_ssp_alone(project_fmus, tmp_path, cli, monkeypatch):
    from tests.test_ssp import nested_ssp

    path = nested_ssp(tmp_path / "n.ssp", project_fmus)
    monkeypatch.chdir(tmp_path)
    code, out, err = cli("check", str(path), "--set", "run.step=0.5")
    assert code == 0 and err == [] and "ok (checked: schema, FMUs" in out
    code, _, err = cli("check", str(path))
    assert code == 2 and len(err) == 1 and "key 'run.step'" in err[0]


def test_arbitrary_filter_settings_never_give_a_traceback():
    """Any key of any filter's settings with any TOML value: a ScenarioError naming the key,
    or a valid scenario."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from tests.test_bad_inputs import VALUES, _toml

    kinds = [k for k in ESTIMATORS.names() if ESTIMATORS.get(k).__module__.startswith("uwcosim")]
    keys = sorted({k for kind in kinds for k in settings_model(kind).model_fields} | {"rng"})

    @settings(max_examples=120, deadline=None)
    @given(kind=st.sampled_from(kinds), key=st.sampled_from(keys), value=VALUES)
    def check(kind, key, value):
        override = f'estimators.e={{type="{kind}", {key} = {_toml(value)}}}'
        try:
            load_scenario(SCEN, [override])
        except ScenarioError as exc:
            assert len(str(exc).splitlines()) == 1
            assert "key 'estimators.e" in str(exc), str(exc)

    check()
