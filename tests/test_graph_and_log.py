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


