"""Do our PF-1000, Stone Soup's particle filter and `particles`' bootstrap filter agree? A
Monte Carlo over seeds of the TAN problem of ``bench_filters.py``.

One trajectory says little: a 1000-particle filter on this problem either locks onto the
terrain or keeps a wrong mode for a while, so the position RMSE of one run is heavy-tailed
(``--truth-seed 1``: the benchmark's own trajectory, only the filters' streams varying;
``docs/benchmarks.md``, "Particle filters over seeds"). Here run ``i = 1..--runs`` simulates
truth seed ``i``, and every filter starts from the same initial cloud
(``bench_filters.initial_cloud``) with its own stream seeded ``1000 + i``. The prior's draw
decides much of whether a filter locks, so the runs are paired: the per-run RMSEs (position,
second half of the run) of each library are compared with ours run by run:

- the mean of the paired differences (library - ours) with its Monte Carlo standard error
  ``se``; the tolerance is ``3 se`` (two-sided 0.3 % under the normal approximation):
  "equal" when the mean difference is inside it;
- the geometric-mean ratio ``exp(mean(log RMSE_lib - log RMSE_ours))``, less sensitive to the
  lost-lock tail, with the same 3-se rule on the log scale;
- each filter's mean (+- se), median, geometric mean, range and the share of runs under 5 m
  (locked),
  and the correlation of the paired log RMSEs (how much the shared cloud pairs them).

Every filter gets the same model and settings (``bench_filters.py``: ``Q = model.Q`` per 1 s
step, ``R = model.R``, the initial cloud, the model's terrain function, systematic resampling
when the ESS falls below N/2, no roughening: ``PF_SETTINGS``); ``tests/test_bench_pf_fairness.py``
checks that those are what each filter gets. What cannot be matched: the random streams after
the prior (ours a ``numpy.random.Generator``, the libraries numpy's global stream), `particles`'
estimate (the weighted mean before the next step's resampling; ours and Stone Soup's after
resampling) and Stone Soup's systematic resampler, which sorts the particles by weight before
its pass (the same expected copies per weight).

    OMP_NUM_THREADS=1 nice .venv/bin/python benchmarks/pf_agreement.py [--runs 20] [--steps 2000]
        [--truth-seed S]

About 5.5 s per run of 2000 steps on the shared 2-core machine (Stone Soup's about 3.5 s,
`particles`' 1.5 s, ours 0.3 s): the default 20 runs in under 2 min, 60 runs in 5.5 min.
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
            print(f"{lib} not installed ({bf.INSTALL[lib]}): its rows are left out")
            continue
        out[label] = make
    return out


def rmse(xs: np.ndarray, truth: np.ndarray) -> float:
    """Position RMSE over the second half of the run."""
    half = slice(len(truth) // 2, None)
    return float(np.sqrt(np.mean(np.sum((xs - truth)[half, :2] ** 2, axis=1))))


def monte_carlo(model, sim, jobs: dict, runs: int, truth_seed: int | None = None,
                verbose: bool = True) -> dict[str, np.ndarray]:
    """``label -> RMSE per run``: run ``i = 1..runs`` on truth seed ``i`` (or on ``truth_seed``
    every time: only the filters' streams vary), every filter from the same initial cloud and
    its own stream seeded ``1000 + i`` (``bench_filters.initial_cloud``)."""
    out: dict[str, list[float]] = {label: [] for label in jobs}
    t0 = time.perf_counter()
    fixed = sim(truth_seed) if truth_seed is not None else None
    for i in range(1, runs + 1):
        truth, zs, x0 = fixed if fixed is not None else sim(i)
        for label, make in jobs.items():
            _, xs = make(x0, 1000 + i)(zs)
            out[label].append(rmse(xs, truth))
        if verbose:
            print(f"  run {i:3d}: " + "  ".join(f"{v[-1]:7.2f}" for v in out.values())
                  + f"   ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    return {label: np.array(v) for label, v in out.items()}


def describe(r: np.ndarray) -> dict[str, float]:
    """Mean, its standard error, geometric mean, median, range, share locked."""
    return {"n": r.size, "mean": float(r.mean()), "se": float(r.std(ddof=1) / math.sqrt(r.size)),
            "gmean": float(np.exp(np.log(r).mean())), "median": float(np.median(r)),
            "min": float(r.min()), "max": float(r.max()), "locked": float(np.mean(r < LOCKED_M))}


def compare(ref: np.ndarray, other: np.ndarray) -> dict[str, float | bool]:
    """``other - ref``, run by run (paired): the mean difference and the geometric-mean ratio,
    each with its tolerance of ``Z_TOL`` standard errors of the paired mean and whether it
    holds; ``corr`` the correlation of the two filters' log RMSEs over the runs."""
    n = ref.size
    d, ld = other - ref, np.log(other) - np.log(ref)
    se, lse = d.std(ddof=1) / math.sqrt(n), ld.std(ddof=1) / math.sqrt(n)
    return {"diff": float(d.mean()), "tol": Z_TOL * se, "equal": abs(d.mean()) <= Z_TOL * se,
            "ratio": math.exp(ld.mean()), "ratio_lo": math.exp(-Z_TOL * lse),
            "ratio_hi": math.exp(Z_TOL * lse), "ratio_equal": abs(ld.mean()) <= Z_TOL * lse,
            "corr": float(np.corrcoef(np.log(ref), np.log(other))[0, 1])}


def report(results: dict[str, np.ndarray]) -> list[str]:
    """The table: per filter its statistics and the comparison with ours (the first)."""
    ref_label = next(iter(results))
    ref = results[ref_label]
    lines = [f"{'filter':26s} {'runs':>4s} {'mean m':>7s} {'+-se':>5s} {'median':>6s} "
             f"{'gmean':>5s} {'range':>12s} {'locked':>6s}  vs ours, paired: mean diff "
             f"(tol {Z_TOL:g} se); geometric-mean ratio (tol); corr"]
    for label, r in results.items():
        s = describe(r)
        row = (f"{label:26s} {s['n']:4d} {s['mean']:7.2f} {s['se']:5.2f} {s['median']:6.2f} "
               f"{s['gmean']:5.2f} {s['min']:5.2f}..{s['max']:5.2f} {s['locked']:6.0%}")
        if label != ref_label:
            c = compare(ref, r)
            row += (f"  {c['diff']:+6.2f} m (tol {c['tol']:.2f}): "
                    f"{'equal' if c['equal'] else 'DIFFERS'}; {c['ratio']:.2f} "
                    f"(tol {c['ratio_lo']:.2f}..{c['ratio_hi']:.2f}): "
                    f"{'equal' if c['ratio_equal'] else 'DIFFERS'}; {c['corr']:.2f}")
        lines.append(row)
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="truth seeds per library")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--truth-seed", type=int, default=None,
                    help="one trajectory for every run (only the filters' streams vary)")
    args = ap.parse_args()
    model, sim = problem(args.steps)
    jobs = filters(model, args.particles)
    what = ("truth seeds" if args.truth_seed is None else
            f"seeds of the filters' streams on truth seed {args.truth_seed}")
    print(f"particle filters over seeds: {args.runs} runs ({what}), {args.steps} steps, "
          f"{args.particles} particles; RMSE = position, second half")
    results = monte_carlo(model, sim, jobs, args.runs, args.truth_seed)
    print("\n".join(report(results)))


if __name__ == "__main__":
    main()
