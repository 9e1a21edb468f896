"""Time per step of the filters on the TAN model (4 states, 3 measurements, synthetic map).

Compares our UKF with FilterPy's ``UnscentedKalmanFilter`` (same scaled sigma points
alpha = 1, beta = 2, kappa = 0; ``Q`` set every step like ours) fed either the model's CasADi
single-point functions (what a user plugs in) or our numpy per-point functions (which isolates
the algorithm's own overhead), and times the bootstrap PF with 1000 particles against its goal of
100 us per step. A step is ``predict`` + ``update`` + reading ``x`` and ``P``. Each filter runs
the same simulated trajectory; the best median of ``--repeats`` runs is reported (the median,
mean and 95th percentile of that run), so a noisy machine does not decide the ratios. The mean
matters for work done once every few steps (the PF draws its process noise for 64 steps at once
and resamples only when the ESS drops), which the median does not see.

    .venv/bin/python benchmarks/bench_filters.py [--steps 2000] [--repeats 3] [--numba]

``--numba`` imports Numba first, as a campaign with a grid filter (PFM-PSI, point mass) does:
the TAN model's terrain lookups then run compiled (:mod:`uwcosim.models.terrain_kernels`, the
same bits); without it they run in numpy, as in a scenario without grid filters.

FilterPy is a benchmark-only dependency (``pip install filterpy``).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from uwcosim.filters import particle, sigma_point, variational  # noqa: E402, F401
from uwcosim.filters.base import ESTIMATORS  # noqa: E402
from uwcosim.models.tan import tan_model  # noqa: E402
from uwcosim.models.terrain import synthetic_bathymetry  # noqa: E402
from uwcosim.models.trajectory import simulate as simulate_model  # noqa: E402

STD0 = np.array([30.0, 30.0, 0.05, 0.05])
START = np.array([2000.0, 18000.0, 0.5, 0.0])


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 200 else 0.0])


def simulate(model, steps: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    X, _, zs = simulate_model(model.symbolic, START, controls, steps, rng)
    xs = X[1:]
    return xs, zs, START + STD0 * rng.standard_normal(4)


def time_ours(name, model, zs, x0, settings):
    est = ESTIMATORS.get(name).from_settings(model, x0, np.diag(STD0**2), settings,
                                             rng=np.random.default_rng(1))  # pf's stream
    times = np.empty(len(zs))
    xs = np.empty((len(zs), 4))
    for k, z in enumerate(zs):
        u = controls(k)
        t0 = time.perf_counter()
        est.predict(u, 1.0)
        est.update(z)
        x, _ = est.x, est.P
        times[k] = time.perf_counter() - t0
        xs[k] = x
    return times, xs


def time_filterpy(model, zs, x0, fx1, hx1):
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    points = MerweScaledSigmaPoints(4, alpha=1.0, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(4, 3, 1.0, hx=hx1, fx=fx1, points=points)
    ukf.x = x0.copy()
    ukf.P = np.diag(STD0**2)
    ukf.R = model.R.copy()
    times = np.empty(len(zs))
    xs = np.empty((len(zs), 4))
    for k, z in enumerate(zs):
        u = controls(k)
        t0 = time.perf_counter()
        ukf.Q = model.Q(ukf.x, u, 1.0)
        ukf.predict(dt=1.0, u=u)
        ukf.update(z)
        x, _ = ukf.x, ukf.P
        times[k] = time.perf_counter() - t0
        xs[k] = x
    return times, xs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--numba", action="store_true",
                    help="import Numba first (compiled terrain lookups, as with grid filters)")
    args = ap.parse_args()
    if args.numba:
        import numba  # noqa: F401

    terrain = synthetic_bathymetry(7)
    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, terrain)
    fast = model  # the closed-form TAN model (its CasADi form is model.symbolic)
    truth, zs, x0 = simulate(model, args.steps)
    print(f"TAN model, {args.steps} steps, best of {args.repeats} interleaved runs; "
          f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}; "
          f"terrain lookups {'compiled' if 'numba' in sys.modules else 'numpy'}")

    jobs = {}
    for name, settings in (("ukf", {}), ("ckf", {}), ("cukf", {}), ("ekf", {}),
                           ("vbakf", {}), ("pf", {"n_particles": args.particles})):
        label = f"ours {name}" + (f"-{args.particles}" if name == "pf" else "")
        jobs[label] = lambda z, n=name, s=settings: time_ours(n, model, z, x0, s)
    try:
        import filterpy  # noqa: F401
    except ImportError:
        print("filterpy not installed (pip install filterpy): no comparison")
    else:
        jobs["filterpy ukf, casadi fx/hx"] = lambda z: time_filterpy(
            model, z, x0, lambda x, dt, u: model.f(x, u, dt), model.h)
        jobs["filterpy ukf, numpy fx/hx"] = lambda z: time_filterpy(
            model, z, x0, lambda x, dt, u: fast.f(x, u, dt), fast.h)

    for job in jobs.values():  # warm-up: caches, lazy imports, CPU clock
        job(zs[:200])
    results: dict[str, tuple] = {}
    for _ in range(args.repeats):
        for label, job in jobs.items():
            times, xs = job(zs)
            med = float(np.median(times)) * 1e6
            if label not in results or med < results[label][0]:
                results[label] = (med, float(np.percentile(times, 95)) * 1e6,
                                  float(np.mean(times)) * 1e6, xs)

    half = slice(args.steps // 2, None)
    print(f"\n{'filter':30s} {'median us':>10s} {'mean us':>10s} {'p95 us':>10s} "
          f"{'pos RMSE m (2nd half)':>22s}")
    for label, (med, p95, mean, xs) in results.items():
        e = (xs - truth)[half, :2]
        rm = np.sqrt(np.mean(np.sum(e**2, axis=1)))
        print(f"{label:30s} {med:10.1f} {mean:10.1f} {p95:10.1f} {rm:22.2f}")
    print("\ngoals")
    ukf = results["ours ukf"][0]
    for label, (med, *_) in results.items():
        if label.startswith("filterpy"):
            r = ukf / med
            print(f"  ours ukf / {label:27s} = {r:6.3f}     (goal <= 0.333: "
                  f"{'met' if r <= 1 / 3 else 'NOT met'})")
    pf, _, pf_mean, _ = results[f"ours pf-{args.particles}"]
    print(f"  ours pf-{args.particles} time per step {'':14s} = {pf:6.1f} us  (goal <= 100 us: "
          f"{'met' if pf <= 100 else 'NOT met'}; mean {pf_mean:.1f} us)")


if __name__ == "__main__":
    main()
