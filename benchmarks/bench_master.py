"""Master overhead against a raw fmpy loop over the same FMUs, and the demo run time.

Measured side by side in one run (ratios; the machines are shared and noisy):

1. a raw loop with fmpy's public API (setReal/doStep/getReal per FMU per step, values copied
   by hand between the three FMUs) over the default scenario's FMUs;
2. our master stepping the same FMUs with the same inputs (no estimators, no logging);
3. the default scenario end to end (5000 steps, dead reckoning + EKF, log, no figures);
4. model exchange with events: the test BouncingBall (FMI 3, ``tests/data/event_fmus``, built
   with CMake into a temporary folder) for 10 s on a 0.01 s grid at relative tolerance 1e-6,
   through the master's ME stepping (CVode with root finding) against ``fmpy.simulate_fmu``
   (``fmi_type="ModelExchange"``, CVode) on the same unzipped FMU, same output interval and
   tolerance. Both include instantiation and initialization; the master's construction
   (archive checks, unzip) is not timed, nor is fmpy's unzip (it is given the folder).

5. strongly coupled model exchange: two SpringMass FMUs (FMI 2, ``tests/data/event_fmus``)
   joined by their spring, 10 s on a 0.01 s grid, CVode at rtol 1e-6, through the master (one
   CVode over both, :mod:`uwcosim.fmi.coupled`) against two single-solver references: (a) the
   same pair run by a minimal loop written here (fmpy's CVodeSolver over both FMUs' states,
   the FMI calls made directly, outputs read at every grid point), (b) ``fmpy.simulate_fmu``
   on TwoMasses (the same equations in one FMU). The three agree with the closed form
   ``expm(A t) x0`` (printed). Initialization included, unzipping not (all three get the
   unzipped folder).
6. the per-run fixed cost of an in-process run: a plain co-simulation of two test FMUs
   (BouncingBall -> Feedthrough, 10 steps): ``Master`` built, initialized, run and closed, and
   the whole ``simulate`` stage (log, simulation.json, summary.json), best of 10 in a warm
   process.
7. the log's tail file (``log.parquet.tail``: the rows a crash would otherwise lose): 5000 rows
   of the default scenario's width (with the EKF) logged the way a run does (each row staged
   when recorded, then appended), with and without the tail file, interleaved, best of 5; the
   difference per step beside the default scenario's time per step of (3).

7. the record of every FMU call that the run-wide watchdog times and a crashed run's report
   names (:mod:`uwcosim.core.fmucall`): (2) with the record as it is against (2) with its
   ``begin``/``end`` replaced by empty functions (the calls and their ``try``/``finally``
   kept), interleaved, best of each; the record's calls per step counted; and the
   ``begin``/``end`` pair alone against the empty pair (``timeit``).

Goals: (2) at most 1.25x (1); (3) under 2 s; (4) at most 2x fmpy; (5) at most 1.5x the
single-solver reference; (6) under 20 ms.
Run: ``.venv/bin/python benchmarks/bench_master.py`` (``--record``: item 7 alone).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from uwcosim.api import run_scenario  # noqa: E402
from uwcosim.master.master import Master  # noqa: E402
from uwcosim.models.terrain import synthetic_bathymetry  # noqa: E402
from uwcosim.scenario import load_scenario, to_system  # noqa: E402

SCENARIO = ROOT / "scenarios" / "tan_terrain.toml"
STEPS = 5000


def raw_fmpy_loop(map_file: str) -> float:
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    fmus = {}
    for name in ("AUVKinematics", "DVL", "DepthSounder"):
        path = str(ROOT / "fmus" / f"{name}.fmu")
        md = read_model_description(path)
        unzip = extract(path)
        fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=unzip,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        fmu.instantiate()
        vr = {v.name: v.valueReference for v in md.modelVariables}
        fmus[name] = (fmu, vr)
    veh, vvr = fmus["AUVKinematics"]
    dvl, dvr = fmus["DVL"]
    snd, svr = fmus["DepthSounder"]
    veh.setFloat64([vvr[n] for n in ("x", "y", "vx", "vy")], [2000.0, 18000.0, 0.5, 0.0])
    snd.setString([svr["mapFile"]], [map_file])
    for f in (veh, dvl, snd):
        f.enterInitializationMode()
        f.exitInitializationMode()
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((STEPS, 7)) * 1e-3
    vin = [vvr[n] for n in ("psi", "a", "w_x", "w_y", "w_vx", "w_vy")]
    vout = [vvr[n] for n in ("x", "y", "vx", "vy")]
    din = [dvr[n] for n in ("vx", "vy", "e_vx", "e_vy")]
    dout = [dvr[n] for n in ("vx_m", "vy_m")]
    sin_ = [svr[n] for n in ("x", "y", "e_h")]
    sout = [svr["depth_m"]]
    a = time.perf_counter()
    for k in range(STEPS):
        t = float(k)
        veh.setFloat64(vin, [0.1, 0.0, *noise[k, :4]])
        veh.doStep(t, 1.0)
        x, y, vx, vy = veh.getFloat64(vout)
        dvl.setFloat64(din, [vx, vy, noise[k, 4], noise[k, 5]])
        dvl.doStep(t, 1.0)
        dvl.getFloat64(dout)
        snd.setFloat64(sin_, [x, y, noise[k, 6]])
        snd.doStep(t, 1.0)
        snd.getFloat64(sout)
    elapsed = time.perf_counter() - a
    for f, _ in fmus.values():
        f.terminate()
        f.freeInstance()
    return elapsed / STEPS


def master_loop(map_file: str) -> float:
    loaded = load_scenario(SCENARIO, ["estimators={}"])
    m = Master(to_system(loaded), seed=0)
    m.initialize({"sounder": {"mapFile": map_file}})
    a = time.perf_counter()
    m.run_until(STEPS)
    elapsed = time.perf_counter() - a
    m.close()
    return elapsed / STEPS


def bouncing_ball(repeats: int = 5) -> tuple[float, float, int]:
    """Best-of-``repeats`` seconds of fmpy.simulate_fmu and of the master (BouncingBall ME),
    and the bounces both counted (they must agree)."""
    import fmpy
    from fmpy import extract

    sys.path.insert(0, str(ROOT / "tests"))
    from event_fmus import build_event_fmus  # noqa: E402 - the tests' CMake build

    from uwcosim.master import FMU, System

    rtol, h, stop = 1e-6, 0.01, 10.0
    with tempfile.TemporaryDirectory() as tmp:
        path = build_event_fmus(Path(tmp))[("BouncingBall", "3.0")]
        unzipped = extract(str(path), unzipdir=str(Path(tmp) / "unzipped"))
        t_fmpy, t_ours, bounces = [], [], set()
        for _ in range(repeats):
            a = time.perf_counter()
            r = fmpy.simulate_fmu(unzipped, fmi_type="ModelExchange", stop_time=stop,
                                  output_interval=h, relative_tolerance=rtol,
                                  output=["h", "bounces"])
            t_fmpy.append(time.perf_counter() - a)
            bounces.add(int(r["bounces"][-1]))
            m = Master(System(fmus={"ball": FMU(path, interface="me", rtol=rtol)}, step=h,
                              duration=stop))
            a = time.perf_counter()
            m.initialize()
            m.run_until(stop)
            t_ours.append(time.perf_counter() - a)
            bounces.add(int(m.signal("ball.bounces")))
            m.close()
    if len(bounces) != 1:
        raise SystemExit(f"BouncingBall: fmpy and the master disagree on the bounces {bounces}")
    return min(t_fmpy), min(t_ours), bounces.pop()


MASSES = {"a": {"m": 1.0, "c": 1.0, "c_wall": 1.0}, "b": {"m": 2.0, "c": 1.0, "c_wall": 0.5}}
X0 = {"a": 1.0, "b": 0.0}


def masses_exact(t: float) -> np.ndarray:
    """The two masses in closed form at ``t``: (xa, va, xb, vb)."""
    from scipy.linalg import expm

    a, b = MASSES["a"], MASSES["b"]
    A = np.array([[0, 1, 0, 0], [-(a["c"] + a["c_wall"]) / a["m"], 0, a["c"] / a["m"], 0],
                  [0, 0, 0, 1], [b["c"] / b["m"], 0, -(b["c"] + b["c_wall"]) / b["m"], 0]])
    return expm(A * t) @ np.array([X0["a"], 0.0, X0["b"], 0.0])


def pair_minimal_loop(unzipped: str, rtol: float, h: float, stop: float) -> tuple[float, float]:
    """The two SpringMass FMUs on one CVode by a minimal loop: seconds and x of mass a at the
    end. Per evaluation: time and states of both, then a.x -> b.x_other -> b.x -> a.x_other,
    then the derivatives; per grid point: CVode, time, exchange, completedIntegratorStep."""
    import ctypes

    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Model
    from fmpy.sundials import CVodeSolver

    md = read_model_description(unzipped)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    a = time.perf_counter()
    fmus = []
    for name in ("a", "b"):
        fmu = FMU2Model(guid=md.guid, unzipDirectory=unzipped,
                        modelIdentifier=md.modelExchange.modelIdentifier, instanceName=name)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        values = {**MASSES[name], "x": X0[name]}
        fmu.setReal([vr[k] for k in values], list(values.values()))
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.newDiscreteStates()
        fmu.enterContinuousTimeMode()
        fmus.append(fmu)
    dll, (ca, cb) = fmus[0].dll, (f.component for f in fmus)
    set_time, set_x = dll.fmi2SetTime, dll.fmi2SetContinuousStates
    get_x, get_dx = dll.fmi2GetContinuousStates, dll.fmi2GetDerivatives
    get_nom, get_real, set_real = (dll.fmi2GetNominalsOfContinuousStates, dll.fmi2GetReal,
                                   dll.fmi2SetReal)
    completed = dll.fmi2CompletedIntegratorStep
    vr_x, vr_in = (ctypes.c_uint * 1)(vr["x"]), (ctypes.c_uint * 1)(vr["x_other"])
    buf, flags = (ctypes.c_double * 1)(), [ctypes.c_int(), ctypes.c_int()]

    def exchange() -> None:
        get_real(ca, vr_x, 1, buf)
        set_real(cb, vr_in, 1, buf)
        get_real(cb, vr_x, 1, buf)
        set_real(ca, vr_in, 1, buf)

    def cb_time(t: float) -> None:
        set_time(ca, t)
        set_time(cb, t)

    def cb_set_x(p, n) -> None:
        set_x(ca, p, 2)
        set_x(cb, ctypes.byref(p.contents, 16), 2)
        exchange()

    def cb_get_x(p, n) -> None:
        get_x(ca, p, 2)
        get_x(cb, ctypes.byref(p.contents, 16), 2)

    def cb_get_dx(p, n) -> None:
        get_dx(ca, p, 2)
        get_dx(cb, ctypes.byref(p.contents, 16), 2)

    def cb_nominals(p, n) -> None:
        get_nom(ca, p, 2)
        get_nom(cb, ctypes.byref(p.contents, 16), 2)

    class NoInput:
        @staticmethod
        def apply(t: float) -> None:
            return None

    exchange()
    solver = CVodeSolver(nx=4, nz=0, get_x=cb_get_x, set_x=cb_set_x, get_dx=cb_get_dx,
                         get_z=lambda p, n: None, get_nominals=cb_nominals, set_time=cb_time,
                         input=NoInput(), startTime=0.0, maxStep=stop / 50,
                         relativeTolerance=rtol, maxNumSteps=100_000)
    n = int(round(stop / h))
    out = np.zeros((n + 1, 2))
    t = 0.0
    for k in range(n):
        t_next = (k + 1) * h
        solver.step(t, t_next)
        t = t_next
        cb_time(t)
        exchange()
        for c in (ca, cb):
            completed(c, 1, ctypes.byref(flags[0]), ctypes.byref(flags[1]))
        get_real(ca, vr_x, 1, buf)
        out[k + 1, 0] = buf[0]
        get_real(cb, vr_x, 1, buf)
        out[k + 1, 1] = buf[0]
    elapsed = time.perf_counter() - a
    for fmu in fmus:
        fmu.terminate()
        fmu.freeInstance()
    return elapsed, float(out[-1, 0])


def coupled_pair(repeats: int = 7) -> dict[str, tuple[float, float]]:
    """Best-of-``repeats`` seconds and the final x of mass a: the master (coupled), the
    minimal loop, fmpy on TwoMasses."""
    import fmpy
    from fmpy import extract

    sys.path.insert(0, str(ROOT / "tests"))
    from event_fmus import build_event_fmus  # noqa: E402 - the tests' CMake build

    from uwcosim.master import FMU, System

    rtol, h, stop = 1e-6, 0.01, 10.0
    out: dict[str, list] = {"master": [], "loop": [], "fmpy": []}
    with tempfile.TemporaryDirectory() as tmp:
        fmus = build_event_fmus(Path(tmp))
        pair = extract(str(fmus[("SpringMass", "2.0")]), unzipdir=str(Path(tmp) / "pair"))
        both = extract(str(fmus[("TwoMasses", "2.0")]), unzipdir=str(Path(tmp) / "both"))
        system = System(fmus={n: FMU(pair, interface="me",  # unzipped, as for the others
                                     solver="cvode", rtol=rtol, parameters=MASSES[n],
                                     start={"x": X0[n]}) for n in ("a", "b")},
                        connections=[("a.x", "b.x_other"), ("b.x", "a.x_other")],
                        step=h, duration=stop)
        a, b = MASSES["a"], MASSES["b"]
        start = {"m1": a["m"], "m2": b["m"], "c": a["c"], "c1": a["c_wall"],
                 "c2": b["c_wall"], "x1": X0["a"], "x2": X0["b"]}
        for _ in range(repeats):  # interleaved: the machine's load hits all three alike
            m = Master(system)
            t0 = time.perf_counter()
            m.initialize()
            m.run_until(stop)
            out["master"].append((time.perf_counter() - t0, m.signal("a.x")))
            m.close()
            out["loop"].append(pair_minimal_loop(pair, rtol, h, stop))
            t0 = time.perf_counter()
            r = fmpy.simulate_fmu(both, fmi_type="ModelExchange", stop_time=stop,
                                  output_interval=h, relative_tolerance=rtol,
                                  start_values=start, output=["x1"])
            out["fmpy"].append((time.perf_counter() - t0, float(r["x1"][-1])))
    return {k: min(v) for k, v in out.items()}


def fixed_cost(repeats: int = 10) -> tuple[float, float]:
    """Best-of seconds of a plain in-process run (two test FMUs, 10 steps): the master alone
    (build, initialize, run, close) and the simulate stage (the same as a scenario)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from event_fmus import build_event_fmus  # noqa: E402 - the tests' CMake build

    from uwcosim import simulate
    from uwcosim.master import FMU, System

    with tempfile.TemporaryDirectory() as tmp:
        fmus = build_event_fmus(Path(tmp) / "fmus")
        ball, ft = fmus[("BouncingBall", "2.0")], fmus[("Feedthrough", "3.0")]
        sc = Path(tmp) / "plain.toml"
        sc.write_text(f'connections = [["ball.h", "ft.u"]]\n[run]\nduration = 0.1\n'
                      f'step = 0.01\n[fmus.ball]\npath = "{ball}"\n[fmus.ft]\n'
                      f'path = "{ft}"\n[log]\nsignals = ["ball.*", "ft.y"]\n')
        system = System(fmus={"ball": FMU(ball), "ft": FMU(ft)},
                        connections=[("ball.h", "ft.u")], step=0.01, duration=0.1)
        t_master, t_sim = [], []
        for i in range(repeats + 2):  # the first two warm the process up
            a = time.perf_counter()
            m = Master(system)
            m.initialize()
            m.run_until(0.1)
            m.close()
            t_master.append(time.perf_counter() - a)
            a = time.perf_counter()
            simulate(load_scenario(sc), Path(tmp) / f"run{i}")
            t_sim.append(time.perf_counter() - a)
    return min(t_master[2:]), min(t_sim[2:])


