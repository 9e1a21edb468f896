"""No inverse crime (issue 25, section 2): ``[map.truth]`` gives the truth's sounder its own
seafloor (finer, with unresolved relief, a correlated survey error and an offset over time),
the filters keep ``[map]``; without it both read the same map; ``model.map_error_std_m``."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.core.rng import stream
from uwcosim.models.terrain import read_coefficients, synthetic_bathymetry
from uwcosim.models.truth_map import correlated_field, truth_bathymetry
from uwcosim.run.factory import build_model, scenario_map
from uwcosim.run.truth_map import scenario_truth_map
from uwcosim.scenario.system import to_system

TRUTH = ["map.truth.resolution=25.0", "map.truth.fine_relief_m=2.0",
         "map.truth.fine_scale_m=50.0", "map.truth.survey_error.std_m=1.0",
         "map.truth.survey_error.correlation_m=500.0"]


def test_correlated_field_std_and_correlation():
    f = correlated_field(np.random.default_rng(1), (400, 400), 25.0, 2.0, 500.0)
    assert f.std() == pytest.approx(2.0) and abs(f.mean()) < 1e-12
    lag = 20  # 500 m: rho = exp(-1/2) = 0.61 for a Gaussian correlation of length 500 m
    rho = np.mean(f[:, :-lag] * f[:, lag:]) / f.var()
    assert 0.45 < rho < 0.75
    rho_far = np.mean(f[:, :-80] * f[:, 80:]) / f.var()  # 2000 m: exp(-8) ~ 0
    assert abs(rho_far) < 0.15


def test_truth_without_errors_is_the_survey_resampled():
    base = synthetic_bathymetry(7, (0.0, 5000.0, 0.0, 5000.0), 50.0)
    t = truth_bathymetry(base, base.extent, 25.0)
    assert t.shape == (201, 201)
    np.testing.assert_allclose(t.depth_grid[::2, ::2], base.depth_grid, atol=1e-9)
    xs = np.random.default_rng(2).uniform(0, 5000, (2, 200))
    assert np.max(np.abs(t.depth(*xs) - base.depth(*xs))) < 0.5  # re-interpolation only


def test_survey_error_and_fine_relief_are_seeded_streams():
    base = synthetic_bathymetry(7, (0.0, 5000.0, 0.0, 5000.0), 50.0)

    def truth(seed):
        return truth_bathymetry(base, base.extent, 50.0, survey_std_m=1.0,
                                survey_correlation_m=500.0,
                                survey_rng=stream(seed, "map-truth:survey-error"))
    a, b, c = truth(1), truth(1), truth(2)
    np.testing.assert_array_equal(a.depth_grid, b.depth_grid)
    err = a.depth_grid - base.depth_grid
    assert err.std() == pytest.approx(1.0, rel=1e-9)
    assert not np.allclose(a.depth_grid, c.depth_grid)


def test_scenario_without_map_truth_has_one_map(tan):
    loaded = tan()
    assert scenario_truth_map(loaded, scenario_map(loaded), 1) is None


def test_scenario_truth_map_and_filters_map(tan):
    loaded = tan(TRUTH)
    survey = scenario_map(loaded)
    t = scenario_truth_map(loaded, survey, 1)
    assert (t.dx, t.shape) == (25.0, (1001, 1001))
    d = t.depth_grid[::2, ::2] - survey.depth_grid
    assert 1.8 < d.std() < 2.6  # sqrt(2^2 + 1^2) = 2.24, at the survey's nodes
    # another seed, another survey error; the filters' map does not change
    t2 = scenario_truth_map(loaded, survey, 2)
    assert not np.allclose(t.depth_grid, t2.depth_grid)
    np.testing.assert_array_equal(scenario_map(loaded).depth_grid, survey.depth_grid)


def test_run_writes_the_truth_map_for_the_sounder(tan, tmp_path):
    from uwcosim.run.simulate import simulate

    loaded = tan(TRUTH + ["run.duration=20", "map.truth.offset=[[0, 0.0], [20, 2.0]]",
                          "log.signals=['vehicle.*', 'controls.*', 'sounder.*']"])
    out = simulate(loaded, tmp_path / "run", evaluate=False)
    import pyarrow.parquet as pq

    table = pq.read_table(out / "log.parquet")
    log = {n: table.column(n).to_numpy() for n in table.column_names}
    survey = read_coefficients(out / "map.bin")
    truth = read_coefficients(out / "map_truth.bin")
    x, y = log["vehicle.x"], log["vehicle.y"]
    offset = log["controls.map_truth_offset"]
    t = log["time"] if "time" in log else np.arange(21.0)
    # row k logs the control held over the step into it (its value at t_k - h)
    np.testing.assert_allclose(offset, np.interp(np.maximum(t - 1.0, 0.0), [0, 20], [0, 2]))
    # the sounder's noise-free altitude is the truth's seafloor, not the filters' map
    np.testing.assert_allclose(log["sounder.altitude"], truth.depth(x, y), atol=1e-6)
    assert np.max(np.abs(log["sounder.altitude"] - survey.depth(x, y))) > 0.1


def test_offset_needs_a_valid_table(tan):
    with pytest.raises(ScenarioError, match="offset"):
        tan(["map.truth.offset=[[10, 0.0], [5, 1.0]]"])


def test_offset_becomes_a_control_of_the_sounder(tan):
    system = to_system(tan(["map.truth.offset=[[0, 0.0], [100, 1.5]]"]))
    c = system.controls["map_truth_offset"]
    assert c.target == "sounder.offset_h" and c.table == [(0.0, 0.0), (100.0, 1.5)]


def test_map_error_std_is_added_to_the_depth_r(tan):
    loaded = tan()
    bathy = scenario_map(loaded)
    r0 = build_model(loaded, bathy).R
    aware = tan(["model.map_error_std_m=2.0"])
    r1 = build_model(aware, bathy).R
    assert r1[2, 2] == pytest.approx(r0[2, 2] + 4.0)
    np.testing.assert_array_equal(r1[:2, :2], r0[:2, :2])
