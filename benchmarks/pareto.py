"""Accuracy against CPU time per step of the terrain-navigation filter families (a Pareto plot).

Issue 25, section 4. Families and their size parameter: the bootstrap PF (particles 100 -
10^4), the point-mass filter (grid points per axis 51 - 201) and PFM-PSI (harmonics per
dimension K = 6 - 16); EKF and UKF as single points. Every configuration runs on the same runs:
the Table 1 terrain scenario's filter model, map and controls (``scenarios/tan_terrain.toml``),
truth simulated from that model without FMUs (:func:`uwcosim.models.trajectory.simulate`),
initial estimate drawn from ``N(truth, diag(30, 30, 0.05, 0.05)^2)`` once per run and shared by
every filter; run ``i`` uses seed ``--seed + i``. Within each step the filters take turns, so a
change of the machine's load falls on all of them alike.

Reported per configuration: the mean over runs of each run's position RMSE (seed 000 eq. 56,
steps 1..K), the median over runs of the mean CPU time per step (``time.process_time`` around
predict + update, one thread, after a 30-step warm-up run that compiles the kernels), and the
number of runs that lost the track (:func:`uwcosim.evaluation.trackloss.track_loss`; a filter
that raised a divergence is lost and left out of the RMSE). The figure (``--figure``) is mean
RMSE against time per step, one line per family.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/pareto.py [--runs 4] [--duration 1000]
        [--figure docs/results/table1/pareto.png]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from reference_posterior import STD0, scenario  # noqa: E402

from uwcosim.core.errors import FilterDivergence  # noqa: E402
from uwcosim.evaluation.trackloss import track_loss  # noqa: E402
from uwcosim.filters.base import ESTIMATORS  # noqa: E402
from uwcosim.models.trajectory import simulate  # noqa: E402

#: (family, size label, estimator type, settings)
CONFIGS = [
    *[("PF", n, "pf", {"n_particles": n}) for n in (100, 300, 1000, 3000, 10_000)],
    *[("point mass", n, "point_mass", {"n_points": n}) for n in (51, 76, 101, 151, 201)],
    *[("PFM-PSI", k, "pfm_psi", {"K": k}) for k in (6, 8, 10, 12, 16)],
    ("EKF", "", "ekf", {}),
    ("UKF", "", "ukf", {}),
]


def one_run(model, controls, start, duration: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    xs, _, zs = simulate(model.symbolic, start, controls, duration, rng)
    x0 = start + STD0 * rng.standard_normal(4)
    P0 = np.diag(STD0**2)
    ests, cpu, err, var = {}, {}, {}, {}
    for fam, size, name, kw in CONFIGS:
        kw = dict(kw, seed=seed) if name == "pf" else kw
        ests[fam, size] = ESTIMATORS.get(name)(model, x0, P0, **kw)
        cpu[fam, size], err[fam, size], var[fam, size] = 0.0, [], []
    dead: set = set()
    for k in range(duration):
        u = controls(k)
        for key, e in ests.items():
            if key in dead:
                err[key].append([np.nan, np.nan])
                var[key].append([np.nan, np.nan])
                continue
            c0 = time.process_time()
            try:
                e.predict(u, 1.0)
                e.t = k + 1.0
                e.update(zs[k])
            except FilterDivergence:
                dead.add(key)
            cpu[key] += time.process_time() - c0
            err[key].append(e.x[:2] - xs[k + 1][:2] if key not in dead else [np.nan, np.nan])
            var[key].append(np.diag(e.P)[:2] if key not in dead else [np.nan, np.nan])
    t = np.arange(1.0, duration + 1.0)
    out = {}
    for key in ests:
        E = np.asarray(err[key], float)
        rmse = float(np.sqrt(np.mean(np.sum(E**2, axis=1)))) if key not in dead else np.nan
        lost = track_loss(t, E, np.asarray(var[key], float))["track_lost"]
        out[key] = (rmse, cpu[key] / duration, lost)
    return out


def figure(rows: dict, path: Path) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for fam, marker in (("PF", "o"), ("point mass", "s"), ("PFM-PSI", "^"), ("EKF", "x"),
                        ("UKF", "+")):
        pts = [(v[1], v[0], size) for (f, size), v in rows.items() if f == fam]
        tt, rr, ss = zip(*pts, strict=True)
        ax.plot(np.array(tt) * 1e3, rr, marker=marker, label=fam)
        for x, y, s in pts:
            if s != "":
                ax.annotate(str(s), (x * 1e3, y), textcoords="offset points", xytext=(4, 3),
                            fontsize=7)
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xticks([0.05, 0.1, 0.2, 0.5, 1.0])
    ax.set_xlabel("CPU time per step (ms, median over runs)")
    ax.set_ylabel("position RMSE (m, mean over runs)")
    ax.set_title("Accuracy against cost, terrain navigation (labels: N, points/axis, K)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--duration", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--figure", type=Path, default=None)
    args = ap.parse_args()
    model, controls, start = scenario()
    one_run(model, controls, start, 30, args.seed)  # warm-up: compiled kernels, caches
    t0 = time.perf_counter()
    runs = [one_run(model, controls, start, args.duration, args.seed + i)
            for i in range(args.runs)]
    rows = {}
    print(f"{args.runs} runs of {args.duration} s, seeds {args.seed}-{args.seed + args.runs - 1};"
          f" {time.perf_counter() - t0:.0f} s")
    print("| family | size | pos. RMSE (m), mean ± sd over runs | CPU ms per step (median) "
          "| lost track |")
    print("|---|---|---|---|---|")
    for key in runs[0]:
        r = np.array([run[key][0] for run in runs])
        c = np.array([run[key][1] for run in runs])
        lost = sum(run[key][2] for run in runs)
        ok = np.isfinite(r)
        rows[key] = (float(np.mean(r[ok])) if ok.any() else np.nan, float(np.median(c)))
        print(f"| {key[0]} | {key[1]} | {np.mean(r[ok]):.2f} ± {np.std(r[ok]):.2f} | "
              f"{np.median(c) * 1e3:.2f} | {lost}/{len(runs)} |")
    if args.figure:
        figure(rows, args.figure)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
