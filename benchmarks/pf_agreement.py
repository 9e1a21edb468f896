"""Do our PF-1000, Stone Soup's particle filter and `particles`' bootstrap filter agree? A
Monte Carlo over seeds of the TAN problem of ``bench_filters.py``.

One trajectory says little: a 1000-particle filter on this problem either locks onto the
terrain or keeps a wrong mode for a while, so the position RMSE of one run is heavy-tailed
(on the benchmark's trajectory, our PF-1000 with 40 seeds of its own stream gave 1.9 to 19.7 m;
``docs/benchmarks.md``, "Particle filters over seeds"). Here every filter runs ``--runs``
trajectories (truth seeds ``1..runs``, each filter's stream seeded ``1000 + truth seed``; ours,
ten times cheaper, ``--ours-factor`` times as many), and the per-run RMSEs (position, second half
of the run) are compared as distributions:

- the mean RMSE of each library minus ours, with the Monte Carlo standard error of that
  difference ``se = sqrt(se_lib^2 + se_ours^2)``; the tolerance is ``3 se`` (two-sided 0.3 %
  under the normal approximation): "equal" when the difference is inside it;
- the geometric-mean ratio ``exp(mean log RMSE_lib - mean log RMSE_ours)``, less sensitive to
  the lost-lock tail, with the same 3-se rule on the log scale;
- the median, and the share of runs under 5 m (locked).

Every filter gets the same model and settings (``bench_filters.py``: ``Q = model.Q`` per 1 s
step, ``R = model.R``, the prior ``N(x0, P0)``, the model's terrain function, systematic
resampling when the ESS falls below N/2, no roughening: ``PF_SETTINGS``);
``tests/test_bench_pf_fairness.py`` checks that those are what each filter gets. What cannot be
matched: the random streams (ours a ``numpy.random.Generator``, the libraries numpy's global
stream), `particles`' estimate (the weighted mean before the next step's resampling; ours and
Stone Soup's after resampling) and Stone Soup's systematic resampler, which sorts the particles
by weight before its pass (the same distribution of copies per weight).

    OMP_NUM_THREADS=1 nice .venv/bin/python benchmarks/pf_agreement.py [--runs 24] [--steps 1000]

About 5 s per truth seed on a loaded 2-core machine (Stone Soup's 2.5 s, `particles`' 1 s).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_filters as bf  # noqa: E402

Z_TOL = 3.0  # tolerance in Monte Carlo standard errors
LOCKED_M = 5.0  # a run whose RMSE is below this has locked onto the terrain


def problem(steps: int):
    """The benchmark's model and ``truth_seed -> (truth, zs, x0)`` (``bench_filters``)."""
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry

    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7))
    return model, lambda seed: bf.simulate(model, steps, seed=seed)


def filters(model, n_particles: int) -> dict:
    """``label -> make(x0, seed) -> job(zs)`` of the particle filters whose library is
    installed (ours always), terrain = the model's function."""
    terrain = bf.Terrain(model, "model")
    out = {f"ours pf-{n_particles}": lambda x0, seed: bf.ours(
        "pf", model, x0, {"n_particles": n_particles, **bf.PF_SETTINGS}, seed=seed)}
    for lib, label, make in (
            ("stonesoup", f"stonesoup pf-{n_particles}",
             lambda x0, seed: bf.stonesoup_job("pf", model, x0, terrain, n_particles, seed)),
            ("particles", f"particles bootstrap-{n_particles}",
             lambda x0, seed: bf.particles_job(model, x0, terrain, n_particles, seed))):
        try:
            __import__(lib)
        except ImportError:
            print(f"{lib} not installed (pip install -e .[bench]): its rows are left out")
            continue
        out[label] = make
    return out


