"""Jobs on several supervised children at once (:func:`uwcosim.core.supervise.supervised_pool`,
``campaign --workers N``): every result once, a child that dies in a job is that job's
:class:`Death` naming the FMU call of *that* child (each child records on its own page), and
the other jobs go on in a new child."""

from __future__ import annotations

import os
import signal
import time

import pytest

from uwcosim.core import fmucall, supervise

pytestmark = pytest.mark.skipif(not supervise.enabled(), reason="needs fork")


def _job(item: tuple[str, int]) -> dict:
    """Item ``(what, n)``: ``ok`` returns ``n`` squared with the child's pid; ``die`` enters a
    doStep of FMU ``die<n>`` and kills its own process; ``slow`` enters a doStep of FMU
    ``slow<n>`` for a while (so that a dying child's neighbour is in a call of its own)."""
    what, n = item
    if what == "die":
        time.sleep(0.2)
        fmucall.begin(fmucall.fmu_index(f"die{n}"), fmucall.CALLS.index("doStep"), float(n))
        os.kill(os.getpid(), signal.SIGKILL)  # no handler runs (pytest's faulthandler)
    if what == "slow":
        fmucall.begin(fmucall.fmu_index(f"slow{n}"), fmucall.CALLS.index("doStep"), 0.0)
        time.sleep(0.6)
        fmucall.end()
    return {"square": n * n, "pid": os.getpid()}


def test_every_job_is_done_once_on_several_children():
    items = [("ok", n) for n in range(12)]
    results = dict(supervise.supervised_pool(_job, items, 3))
    assert sorted(results) == list(range(12))
    assert [results[i]["square"] for i in range(12)] == [n * n for n in range(12)]
    assert 1 < len({r["pid"] for r in results.values()}) <= 3


def test_a_child_that_dies_is_its_jobs_death_and_the_others_go_on():
    items = [("slow", 0), ("die", 1), ("ok", 2), ("die", 3), ("ok", 4), ("slow", 5)]
    results = dict(supervise.supervised_pool(_job, items, 2))
    assert sorted(results) == list(range(6))
    for i in (1, 3):
        death = results[i]
        assert isinstance(death, supervise.Death), death
        assert death.how == "killed by SIGKILL"
        assert death.call[:3] == (f"die{i}", "doStep", float(i)), death.call
        assert f"FMU 'die{i}' ended the process during doStep" in death.message()
    assert all(results[i]["square"] == i * i for i in (0, 2, 4, 5))


def test_one_worker_is_the_supervised_map():
    items = [("ok", 1), ("die", 2), ("ok", 3)]
    results = list(supervise.supervised_pool(_job, items, 1))
    assert [i for i, _ in results] == [0, 1, 2]
    assert isinstance(results[1][1], supervise.Death)



def _ok_or_announce_and_die(item: tuple[str, int]) -> int:
    """``ok``: returns ``n``; ``die``: says its run directory at once, then kills its own
    process."""
    what, n = item
    if what == "die":
        supervise.announce(f"/runs/{n}")
        os.kill(os.getpid(), signal.SIGKILL)
    return n


def test_the_death_of_a_job_names_the_run_directory_it_said_at_once():
    """While the caller holds a result, the child starts its next job, says its run directory
    and dies: the parent then reads ``item`` and ``out`` at once, and the directory is that
    job's (not cleared by the start of the job it belongs to)."""
    items = [("ok", 0), ("die", 1), ("ok", 2), ("die", 3)]
    seen = {}
    for i, result in supervise.supervised_map(_ok_or_announce_and_die, items):
        seen[i] = result
        time.sleep(0.3)  # the child goes on meanwhile
    assert seen[0] == 0 and seen[2] == 2
    assert (seen[1].out_dir, seen[3].out_dir) == ("/runs/1", "/runs/3")
    assert seen[1].how == seen[3].how == "killed by SIGKILL"
