"""Where the filters reach the PCRB: RMSE(k) over runs of each filter against the bound(k).

Runs the first ``--runs`` runs of each variant of a campaign (default
``scenarios/campaigns/table1.toml``: the same seeds and overrides as the campaign's runs
``0..N-1``), computes the PCRB over the same truth runs (``uwcosim.run.bound``), and prints per
variant and filter the ratio ``RMSE(k) / PCRB(k)`` -- ``RMSE(k)`` the root of the mean over the
runs of the squared position error at step ``k`` -- as its root mean square over time windows
and over the whole run (steps 1..K), then, for the variant without terrain, the largest
relative difference between the EKF's variances and the bound (the same matrices, run by run).
With ``--figure DIR`` it draws ``pcrb_rmse_k_VARIANT.png`` there (log scale, the bound dashed).

    .venv/bin/python benchmarks/bound_rmse_k.py [--runs 20] [--figure docs/results/table1]

About 7 min for `--runs 20` (40 filter runs, 40 truth runs) on the loaded 2-core machine.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from uwcosim.campaign import load_campaign
from uwcosim.campaign.spec import run_seed
from uwcosim.run.bound import scenario_bound
from uwcosim.run.simulate import simulate
from uwcosim.runlog import columns, read_log
from uwcosim.scenario.load import load_scenario

ROOT = Path(__file__).resolve().parents[1]
WINDOWS = ((1, 100), (100, 500), (500, 1000), (1000, 2500), (2500, 5000))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaign", default=str(ROOT / "scenarios/campaigns/table1.toml"))
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--figure", default=None, help="folder for pcrb_rmse_k_VARIANT.png")
    args = ap.parse_args()
    campaign = load_campaign(args.campaign)
    seeds = [run_seed(campaign.spec.seed, i) for i in range(args.runs)]
    for v in campaign.spec.variants:
        loaded = load_scenario(campaign.resolve(v.scenario), v.set)
        bound = scenario_bound(loaded, args.runs, seed=campaign.spec.seed)
        names = list(loaded.spec.estimators)
        err2: dict[str, list[np.ndarray]] = {e: [] for e in names}
        worst_ekf = 0.0
        with tempfile.TemporaryDirectory() as tmp:
            for i, seed in enumerate(seeds):
                out = simulate(loaded, Path(tmp) / f"r{i}", seed=seed, evaluate=False)
                cols, _ = read_log(out / "log.parquet")
                for e in names:
                    err2[e].append(sum((cols[columns.estimate(e, s)] - cols[f"vehicle.{s}"])
                                       ** 2 for s in ("x", "y")))
                if v.name == "without_terrain" and "ekf" in names:
                    for j, s in enumerate(bound.states):
                        var = cols[columns.variance("ekf", s)]
                        d = np.max(np.abs(bound.std[:, j] ** 2 - var)) / np.max(var)
                        worst_ekf = max(worst_ekf, float(d))
        K = bound.t.size - 1
        print(f"\n{v.name}: {args.runs} runs, PCRB position {bound.position_m():.3f} m "
              f"(RMS over steps 1..{K})")
        heads = [f"{a}-{b} s" for a, b in WINDOWS if b <= K] + ["1..K"]
        print("| filter | " + " | ".join(f"RMSE/PCRB {h}" for h in heads) + " |")
        print("|---|" + "---|" * len(heads))
        curves = {}
        for e in names:
            rmse_k = np.sqrt(np.mean(err2[e], axis=0))  # RMSE(k) over the runs
            curves[e] = rmse_k
            ratios = []
            for a, b in [w for w in WINDOWS if w[1] <= K] + [(1, K + 1)]:
                r2 = np.mean(rmse_k[a:b] ** 2) / np.mean(bound.position[a:b] ** 2)
                ratios.append(f"{np.sqrt(r2):.2f}")
            print(f"| {e} | " + " | ".join(ratios) + " |")
        if v.name == "without_terrain":
            print(f"EKF variances against the bound: largest relative difference "
                  f"{worst_ekf:.1e} over the {args.runs} runs")
        if args.figure:
            _figure(bound, curves, v.name, Path(args.figure), args.runs)


def _figure(bound, curves, variant: str, folder: Path, runs: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=110)
    for e, c in curves.items():
        ax.plot(bound.t, c, lw=0.8, label=e)
    ax.plot(bound.t, bound.position, color="black", ls="--", lw=1.2, label="PCRB")
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position RMSE over runs (m)")
    ax.set_title(f"RMSE(k) over {runs} runs and the PCRB, {variant.replace('_', ' ')}")
    ax.legend(fontsize=8, ncol=3)
    fig.tight_layout()
    fig.savefig(folder / f"pcrb_rmse_k_{variant}.png")
    plt.close(fig)


if __name__ == "__main__":
    main()
