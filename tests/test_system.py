"""`uwcosim run` of plain scenarios on the event test FMUs against `fmpy.simulate_fmu`.

Each FMU of ``tests/data/event_fmus`` (FMI 2.0 and 3.0, co-simulation and model exchange) runs
through the command line from a scenario written here, and is compared with fmpy's own
simulation loop on the same FMU: co-simulation on the same output grid, model exchange to the
solver tolerance, including the event times.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import fmpy
import numpy as np
import pytest

from uwcosim.cli import main
from uwcosim.runlog import read_log

try:
    from event_fmus import VERSIONS, event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover - run from the repository root
    from tests.event_fmus import VERSIONS, event_fmus  # noqa: F401


def toml_value(v) -> str:
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, Path):
        v = str(v)
    return json.dumps(v)  # strings, numbers and booleans are the same in TOML


def scenario(tmp_path: Path, fmus: dict, duration: float, step: float, connections=(),
             log=("*",), name: str = "s.toml", **tables) -> Path:
    """Write a plain scenario: ``fmus = {name: {key: value}}``; ``tables``: other sections
    (``run_extra``, ``controls`` ...) as dicts."""
    lines = [f"name = {json.dumps(Path(name).stem)}",
             f"connections = {toml_value([list(c) for c in connections])}", "", "[run]",
             f"duration = {duration!r}", f"step = {step!r}"]
    lines += [f"{k} = {toml_value(v)}" for k, v in tables.pop("run_extra", {}).items()]
    for fname, keys in fmus.items():
        lines += ["", f"[fmus.{fname}]"] + [f"{k} = {toml_value(v)}" for k, v in keys.items()]
    for section, entries in tables.items():
        for ename, keys in entries.items():
            lines += ["", f"[{section}.{ename}]"]
            lines += [f"{k} = {toml_value(v)}" for k, v in keys.items()]
    lines += ["", "[log]", f"signals = {toml_value(list(log))}"]
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def run(sc: Path, out: Path, *extra) -> tuple[int, dict, dict]:
    """``uwcosim run`` through the CLI: (exit status, log columns, summary)."""
    rc = main(["run", str(sc), "--out", str(out), "--no-figures", *extra])
    cols = read_log(out / "log.parquet")[0] if (out / "log.parquet").is_file() else {}
    summary = json.loads((out / "summary.json").read_text()) \
        if (out / "summary.json").is_file() else {}
    return rc, cols, summary


def ball_bounce_times(h0=1.0, g=9.81, e=0.7, v_min=0.1) -> np.ndarray:
    """Exact times of the bounces that do not leave the ball at rest."""
    t = [math.sqrt(2 * h0 / g)]
    v = math.sqrt(2 * g * h0) * e
    while v * e >= v_min:
        t.append(t[-1] + 2 * v / g)
        v *= e
    return np.array(t)


def bounces_from_grid(time, h, v, bounces, g=9.81) -> np.ndarray:
    """Bounce times recovered from the first sample after each bounce: the ball flies a parabola
    from the floor, so ``h = v s + g s^2 / 2`` with ``s`` the time since the bounce."""
    out = []
    for i in np.flatnonzero(np.diff(bounces) == 1) + 1:
        if v[i] == 0.0 and h[i] == 0.0:  # the last bounce: at rest
            continue
        s = (-v[i] + math.sqrt(v[i] ** 2 + 2 * g * h[i])) / g
        out.append(time[i] - s)
    return np.array(out)


# -- BouncingBall ----------------------------------------------------------------------------
@pytest.mark.parametrize("version", VERSIONS)
def test_ball_cs_matches_fmpy_on_the_same_grid(event_fmus, tmp_path, version):
    path = event_fmus[("BouncingBall", version)]
    sc = scenario(tmp_path, {"ball": {"path": path}}, 3.0, 0.01)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    ref = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", stop_time=3.0,
                            output_interval=0.01, output=["h", "v", "bounces"])
    assert cols["time"].size == ref["time"].size == 301
    # the same grid and the same step sizes t_{k+1} - t_k: the same numbers, bit for bit
    np.testing.assert_array_equal(cols["time"], ref["time"])
    np.testing.assert_array_equal(cols["ball.h"], ref["h"])
    np.testing.assert_array_equal(cols["ball.v"], ref["v"])
    np.testing.assert_array_equal(cols["ball.bounces"], ref["bounces"])
    assert cols["ball.bounces"].dtype == np.int32 and cols["ball.bounces"][-1] == 11


@pytest.mark.parametrize("version", VERSIONS)
def test_ball_me_matches_fmpy_and_the_bounce_times(event_fmus, tmp_path, version):
    path = event_fmus[("BouncingBall", version)]
    sc = scenario(tmp_path, {"ball": {"path": path, "interface": "me", "rtol": 1e-10}},
                  3.0, 0.01)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    t, h, v, b = cols["time"], cols["ball.h"], cols["ball.v"], cols["ball.bounces"]
    assert h.min() > -1e-6  # the ball no longer falls through the floor
    exact = ball_bounce_times()
    np.testing.assert_allclose(bounces_from_grid(t, h, v, b), exact, rtol=0, atol=1e-6)
    ref = fmpy.simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=3.0,
                            output_interval=0.01, relative_tolerance=1e-10,
                            output=["h", "v", "bounces"])
    ref_events = ref["time"][1:][np.diff(ref["time"]) == 0]  # fmpy records both sides
    np.testing.assert_allclose(ref_events[:len(exact)], exact, rtol=0, atol=1e-6)
    # on the grid (fmpy's rows at the events removed): the same values to the tolerance
    grid = np.concatenate([[True], np.diff(ref["time"]) > 0])
    on_grid = np.isclose(ref["time"][grid], np.round(ref["time"][grid] / 0.01) * 0.01,
                         rtol=0, atol=1e-9)
    r_t, r_h = ref["time"][grid][on_grid], ref["h"][grid][on_grid]
    assert r_t.size == 301
    np.testing.assert_allclose(t, r_t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(h, r_h, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(b, ref["bounces"][grid][on_grid])