def rmse(xs: np.ndarray, truth: np.ndarray) -> float:
    """Position RMSE over the second half of the run."""
    half = slice(len(truth) // 2, None)
    return float(np.sqrt(np.mean(np.sum((xs - truth)[half, :2] ** 2, axis=1))))


def monte_carlo(model, sim, jobs: dict, runs: int, ours_factor: int = 1,
                verbose: bool = True) -> dict[str, np.ndarray]:
    """``label -> RMSE per run``: truth seeds ``1..runs`` (``1..ours_factor * runs`` for the
    first label, ours), each filter's stream seeded ``1000 + truth seed``."""
    out: dict[str, list[float]] = {label: [] for label in jobs}
    first = next(iter(jobs))
    t0 = time.perf_counter()
    for seed in range(1, ours_factor * runs + 1):
        truth, zs, x0 = sim(seed)
        for label, make in jobs.items():
            if seed > runs and label != first:
                continue
            _, xs = make(x0, 1000 + seed)(zs)
            out[label].append(rmse(xs, truth))
        if verbose and (seed <= runs or seed % runs == 0):
            print(f"  seed {seed:4d}: " + "  ".join(f"{v[-1]:7.2f}" for v in out.values()
                                                    if len(v) == seed)
                  + f"   ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    return {label: np.array(v) for label, v in out.items()}


def describe(r: np.ndarray) -> dict[str, float]:
    """Mean, its standard error, mean log and its standard error, median, share locked."""
    n = r.size
    lr = np.log(r)
    return {"n": n, "mean": float(r.mean()), "se": float(r.std(ddof=1) / math.sqrt(n)),
            "lmean": float(lr.mean()), "lse": float(lr.std(ddof=1) / math.sqrt(n)),
            "median": float(np.median(r)), "locked": float(np.mean(r < LOCKED_M))}


def compare(ref: dict, other: dict) -> dict[str, float | bool]:
    """``other - ref``: mean difference and geometric-mean ratio, each with its ``Z_TOL``
    standard-error tolerance and whether it holds."""
    se = math.hypot(ref["se"], other["se"])
    lse = math.hypot(ref["lse"], other["lse"])
    d, ld = other["mean"] - ref["mean"], other["lmean"] - ref["lmean"]
    return {"diff": d, "tol": Z_TOL * se, "equal": abs(d) <= Z_TOL * se,
            "ratio": math.exp(ld), "ratio_lo": math.exp(-Z_TOL * lse),
            "ratio_hi": math.exp(Z_TOL * lse), "ratio_equal": abs(ld) <= Z_TOL * lse}


def report(results: dict[str, np.ndarray]) -> list[str]:
    """The table: per filter its statistics and the comparison with ours (the first)."""
    stats = {label: describe(r) for label, r in results.items()}
    ref_label = next(iter(stats))
    ref = stats[ref_label]
    lines = [f"{'filter':30s} {'runs':>4s} {'mean m':>7s} {'+-se':>6s} {'median':>7s} "
             f"{'gmean':>6s} {'locked':>6s}  vs ours: mean diff (tol {Z_TOL:g} se); "
             "geometric-mean ratio (tol)"]
    for label, s in stats.items():
        row = (f"{label:30s} {s['n']:4d} {s['mean']:7.2f} {s['se']:6.2f} {s['median']:7.2f} "
               f"{math.exp(s['lmean']):6.2f} {s['locked']:6.0%}")
        if label != ref_label:
            c = compare(ref, s)
            row += (f"  {c['diff']:+6.2f} m (tol {c['tol']:.2f}): "
                    f"{'equal' if c['equal'] else 'DIFFERS'}; {c['ratio']:.2f} "
                    f"(tol {c['ratio_lo']:.2f}..{c['ratio_hi']:.2f}): "
                    f"{'equal' if c['ratio_equal'] else 'DIFFERS'}")
        lines.append(row)
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=24, help="truth seeds per library")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--ours-factor", type=int, default=5,
                    help="ours runs this many times as many truth seeds")
    args = ap.parse_args()
    model, sim = problem(args.steps)
    jobs = filters(model, args.particles)
    print(f"particle filters over seeds: {args.runs} truth seeds per library "
          f"({args.ours_factor * args.runs} for ours), {args.steps} steps, "
          f"{args.particles} particles; RMSE = position, second half")
    results = monte_carlo(model, sim, jobs, args.runs, args.ours_factor)
    print("\n".join(report(results)))


if __name__ == "__main__":
    main()
