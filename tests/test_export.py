"""``uwcosim export RUN --csv|--mat``: every column and value of the log, readable back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.csv as pcsv
import pytest
from scipy.io import loadmat

from uwcosim.api import run_scenario
from uwcosim.cli import main
from uwcosim.export import matlab_names
from uwcosim.runlog import read_log, read_units
from uwcosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run(tmp_path_factory, project_fmus) -> Path:
    out = tmp_path_factory.mktemp("run")
    run_scenario(load_scenario(ROOT / "scenarios" / "lost_measurements.toml",
                               ["run.duration=30"]), out, figures=False)
    return out


def test_csv_has_every_column_and_value(run, capsys):
    assert main(["export", str(run), "--csv"]) == 0
    path = Path(capsys.readouterr().out.strip())
    assert path == run / "log.csv"
    cols, _ = read_log(run / "log.parquet")
    units = read_units(run / "log.parquet")
    table = pcsv.read_csv(path)
    assert table.column_names == [f"{c} [{units[c]}]" if c in units else c for c in cols]
    assert table.column_names[0] == "time [s]"
    assert all(c in units for c in cols if c.startswith("est.") and cols[c].dtype != bool)
    for name, header in zip(cols, table.column_names):
        values = cols[name]
        got = table.column(header).to_numpy(zero_copy_only=False)
        if values.dtype == bool:
            assert (got == values).all(), name
        else:
            np.testing.assert_array_equal(got, values, err_msg=name)  # NaN == NaN here


def test_csv_without_units_has_the_bare_names(run, tmp_path):
    assert main(["export", str(run), "--csv", "--no-units", "--out", str(tmp_path / "x.csv")]
                ) == 0
    cols, _ = read_log(run / "log.parquet")
    assert pcsv.read_csv(tmp_path / "x.csv").column_names == list(cols)


def test_mat_has_data_columns_struct_and_metadata(run, tmp_path, capsys):
    out = tmp_path / "x.mat"
    assert main(["export", str(run / "log.parquet"), "--mat", "--out", str(out)]) == 0
    cols, meta = read_log(run / "log.parquet")
    m = loadmat(out, simplify_cells=True)
    assert list(m["columns"]) == list(cols)
    data = m["data"]
    assert data.shape == (cols["time"].size, len(cols))
    for j, (name, values) in enumerate(cols.items()):
        np.testing.assert_array_equal(data[:, j], values.astype(float), err_msg=name)
        field = matlab_names(list(cols))[j]
        np.testing.assert_array_equal(np.ravel(m["log"][field]), values.astype(float))
    assert json.loads(m["metadata"])["seed"] == meta["seed"]


def test_matlab_names_are_valid_and_unique():
    names = matlab_names(["time", "est.kf.var.px", "est_kf_var_px", "1x", "a" * 80, "a" * 81])
    assert names[:4] == ["time", "est_kf_var_px", "est_kf_var_px_1", "v_1x"]
    assert len(set(names)) == len(names) and all(len(n) <= 63 for n in names)
    assert all(n[0].isalpha() and n.replace("_", "").isalnum() for n in names)


def test_export_needs_a_format_and_a_log(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["export", str(tmp_path)])
    assert exc.value.code == 2
    assert main(["export", str(tmp_path), "--csv"]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err == f"uwcosim: error: {tmp_path / 'log.parquet'}: run log not found"
