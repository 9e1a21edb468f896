"""Connection graph (order, algebraic loops) and the incremental Parquet log."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import AlgebraicLoopError
from uwcosim.master.graph import stepping_order
from uwcosim.runlog import RunLogger, read_log


def test_order_follows_feedthrough_dependencies():
    deps = {"sensor": {"z": {"x"}}, "vehicle": {"x": set()}, "filter": {"y": {"z"}}}
    conns = [("sensor.z", "filter.z"), ("vehicle.x", "sensor.x")]
    order = stepping_order(["filter", "sensor", "vehicle"], conns, deps)
    assert order.index("vehicle") < order.index("sensor") < order.index("filter")


def test_feedback_through_states_is_not_a_loop():
    # controller output depends on its input; the plant's output does not (state)
    deps = {"plant": {"y": set()}, "ctrl": {"u": {"y"}}}
    conns = [("plant.y", "ctrl.y"), ("ctrl.u", "plant.u")]
    order = stepping_order(["plant", "ctrl"], conns, deps)
    assert order == ["plant", "ctrl"]


def test_algebraic_loop_is_reported_with_its_variables():
    deps = {"a": {"y": {"u"}}, "b": {"y": {"u"}}}
    conns = [("a.y", "b.u"), ("b.y", "a.u")]
    with pytest.raises(AlgebraicLoopError, match="algebraic loop") as info:
        stepping_order(["a", "b"], conns, deps)
    assert "a.y" in str(info.value) and "b.u" in str(info.value)


def test_algebraic_loop_message_arrows_run_along_the_data_flow():
    """Each arrow of the message is a connection (output -> input) or a feedthrough inside an
    FMU (input -> output): the loop read in the direction the values flow (issue 21, item 8)."""
    deps = {"a": {"y": {"u"}}, "b": {"y": {"u"}}, "c": {"y": {"u"}}}
    conns = [("a.y", "b.u"), ("b.y", "c.u"), ("c.y", "a.u")]
    with pytest.raises(AlgebraicLoopError) as info:
        stepping_order(["a", "b", "c"], conns, deps)
    loop = str(info.value).split(": ", 1)[1].split(" -> ")
    flow = set(conns) | {(f"{f}.u", f"{f}.y") for f in deps}
    assert loop[0] == loop[-1] and len(loop) == 7
    assert all(edge in flow for edge in zip(loop, loop[1:])), loop


def test_log_chunks_are_readable_before_close(tmp_path):
    path = tmp_path / "log.parquet"
    log = RunLogger(path, ["a"], ["ok"], {"seed": 1}, chunk=3)
    for k in range(7):
        log.append(np.array([k * 0.5, k]), np.array([k % 2 == 0]))
    # two chunks written, one row buffered: a crash now keeps 6 rows
    assert log.rows_written == 6
    log.close()
    cols, meta = read_log(path)
    np.testing.assert_array_equal(cols["time"], np.arange(7) * 0.5)
    np.testing.assert_array_equal(cols["ok"], [True, False] * 3 + [True])
    assert meta == {"seed": 1}
    assert list(cols)[0] == "time"




def test_the_tail_keeps_64_bit_integers_that_float64_holds(tmp_path):
    """A log whose writer never closed it (a crash) is read from its tail: Int64 and UInt64
    values come back exactly up to 2**53 in magnitude, null beyond; Strings are null."""
    path = tmp_path / "log.parquet"
    log = RunLogger(path, ["a", "n", "u", "s"], [], {"seed": 1}, chunk=100,
                    dtypes={"n": np.int64, "u": np.uint64, "s": object})
    ints = [-2**53, -1, 0, 2**60, 2**53]
    uints = [0, 1, 2**53, 3, 2**64 - 1]
    for k in range(5):
        log.append(np.array([k, k * 0.5, np.nan, np.nan, np.nan]), np.zeros(0, dtype=bool),
                   [ints[k], uints[k], f"s{k}"])
    assert log.rows_written == 0  # every row only in the tail file
    cols, _ = read_log(path)
    np.testing.assert_array_equal(cols["n"], [-2.0**53, -1, 0, np.nan, 2.0**53])
    np.testing.assert_array_equal(cols["u"], [0, 1, 2.0**53, 3, np.nan])
    assert cols["s"].tolist() == [None] * 5
    np.testing.assert_array_equal(cols["a"], np.arange(5) * 0.5)
    log.close()
    cols, _ = read_log(path)  # closed: every value exact
    assert cols["n"].tolist() == ints and cols["u"].tolist() == uints
    assert cols["s"].tolist() == [f"s{k}" for k in range(5)]
