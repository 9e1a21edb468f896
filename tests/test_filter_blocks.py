"""The estimator bank filters blocks of steps, one estimator after the other
(``[run] filter_block``): the log, the summary and the density snapshots do not depend on the
block size, also when estimators diverge or lose measurements inside a block."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

ESTIMATORS = ['estimators={ekf={type="ekf"}, ukf={type="ukf"}, pf={type="pf", n_particles=200},'
              ' pfm={type="pfm_psi", K=8}, pm={type="point_mass", n_points=41},'
              ' qivbf={type="qivbf", policy="extrapolate"}}',
              'sensors.depth.loss={model="bernoulli", p=0.3}']


def _run(tan, tmp_path, block, extra=()):
    from uwcosim.api import run_scenario

    out = tmp_path / f"block{block}"
    res = run_scenario(tan(["run.duration=150", f"run.filter_block={block}",
                            "output.density_snapshots=[10.0, 75.5]", *extra]), out,
                       figures=False)
    return out, res.summary


def _same_runs(a, b):
    (out_a, sum_a), (out_b, sum_b) = a, b
    ta, tb = pq.read_table(out_a / "log.parquet"), pq.read_table(out_b / "log.parquet")
    assert ta.column_names == tb.column_names
    assert ta.num_rows == tb.num_rows
    for name in ta.column_names:  # NaN == NaN: the same bits
        x, y = ta.column(name).to_numpy(), tb.column(name).to_numpy()
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name
    for name, m in sum_a["estimators"].items():
        other = sum_b["estimators"][name]
        for key in ("rmse_position", "anees", "diverged", "diverged_at", "error"):
            if key in m:
                va, vb = m[key], other[key]
                assert va == vb or (va != va and vb != vb), (name, key, va, vb)
    assert (out_a / "densities.npz").exists() == (out_b / "densities.npz").exists()
    if not (out_a / "densities.npz").exists():
        return
    da, db = np.load(out_a / "densities.npz"), np.load(out_b / "densities.npz")
    assert sorted(da.files) == sorted(db.files)
    for k in da.files:
        assert np.array_equal(da[k], db[k]), k


@pytest.mark.parametrize("block", [7, 64], ids=lambda b: f"block{b}")
def test_results_do_not_depend_on_the_block_size(tan, tmp_path, block):
    _same_runs(_run(tan, tmp_path, 1, ESTIMATORS), _run(tan, tmp_path, block, ESTIMATORS))


def test_divergence_inside_a_block_is_flagged_at_the_same_step(tan, tmp_path):
    broken = ["model.q_psd=[1e30,1e30,1e30,1e30]",
              'estimators={ekf={type="ekf"}, pf={type="pf", n_particles=200},'
              ' dr={type="dead_reckoning"}}']
    one, many = _run(tan, tmp_path, 1, broken), _run(tan, tmp_path, 16, broken)
    _same_runs(one, many)
    est = many[1]["estimators"]
    assert est["ekf"]["diverged"] and est["pf"]["diverged"] and not est["dr"]["diverged"]
    log = pq.read_table(many[0] / "log.parquet")
    for name in ("ekf", "pf"):
        flagged = log.column(f"est.{name}.diverged").to_numpy(zero_copy_only=False)
        x = log.column(f"est.{name}.x").to_numpy()
        k = int(np.argmax(flagged))
        assert k > 0 and flagged[k:].all() and not flagged[:k].any()
        assert np.isnan(x[k:]).all() and np.isfinite(x[:k]).all()


def test_row_groups_are_written_as_their_last_step_is_co_simulated(tan, tmp_path, monkeypatch):
    """Blocks end with the log's row groups: a row group is written (and kept after a kill)
    as soon as its last step is co-simulated, with its estimates, not a block later."""
    from uwcosim.api import run_scenario
    from uwcosim.master.master import Master
    from uwcosim.runlog.parquet import RunLogger

    now = [float("nan")]
    step = Master.step

    def stepped(self):
        step(self)
        now[0] = self.t

    groups = []
    flush = RunLogger._flush

    def spy(self):
        cols = [i for i, c in enumerate(self.columns)  # the estimates (NIS, NEES: not at t0)
                if c.startswith("est.") and not c.endswith((".nis", ".nees"))]
        if self._n:
            groups.append((self._f[self._n - 1, 0], now[0], self._f[:self._n][:, cols].copy()))
        flush(self)

    monkeypatch.setattr(Master, "step", stepped)
    monkeypatch.setattr(RunLogger, "_flush", spy)
    run_scenario(tan(["run.duration=35", "run.filter_block=64", "log.chunk_steps=10",
                      'estimators={ekf={type="ekf"}, pf={type="pf", n_particles=100}}']),
                 tmp_path, figures=False)
    assert [len(g) for _, _, g in groups] == [10, 10, 10, 6]
    # written by the hooks of the step that ends the row group (the master's time of the step
    # before it until the step returns); the last one when the log is closed
    assert [(last, at) for last, at, _ in groups] == [(9.0, 8.0), (19.0, 18.0), (29.0, 28.0),
                                                      (35.0, 35.0)]
    assert all(np.isfinite(g).all() for _, _, g in groups)
