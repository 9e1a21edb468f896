"""Time per step of the marginalized (``rbpf``) and regularized (``rpf``) particle filters
against the bootstrap PF (``pf``), 1000 particles each, on the TAN model with terrain.

Goal (issue 14): RBPF-1000 no slower per step than PF-1000. The filters run the same simulated
trajectory in turn, ``--repeats`` times (interleaved, so a load change on the shared machine
hits all of them); for each filter the best median and best mean over the repeats are reported,
and the ratios to the PF come from the same run. A step is ``predict`` + ``update`` + reading
``x`` and ``P``.

    .venv/bin/python benchmarks/bench_rbpf.py [--steps 2000] [--repeats 5] [--particles 1000]

``--check-numpy SEEDS`` runs instead the RBPF with its compiled kernels and with its numpy code
side by side (trajectory and filter seeded by each seed in turn) and prints the largest
difference of their estimates and whether they resampled at the same steps.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from uwcosim.filters.base import ESTIMATORS  # noqa: E402
from uwcosim.models.tan import tan_model  # noqa: E402
from uwcosim.models.terrain import synthetic_bathymetry  # noqa: E402
from uwcosim.models.trajectory import simulate  # noqa: E402

STD0 = np.array([30.0, 30.0, 0.05, 0.05])
START = np.array([2000.0, 18000.0, 0.5, 0.0])


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 200 else 0.0])


def time_filter(name, settings, model, zs, x0, us) -> np.ndarray:
    est = ESTIMATORS.get(name).from_settings(model, x0, np.diag(STD0**2), settings,
                                             rng=np.random.default_rng(1))  # same stream
    times = np.empty(len(zs))
    for k, z in enumerate(zs):
        t0 = time.perf_counter()
        est.predict(us[k], 1.0)
        est.update(z)
        est.x, est.P  # noqa: B018  (the estimate is part of the step)
        times[k] = time.perf_counter() - t0
    return times


def check_numpy(model, steps: int, n: int, seeds: list[int]) -> None:
    """The compiled and the numpy RBPF on the same measurements and random stream."""
    for seed in seeds:
        rng = np.random.default_rng(seed)
        _, _, zs = simulate(model.symbolic, START, controls, steps, rng)
        x0 = START + STD0 * rng.standard_normal(4)
        fast, ref = (ESTIMATORS.get("rbpf").from_settings(
            model, x0, np.diag(STD0**2), {"n_particles": n}, rng=np.random.default_rng(seed))
            for _ in range(2))
        ref.fast = False
        worst, same, count = 0.0, True, 0
        for k in range(steps):
            for est in (fast, ref):
                est.predict(controls(k), 1.0)
                est.update(zs[k])
            same &= fast.diagnostics["resampled"] == ref.diagnostics["resampled"]
            count += int(ref.diagnostics["resampled"])
            worst = max(worst, float(np.abs(fast.x - ref.x).max()))
        print(f"seed {seed}: compiled (fast={fast.fast}) vs numpy, {steps} steps: max |dx| "
              f"{worst:.2g}, {count} resamplings, {'same' if same else 'DIFFERENT'} steps")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--check-numpy", type=int, nargs="+", metavar="SEED")
    args = ap.parse_args()
    model = tan_model([0.05, 0.05, 1e-5, 1e-5], 0.05, 1.0, synthetic_bathymetry(7))
    if args.check_numpy:
        check_numpy(model, args.steps, args.particles, args.check_numpy)
        return
    rng = np.random.default_rng(1)
    _, _, zs = simulate(model.symbolic, START, controls, args.steps, rng)
    x0 = START + STD0 * rng.standard_normal(4)
    us = [controls(k) for k in range(args.steps)]
    n = args.particles
    filters = {
        f"pf-{n}": ("pf", {"n_particles": n}),
        f"rbpf-{n}": ("rbpf", {"n_particles": n}),
        f"rpf-{n}": ("rpf", {"n_particles": n}),
        f"rpf-{n} shrink": ("rpf", {"n_particles": n, "shrink": True}),
    }
    best = {k: [np.inf, np.inf] for k in filters}
    for _ in range(args.repeats):
        for label, (name, settings) in filters.items():
            t = time_filter(name, settings, model, zs, x0, us)
            best[label][0] = min(best[label][0], float(np.median(t)))
            best[label][1] = min(best[label][1], float(np.mean(t)))
    base = best[f"pf-{n}"]
    print(f"# {platform.processor() or platform.machine()}, {args.steps} steps, "
          f"best of {args.repeats} interleaved repeats")
    print("| filter | median (us) | mean (us) | median / PF | mean / PF |")
    print("|---|---|---|---|---|")
    for label, (med, mean) in best.items():
        print(f"| {label} | {med * 1e6:.0f} | {mean * 1e6:.0f} | {med / base[0]:.2f} | "
              f"{mean / base[1]:.2f} |")


if __name__ == "__main__":
    main()