def call_record(map_file: str, segments: int = 60, steps: int = 200) -> dict[str, float]:
    """Item 7: seconds per step of one master (3 FMUs, no estimators) run in ``segments``
    stretches of ``steps`` steps, alternately with the record of every FMU call and with it
    emptied (best and median of each), the record's calls per step, and the seconds per
    ``begin``/``end`` pair and per empty pair (best of interleaved ``timeit`` runs)."""
    from uwcosim.core import fmucall

    real = fmucall.begin, fmucall.end
    calls = [0]

    def counting(fmu: int, call: int, t: float) -> None:
        calls[0] += 1
        real[0](fmu, call, t)

    def empty_begin(fmu: int, call: int, t: float) -> None:
        pass

    def empty_end() -> None:
        pass

    loaded = load_scenario(SCENARIO, ["estimators={}",
                                      f"run.duration={float((segments + 1) * steps)}"])
    m = Master(to_system(loaded), seed=0)
    m.initialize({"sounder": {"mapFile": map_file}})
    on, off = [], []
    try:
        fmucall.begin = counting
        m.run_until(float(steps))  # warm-up, and the count
        per_step = calls[0] / steps
        for j in range(segments):
            empty = j % 2 == 1
            fmucall.begin, fmucall.end = (empty_begin, empty_end) if empty else real
            a = time.perf_counter()
            m.run_until(float((j + 2) * steps))
            (off if empty else on).append((time.perf_counter() - a) / steps)
    finally:
        fmucall.begin, fmucall.end = real
        m.close()
    i = fmucall.fmu_index("bench")

    def pair(begin=real[0], end=real[1]) -> None:
        begin(i, 3, 1.0)
        try:
            pass
        finally:
            end()

    def empty_pair(begin=empty_begin, end=empty_end) -> None:
        begin(i, 3, 1.0)
        try:
            pass
        finally:
            end()

    n = 200_000
    t_pair, t_empty = [], []
    for _ in range(7):
        t_pair.append(timeit.timeit(pair, number=n) / n)
        t_empty.append(timeit.timeit(empty_pair, number=n) / n)
    fmucall.clear()
    return {"with": min(on), "without": min(off), "with_median": float(np.median(on)),
            "without_median": float(np.median(off)), "calls": per_step, "pair": min(t_pair),
            "empty": min(t_empty)}


