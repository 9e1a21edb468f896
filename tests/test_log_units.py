"""The log's units: Parquet field metadata from the FMUs' model descriptions and the filters'
state units, ``read_units``, and ``read_log(..., as_dataframe=True)`` with them in ``attrs``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from fmpy import read_model_description

from uwcosim.fmi.varmap import fmu_unit
from uwcosim.run.simulate import run_scenario
from uwcosim.runlog import read_log, read_units
from uwcosim.runlog.units import squared
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tan_run(tmp_path_factory, project_fmus):
    out = tmp_path_factory.mktemp("units") / "run"
    loaded = load_scenario(ROOT / "scenarios" / "tan_terrain.toml", ["run.duration=5"])
    run_scenario(loaded, out, figures=False)
    return out / "log.parquet", project_fmus


def test_every_float_column_has_the_unit_its_fmu_declares(tan_run):
    log, fmus = tan_run
    units = read_units(log)
    md = {v.name: v for v in read_model_description(str(fmus / "DVL.fmu")).modelVariables}
    assert units["z.dvl.vx_m"] == fmu_unit(md["vx_m"]) == "m/s"
    vehicle = {v.name: v for v in
               read_model_description(str(fmus / "AUVKinematics.fmu")).modelVariables}
    for name in ("x", "y", "vx", "vy", "psi_out"):
        assert units[f"vehicle.{name}"] == fmu_unit(vehicle[name]), name
    assert units["controls.psi"] == "rad"  # a source: the unit of the FMU input it drives
    assert units["time"] == "s"
    assert units["est.ekf.x"] == "m" and units["est.ekf.var.x"] == "m2"
    assert units["est.ukf.vy"] == "m/s" and units["est.ukf.var.vy"] == "m2/s2"
    assert units["est.pf.nees"] == units["est.pf.nis"] == "1"
    schema = pq.read_schema(log)
    floats = [f.name for f in schema if not str(f.type) == "bool"]
    assert set(floats) == set(units), set(floats) ^ set(units)
    assert not any(f.metadata for f in schema if str(f.type) == "bool")


def test_read_log_as_a_dataframe(tan_run):
    pytest.importorskip("pandas")
    log, _ = tan_run
    cols, meta = read_log(log)
    df = read_log(log, as_dataframe=True)
    assert list(df.columns) == list(cols)
    for name, values in cols.items():
        np.testing.assert_array_equal(df[name].to_numpy(), values, err_msg=name)
    assert df.attrs["units"] == read_units(log) and df.attrs["units"]["vehicle.x"] == "m"
    assert df.attrs["uwcosim"] == meta


@pytest.mark.parametrize("unit, sq", [("m", "m2"), ("m/s", "m2/s2"), ("rad", "rad2"),
                                      ("1", "1"), ("m/s2", "(m/s2)2")])
def test_squared_units(unit, sq):
    assert squared(unit) == sq
