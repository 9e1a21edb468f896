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
from uwcosim.master.observer import Callback
from uwcosim.runlog import read_log

try:
    from conftest import without_progress
except ImportError:  # tests/ imported as a package
    from tests.conftest import without_progress

try:
    from event_fmus import VERSIONS, event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover - run from the repository root
    from tests.event_fmus import VERSIONS, event_fmus  # noqa: F401


def toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)


def toml_value(v) -> str:
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
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
    assert summary["fmus"]["ball"]["solver"] == "cvode"  # event indicators: root finding
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


# -- Stair: time events, an Integer output, termination ---------------------------------------
@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("interface", ["cs", "me"])
def test_stair_matches_fmpy(event_fmus, tmp_path, version, interface):
    path = event_fmus[("Stair", version)]
    sc = scenario(tmp_path, {"stair": {"path": path, "interface": interface}}, 10.0, 0.1)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    ref = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation" if interface == "cs" else
                            "ModelExchange", stop_time=10.0, output_interval=0.1,
                            output=["counter"])
    # fmpy's ME result has two rows at a time event: keep the last (after the event), as ours
    last = np.append(np.diff(ref["time"]) > 0, True)
    np.testing.assert_array_equal(cols["time"], ref["time"][last])
    np.testing.assert_array_equal(cols["stair.counter"], ref["counter"][last])
    assert cols["stair.counter"].dtype == np.int32
    # counter = 1 + floor(t), the ticks (time events) on the grid included
    np.testing.assert_array_equal(cols["stair.counter"], 1 + np.floor(cols["time"] + 1e-9))


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("t_end", [5.0, 5.05], ids=["on-grid", "mid-step"])
def test_stair_termination_ends_the_run(event_fmus, tmp_path, capsys, version, interface,
                                        t_end):
    path = event_fmus[("Stair", version)]
    sc = scenario(tmp_path, {"stair": {"path": path, "interface": interface,
                                       "parameters": {"t_terminate": t_end}}}, 10.0, 0.1)
    out = tmp_path / "r"
    rc = main(["run", str(sc), "--out", str(out)])
    err = without_progress(capsys.readouterr().err).strip().splitlines()
    assert rc == 0
    assert err == [f"uwcosim: FMU 'stair' requested termination at t={t_end:g}: "
                   + err[0].split(": ", 2)[2]]
    cols, _ = read_log(out / "log.parquet")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "terminated" and summary["error"] == ""
    assert summary["termination"]["fmu"] == "stair"
    assert summary["termination"]["time_s"] == pytest.approx(t_end, abs=1e-12)
    assert summary["end_time_s"] == pytest.approx(t_end, abs=1e-12)
    # rows up to the termination time: the grid up to it, and the termination time itself
    t = cols["time"]
    assert t[-1] == pytest.approx(t_end, abs=1e-12) and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(t[:-1], 0.1 * np.arange(t.size - 1), rtol=0, atol=1e-12)
    assert t.size == (51 if t_end == 5.0 else 52)
    assert cols["stair.counter"][-1] == 6
    assert "status **terminated**" in (out / "report.md").read_text()


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_stair_termination_as_error(event_fmus, tmp_path, capsys, interface):
    path = event_fmus[("Stair", "2.0")]
    sc = scenario(tmp_path, {"stair": {"path": path, "interface": interface,
                                       "parameters": {"t_terminate": 2.0}}}, 10.0, 0.1,
                  run_extra={"stop_on_terminate": "error"})
    out = tmp_path / "r"
    assert main(["run", str(sc), "--out", str(out)]) == 3
    err = without_progress(capsys.readouterr().err).strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("uwcosim: error: FMU 'stair' requested termination at t=2")
    assert 'stop_on_terminate = "error"' in err and "log up to t=" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["termination"]["time_s"] == 2.0
    assert read_log(out / "log.parquet")[0]["time"][-1] <= 2.0 + 1e-12


