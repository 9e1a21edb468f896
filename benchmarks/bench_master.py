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

Goals: (2) at most 1.25x (1); (3) under 2 s; (4) at most 2x fmpy.
Run: ``.venv/bin/python benchmarks/bench_master.py``.
"""

from __future__ import annotations

import sys
import tempfile
import time
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


def main() -> None:
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


if __name__ == "__main__":
    main()