def print_call_record(map_file: str) -> None:
    r = call_record(map_file)
    w, wo = r["with"], r["without"]
    wm, wom = r["with_median"], r["without_median"]
    print(f"the FMU call record (core.fmucall), {r['calls']:.1f} recorded calls per step; "
          f"one master, 200-step stretches alternately with and without it (best, median):")
    print(f"  master loop with the record   : {1e6 * w:8.2f} {1e6 * wm:8.2f} us/step")
    print(f"  master loop, record emptied   : {1e6 * wo:8.2f} {1e6 * wom:8.2f} us/step")
    print(f"  difference                    : {1e6 * (w - wo):+8.2f} {1e6 * (wm - wom):+8.2f} "
          f"us/step ({100 * (w / wo - 1):+.1f} %, {100 * (wm / wom - 1):+.1f} %)")
    print(f"  begin/end pair {1e9 * r['pair']:.0f} ns, empty pair {1e9 * r['empty']:.0f} ns: "
          f"the record {1e9 * (r['pair'] - r['empty']):.0f} ns per call, "
          f"{1e6 * r['calls'] * (r['pair'] - r['empty']):.2f} us per step")


def log_tail_cost(repeats: int = 5) -> tuple[float, float, int]:
    """Best-of seconds per row of logging 5000 rows (stage + append, as the recorder does with
    estimators) without and with the tail file; and the row width."""
    from uwcosim.runlog import RunLogger

    width, flags = 80, 3  # the default scenario with the EKF: 79 columns and time, 3 flags
    rows = np.random.default_rng(0).normal(size=(STEPS, width))
    got = np.ones(flags, dtype=bool)
    best = {False: [], True: []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats):
            for tail in (False, True):
                log = RunLogger(Path(tmp) / f"log{i}{tail}.parquet",
                                [f"c{j}" for j in range(width - 1)], ["f0", "f1", "f2"], {},
                                1000, pending=64, tail=tail)
                a = time.perf_counter()
                for k in range(STEPS):
                    log.stage(k, rows[k], [True])
                    log.append(rows[k], got)
                log.close()
                best[tail].append((time.perf_counter() - a) / STEPS)
    return min(best[False]), min(best[True]), width


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--record", action="store_true", help="item 7 alone (the FMU call record)")
    if ap.parse_args().record:
        with tempfile.TemporaryDirectory() as tmp:
            map_file = str(synthetic_bathymetry(7).write_coefficients(Path(tmp) / "map.bin"))
            print_call_record(map_file)
        return
    with tempfile.TemporaryDirectory() as tmp:
        map_file = str(synthetic_bathymetry(7).write_coefficients(Path(tmp) / "map.bin"))
        raw, ours = [], []
        for _ in range(3):  # interleaved repetitions, best of three each
            raw.append(raw_fmpy_loop(map_file))
            ours.append(master_loop(map_file))
        a = time.perf_counter()
        dr_ekf = ['estimators={dead_reckoning={type="dead_reckoning"}, ekf={type="ekf"}}']
        res = run_scenario(load_scenario(SCENARIO, dr_ekf), Path(tmp) / "run", figures=False)
        demo = time.perf_counter() - a
        print_call_record(map_file)
    r, o = min(raw), min(ours)
    print(f"raw fmpy loop (3 FMUs)     : {1e6 * r:8.1f} us/step")
    print(f"uwcosim master (3 FMUs)    : {1e6 * o:8.1f} us/step   ratio {o / r:.2f} "
          f"(goal <= 1.25)")
    print(f"default scenario, 5000 steps with DR + EKF, logged: {demo:.2f} s (goal < 2 s)")
    for name, m in res.summary["estimators"].items():
        print(f"  {name:16s} {1e6 * m['time_per_step_s']:8.1f} us/step")
    f, o, n = bouncing_ball()
    print(f"BouncingBall ME 10 s, 0.01 s grid, rtol 1e-6 ({n} bounces in both):")
    print(f"  fmpy.simulate_fmu (CVode)  : {1e3 * f:8.1f} ms")
    print(f"  uwcosim master (CVode)     : {1e3 * o:8.1f} ms   ratio {o / f:.2f} (goal <= 2)")
    res = coupled_pair()
    x_exact = masses_exact(10.0)[0]
    tm, tl, tf = (res[k][0] for k in ("master", "loop", "fmpy"))
    print("two coupled ME masses (SpringMass x2), 10 s, 0.01 s grid, CVode rtol 1e-6:")
    for label, key in (("uwcosim master, one CVode", "master"),
                       ("minimal loop, one CVode", "loop"),
                       ("fmpy.simulate_fmu TwoMasses", "fmpy")):
        t, x = res[key]
        print(f"  {label:28s}: {1e3 * t:8.1f} ms   x_a(10) - exact = {x - x_exact:+.1e}")
    print(f"  ratio master / minimal loop {tm / tl:.2f}, master / fmpy (one FMU) {tm / tf:.2f} "
          f"(goal <= 1.5)")
    t_master, t_sim = fixed_cost()
    print(f"per-run fixed cost, plain CS run of two FMUs in process: master {1e3 * t_master:.1f} "
          f"ms, simulate stage {1e3 * t_sim:.1f} ms (goal < 20 ms)")
    off, on, width = log_tail_cost()
    print(f"log tail file ({width} columns, staged + appended): {1e6 * off:.2f} us/row without, "
          f"{1e6 * on:.2f} us/row with: +{1e6 * (on - off):.2f} us/step = "
          f"{100 * (on - off) / (demo / STEPS):.1f}% of the default scenario's "
          f"{1e6 * demo / STEPS:.0f} us/step of (3)")


if __name__ == "__main__":
    main()