@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("t_end", [2.0, 2.05], ids=["on-grid", "mid-step"])
def test_termination_as_error_keeps_the_last_row_as_stop_does(event_fmus, tmp_path, interface,
                                                              t_end):
    """``stop_on_terminate = "error"`` only changes the status and the exit code: the log has
    the same rows as with ``"stop"``, the termination time's row included (issue 21, item 8)."""
    path = event_fmus[("Stair", "2.0")]
    logs = {}
    for how in ("stop", "error"):
        sc = scenario(tmp_path, {"stair": {"path": path, "interface": interface,
                                           "parameters": {"t_terminate": t_end}}}, 10.0, 0.1,
                      run_extra={"stop_on_terminate": how}, name=f"{how}.toml")
        out = tmp_path / how
        assert main(["run", str(sc), "--out", str(out)]) == (0 if how == "stop" else 3)
        logs[how] = read_log(out / "log.parquet")[0]
    assert logs["stop"]["time"][-1] == pytest.approx(t_end, abs=1e-12)
    for name in ("time", "stair.counter"):
        np.testing.assert_array_equal(logs["error"][name], logs["stop"][name])


# -- Feedthrough: connections across types and across CS/ME -----------------------------------
CONTROLS = {"u": {"target": "ft.u", "table": [[0, 0.0], [1, 1.0], [2, -1.0]]},
            "iu": {"target": "ft.iu", "table": [[0, 0], [0.5, 3], [1.5, -2]],
                   "interpolation": "hold"},
            "bu": {"target": "ft.bu", "table": [[0, 0], [0.7, 1], [1.2, 0]],
                   "interpolation": "hold"}}


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("interface", ["cs", "me"])
def test_feedthrough_typed_inputs_match_fmpy(event_fmus, tmp_path, version, interface):
    path = event_fmus[("Feedthrough", version)]
    sc = scenario(tmp_path, {"ft": {"path": path, "interface": interface,
                                    "parameters": {"k": 3}}}, 2.0, 0.1, controls=CONTROLS)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    t = cols["time"]
    u = np.interp(t, [0, 1, 2], [0.0, 1.0, -1.0])
    iu = np.where(t < 0.5 - 1e-9, 0, np.where(t < 1.5 - 1e-9, 3, -2))
    bu = (t >= 0.7 - 1e-9) & (t < 1.2 - 1e-9)

    def held(x):  # the value set at t_k, held over the step: seen in the row of t_{k+1}
        return np.concatenate([x[:1], x[:-1]])

    # co-simulation holds every input over the step; model exchange follows the Real table
    # at the integrator's stages and sets the discrete inputs at communication points
    y = held(u) if interface == "cs" else u
    np.testing.assert_allclose(cols["ft.y"], y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(cols["ft.yk"], 3 * y, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(cols["ft.iy"], held(iu))
    np.testing.assert_array_equal(cols["ft.by"], held(bu))
    assert cols["ft.iy"].dtype == np.int32 and cols["ft.by"].dtype == np.bool_
    # fmpy with the same inputs (linear u, held iu and bu) gives the same outputs; its ME
    # result has two rows at an input event: ours is the one before the new input
    signals = np.array(list(zip(t, u, iu, bu)),
                       dtype=[("time", float), ("u", float), ("iu", np.int32), ("bu", bool)])
    ref = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation" if interface == "cs" else
                            "ModelExchange", stop_time=2.0, output_interval=0.1,
                            start_values={"k": 3.0}, input=signals,
                            output=["y", "iy", "by", "yk"])
    first = np.concatenate([[True], np.diff(ref["time"]) > 0])
    assert first.sum() == t.size
    np.testing.assert_allclose(cols["ft.y"], ref["y"][first], rtol=0, atol=1e-12)
    np.testing.assert_allclose(cols["ft.yk"], ref["yk"][first], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(cols["ft.iy"], ref["iy"][first])
    np.testing.assert_array_equal(cols["ft.by"], ref["by"][first])


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("ft_interface", ["cs", "me"])
def test_me_ball_feeds_feedthrough_across_types(event_fmus, tmp_path, version, ft_interface):
    """Ball (ME, events) -> Feedthrough: Float -> Float and Int32 -> Float64; Stair (ME, time
    events) -> the Feedthrough's discrete Integer input, set at communication points only."""
    fmus = {"ball": {"path": event_fmus[("BouncingBall", version)], "interface": "me"},
            "stair": {"path": event_fmus[("Stair", version)], "interface": "me"},
            "ft": {"path": event_fmus[("Feedthrough", version)], "interface": ft_interface}}
    conns = [("ball.h", "ft.u"), ("stair.counter", "ft.iu")]
    sc = scenario(tmp_path, fmus, 3.0, 0.01, connections=conns)
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "ok"
    # Gauss-Seidel: the Feedthrough sees the ball's and the stair's outputs of the same point
    np.testing.assert_array_equal(cols["ft.y"], cols["ball.h"])
    np.testing.assert_array_equal(cols["ft.iy"], cols["stair.counter"])
    assert cols["ball.bounces"][-1] == 11 and cols["ft.iy"][-1] == 4
    # the Integer bounce count into a Float64 input is allowed too
    sc2 = scenario(tmp_path, fmus, 1.0, 0.01, connections=[("ball.bounces", "ft.u")],
                   name="b.toml")
    rc, cols, _ = run(sc2, tmp_path / "r2")
    assert rc == 0
    np.testing.assert_array_equal(cols["ft.y"], cols["ball.bounces"].astype(float))


def test_float_to_integer_connection_is_refused(event_fmus, tmp_path, capsys):
    fmus = {"ball": {"path": event_fmus[("BouncingBall", "3.0")]},
            "ft": {"path": event_fmus[("Feedthrough", "3.0")]}}
    sc = scenario(tmp_path, fmus, 1.0, 0.1, connections=[("ball.h", "ft.iu")])
    assert main(["run", str(sc), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "key 'connections[0]'" in err and "'ball.h' (Float64)" in err
    assert "'ft.iu' (Int32)" in err


def test_system_built_in_code_as_in_the_readme(event_fmus):
    """The README's example: a Python user builds the System, no TOML."""
    from uwcosim.master import FMU, Control, Master, System

    system = System(fmus={"ball": FMU(event_fmus[("BouncingBall", "3.0")], interface="me"),
                          "ft": FMU(event_fmus[("Feedthrough", "2.0")], parameters={"k": 3})},
                    connections=[("ball.h", "ft.u")],
                    controls={"iu": Control(target="ft.iu", table=[[0, 0], [1, 5]],
                                            interpolation="hold")},
                    step=0.01, duration=3.0)
    m = Master(system, seed=1)
    rows = []
    m.observers.append(Callback(lambda k, v: k and rows.append(
        (v.t, v.value("ball.h"), v.value("ft.yk"), v.value("ft.iy"), v.value("ball.bounces")))))
    try:
        m.initialize()
        m.run_until(3.0)
    finally:
        m.close()
    assert m.t == pytest.approx(3.0) and m.terminated is None
    t, h, yk, iy, b = (np.array(c) for c in zip(*rows))
    np.testing.assert_array_equal(yk, 3 * h)  # Gauss-Seidel: same communication point
    assert isinstance(rows[-1][4], int) and b[-1] == 11
    np.testing.assert_array_equal(iy, np.where(t <= 1.0 + 1e-9, 0, 5))
    # the bounce count steps up in the step that holds each exact bounce time
    exact = ball_bounce_times()
    np.testing.assert_allclose(t[np.searchsorted(b, np.arange(1, exact.size + 1))],
                               np.ceil(exact / 0.01) * 0.01, rtol=0, atol=1e-9)
    assert h.min() > -1e-6
    assert not Path(m.unzip_root).exists()


def test_termination_of_an_fmu_in_a_worker_process(event_fmus, tmp_path):
    """``timeout_s``: the FMU runs in a worker process; its request to stop comes through."""
    fmus = {"stair": {"path": event_fmus[("Stair", "2.0")], "timeout_s": 30,
                      "parameters": {"t_terminate": 0.55}},
            "ft": {"path": event_fmus[("Feedthrough", "3.0")], "interface": "me"}}
    sc = scenario(tmp_path, fmus, 2.0, 0.1, connections=[("stair.counter", "ft.iu")])
    rc, cols, summary = run(sc, tmp_path / "r")
    assert rc == 0 and summary["status"] == "terminated"
    assert summary["termination"] == {"fmu": "stair", "time_s": 0.55,
                                      "reason": summary["termination"]["reason"]}
    np.testing.assert_allclose(cols["time"], [0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.55], atol=1e-12)
