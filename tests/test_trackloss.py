"""The lost-track criterion (issue 25, section 4) and its place in summary.json."""

from __future__ import annotations

import numpy as np

from uwcosim.evaluation.trackloss import track_loss

T = np.arange(0.0, 300.0)


def errors(bad_from: float, bad_to: float, size: float = 80.0) -> np.ndarray:
    e = np.full((T.size, 2), 1.0)
    e[(T >= bad_from) & (T <= bad_to), 0] = size
    return e


def test_confident_and_wrong_for_60_s_is_lost():
    var = np.full((T.size, 2), 10.0**2)  # 3 sigma radius 42 m
    out = track_loss(T, errors(100, 160), var)
    assert out == {"track_lost": True, "track_lost_at_s": 100.0}


def test_shorter_than_60_s_is_not_lost():
    var = np.full((T.size, 2), 10.0**2)
    assert track_loss(T, errors(100, 159), var) == {"track_lost": False}
    # two 40 s spells with a good sample between them are two spells, not one of 81 s
    e = errors(100, 180)
    e[140] = 1.0
    assert track_loss(T, e, var) == {"track_lost": False}


def test_uncertain_filter_has_not_lost_the_track():
    """80 m off with a 40 m sigma (3 sigma = 170 m): acquiring, not lost."""
    var = np.full((T.size, 2), 40.0**2)
    assert track_loss(T, errors(0, 299), var) == {"track_lost": False}


def test_small_errors_are_never_lost():
    """Below 50 m the track is kept however small the covariance."""
    var = np.full((T.size, 2), 0.1**2)
    assert track_loss(T, errors(0, 299, size=45.0), var) == {"track_lost": False}


def test_no_estimate_is_lost():
    var = np.full((T.size, 2), 10.0**2)
    e = errors(0, -1)
    e[200:] = np.nan
    assert track_loss(T, e, var) == {"track_lost": True, "track_lost_at_s": 200.0}


def test_summary_reports_track_loss(tmp_path):
    """The evaluate stage writes ``track_lost`` per estimator: none in the terrain baseline; the
    PF's estimate moved 500 m away (its variances unchanged) is lost from the first step."""
    import shutil
    from pathlib import Path

    import pyarrow as pa
    import pyarrow.parquet as pq

    from uwcosim.evaluation import evaluate
    from uwcosim.runlog import columns

    base = Path(__file__).parent / "baselines" / "tan_terrain.parquet"
    (tmp_path / "kept").mkdir()
    shutil.copy(base, tmp_path / "kept" / "log.parquet")
    summary = evaluate(tmp_path / "kept", write=False)
    assert {n: m["track_lost"] for n, m in summary["estimators"].items()} == dict.fromkeys(
        summary["estimators"], False)
    table = pq.read_table(base)
    col = columns.estimate("pf", "x")
    i = table.schema.get_field_index(col)
    moved = pa.array(table.column(col).to_numpy() + 500.0)
    (tmp_path / "moved").mkdir()
    pq.write_table(table.set_column(i, col, moved), tmp_path / "moved" / "log.parquet")
    summary = evaluate(tmp_path / "moved", write=False)
    t1 = float(table.column("time").to_numpy()[1])
    assert summary["estimators"]["pf"]["track_lost"] is True
    assert summary["estimators"]["pf"]["track_lost_at_s"] == t1
    assert summary["estimators"]["ekf"]["track_lost"] is False
