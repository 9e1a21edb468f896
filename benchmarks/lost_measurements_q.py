"""Seed 001 with the paper's diagonal ``Q`` exactly: QIVBF variants against the KF that skips.

The campaign ``scenarios/campaigns/lost_measurements_variants.toml`` runs the truth through the
ConstantVelocity FMU with white noise held over each step, whose discrete ``Q`` has the paper's
diagonal ``1e-3 diag(1, 0.5, 1, 0.5)`` but also the off-diagonal ``q_v/2`` of a continuous
white-noise-acceleration model. This script runs the experiment without FMUs, truth and filters
on one discrete linear model, with either ``Q`` (``--q diagonal``: seed 001 Table 2 exactly,
:func:`uwcosim.models.linear.seed001_model`; ``--q wna``: the FMU's ``Q``; ``--q both``):
``x' = F x + w``, ``w ~ N(0, Q)``, ``z = x + v``, ``v ~ N(0, I)``, ``P0 = I``, ``x0 ~ N(0, I)``
around ``[0, 1, 0, 0.5]``, every measurement lost with probability ``a``. Runs are seeded
(``--seed``, run ``i`` uses ``seed + i`` for the truth, the same for every filter).

Mis-specified ``R`` (issue 25): ``--true-r r`` makes the truth's measurement noise ``v ~ N(0,
r I)`` while every filter keeps the nominal ``R = I`` (the case VB adaptation exists for);
a row ``kf_skip_true_r``, the skipping KF given the true ``R``, is added as the yardstick.

    .venv/bin/python benchmarks/lost_measurements_q.py [--runs 20] [--steps 1000] [--q both]
        [--a 0.1 0.3 0.5] [--true-r 1.0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from uwcosim.core.errors import FilterDivergence  # noqa: E402
from uwcosim.filters.base import ESTIMATORS  # noqa: E402
from uwcosim.models.linear import constant_velocity_model, seed001_model  # noqa: E402

ESTIMATORS_SPEC = {
    "kf_skip": ("kf", {}),
    "vbakf": ("vbakf", {}),
    "qivbf": ("qivbf", {}),
    "qivbf_isolated": ("qivbf", {"extrapolate": "isolated"}),
    "qivbf_inflated": ("qivbf", {"inflate_r": True}),
    "qivbf_iso_inflated": ("qivbf", {"extrapolate": "isolated", "inflate_r": True}),
    "qivbf_tau1": ("qivbf", {"tau": 1.0}),
    "qivbf_tau30": ("qivbf", {"tau": 30.0}),
}


def models(which: str):
    out = {}
    if which in ("diagonal", "both"):
        out["diagonal"] = seed001_model()
    if which in ("wna", "both"):
        out["wna"] = constant_velocity_model(q_psd=[0.875e-3, 0.5e-3, 0.875e-3, 0.5e-3])
    return out


def specs(true_r: float) -> dict:
    """The estimators; with a mis-specified ``R`` also the KF told the true ``R``."""
    if true_r == 1.0:
        return ESTIMATORS_SPEC
    return {**ESTIMATORS_SPEC, "kf_skip_true_r": ("kf", {})}


def one_run(model, a: float, steps: int, seed: int, true_r: float = 1.0):
    rng = np.random.default_rng(seed)
    x = np.array([0.0, 1.0, 0.0, 0.5])
    x0 = x + rng.standard_normal(4)
    LQ = np.linalg.cholesky(model.Q(x, None, 1.0))
    ests = {k: ESTIMATORS.get(t)(model, x0, np.eye(4), **kw)
            for k, (t, kw) in ESTIMATORS_SPEC.items()}
    if true_r != 1.0:
        told = constant_velocity_model(Q=model.Q(x, None, 1.0), R=true_r * np.eye(4))
        ests["kf_skip_true_r"] = ESTIMATORS.get("kf")(told, x0, np.eye(4))
    err = {k: [] for k in ests}
    nees = {k: [] for k in ests}
    dead = set()
    for k in range(steps):
        x = model.f(x, None, 1.0) + LQ @ rng.standard_normal(4)
        z = x + np.sqrt(true_r) * rng.standard_normal(4)  # v ~ N(0, r I)
        lost = rng.random() < a
        for name, e in ests.items():
            if name in dead:
                continue
            try:
                e.predict(None, 1.0)
                e.t = k + 1.0
                if lost:
                    e.update(np.full(4, np.nan), np.zeros(4, dtype=bool))
                else:
                    e.update(z)
            except FilterDivergence:
                dead.add(name)
                continue
            d = e.x - x
            err[name].append(d[[0, 2]] @ d[[0, 2]])
            nees[name].append(d @ np.linalg.solve(e.P, d))
    return ({k: float(np.sqrt(np.mean(v))) if k not in dead else np.nan for k, v in err.items()},
            {k: float(np.mean(v)) / 4 if k not in dead else np.nan for k, v in nees.items()})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=2020)
    ap.add_argument("--q", choices=("diagonal", "wna", "both"), default="both")
    ap.add_argument("--a", type=float, nargs="+", default=[0.1, 0.3, 0.5])
    ap.add_argument("--true-r", type=float, default=1.0,
                    help="variance of the truth's measurement noise (the filters keep R = I)")
    args = ap.parse_args()
    names = specs(args.true_r)
    print("| Q | a | estimator | pos. RMSE (m), mean ± sd | median | ANEES | diverged |")
    print("|---|---|---|---|---|---|---|")
    for qname, model in models(args.q).items():
        for a in args.a:
            rm = {k: [] for k in names}
            an = {k: [] for k in names}
            for i in range(args.runs):
                r, n = one_run(model, a, args.steps, args.seed + i, args.true_r)
                for k in names:
                    rm[k].append(r[k])
                    an[k].append(n[k])
            for k in names:
                v = np.array(rm[k])
                ok = np.isfinite(v)
                print(f"| {qname} | {a} | {k} | {np.mean(v[ok]):.2f} ± {np.std(v[ok]):.2f} | "
                      f"{np.median(v[ok]):.2f} | {np.nanmean(an[k]):.2f} | {int((~ok).sum())} |")


if __name__ == "__main__":
    main()
