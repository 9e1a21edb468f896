"""Distance of every filter's position posterior to an independent reference posterior (TAN).

Issue 14, item 4. The point-mass filter, our usual "reference", shares its position/velocity
split (a conditional velocity Kalman block, cross-covariance neglected) with PFM-PSI, so it is
not an independent exact posterior. The reference here shares none of that code: the
marginalized particle filter (:mod:`uwcosim.filters.rbpf`) with ``--reference-particles``
(10^5) particles, whose per-particle velocity Kalman filters are exact for this model (the
position-velocity correlation is kept). A second RBPF-10^5 with another seed is its check: the
distance between the two replicas is the Monte Carlo floor below which no difference means
anything. A plain bootstrap PF with 10^5 particles runs too (``PF-1e5``). It is not a safe
reference: when the initial velocity error is large, its first DVL update keeps a few hundred
distinct velocities, which the small velocity process noise cannot re-diversify: with
``--runs 1 --duration 100 --times 3 10 30 100`` (an initial velocity error of 2.8 sigma) it is
0.25-0.56 from the reference while the RBPF replica stays at 0.03 (docs/results/table1.md).

Set-up: the Table 1 terrain scenario's filter model (``scenarios/tan_terrain.toml``: process
PSD ``[0.05, 0.05, 1e-5, 1e-5]``, DVL 0.05 m/s, depth 1 m, the seeded synthetic map, the heading
and acceleration tables), truth simulated from that model without FMUs
(:func:`uwcosim.models.trajectory.simulate`), initial estimate drawn from ``N(truth, diag(30, 30,
0.05, 0.05)^2)`` once per run and shared by every filter. Run ``i`` uses seed ``--seed + i``.

At each snapshot time the position marginal ``p(x, y | z_1..k)`` of every filter is put on one
grid around the reference (161 x 161 points over +-6 reference standard deviations,
:mod:`uwcosim.evaluation.density`): a Gaussian for the Kalman-family filters, a kernel density
estimate (Silverman bandwidth) for particle filters, the filter's own interpolation for grid
filters; the Hellinger distance to the reference is reported (0 = identical, 1 = disjoint;
``TV <= sqrt(2) H``). ``floor-1000`` is the distance of a kernel density of 1000 exact draws from
the reference: what a perfect 1000-particle filter would score with this estimator.

Issue 25: the reference's resolution is a reported quantity. The reference is a kernel estimate
of the RBPF-10^5 cloud, whose Silverman bandwidth oversmooths multimodal posteriors, so the
distances are given for the reference's bandwidth scaled by each ``--bandwidth-factors`` (1,
1/2, 1/4: Silverman's, half, quarter). The two RBPF-10^5 replicas and the PF-10^5 are estimated
with the same factor (the replica's distance is the Monte Carlo floor *at that resolution*);
the 1000-particle filters keep their own Silverman bandwidth (their density estimate). The
distance keeps each density's mass outside the window (``hellinger(..., cell=...)``, counted
as disjoint); the original estimator (renormalized over the window, Silverman bandwidth) is
printed last so that the earlier table can be reproduced.

    .venv/bin/python benchmarks/reference_posterior.py [--runs 3] [--duration 1000]
        [--times 10 100 300 1000] [--reference-particles 100000] [--fine-grid 201]
        [--bandwidth-factors 1 0.5 0.25]
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from uwcosim.evaluation.density import (  # noqa: E402
    gaussian_on_grid,
    grid_around,
    particles_on_grid,
    silverman_bandwidth,
)
from uwcosim.evaluation.distance import hellinger  # noqa: E402
from uwcosim.filters.base import ESTIMATORS  # noqa: E402
from uwcosim.models.tan import tan_model  # noqa: E402
from uwcosim.models.terrain import synthetic_bathymetry  # noqa: E402
from uwcosim.models.trajectory import simulate  # noqa: E402

STD0 = np.array([30.0, 30.0, 0.05, 0.05])
FILTERS = {
    "EKF": ("ekf", {}),
    "UKF": ("ukf", {}),
    "PF-1000": ("pf", {"n_particles": 1000}),
    "RBPF-1000": ("rbpf", {"n_particles": 1000}),
    "RPF-1000 shrink": ("rpf", {"n_particles": 1000, "shrink": True}),
    "PFM-PSI K=10": ("pfm_psi", {"K": 10}),
    "point mass 101": ("point_mass", {}),
}


def filters(args) -> dict:
    out = dict(FILTERS)
    if args.fine_grid:
        out[f"point mass {args.fine_grid}"] = ("point_mass", {"n_points": args.fine_grid})
    return out


def scenario():
    """Model, controls and start of ``scenarios/tan_terrain.toml``."""
    spec = tomllib.loads((ROOT / "scenarios" / "tan_terrain.toml").read_text())
    m = spec["map"]
    bathy = synthetic_bathymetry(m["seed"], tuple(m["extent"]), m["resolution"])
    model = tan_model(spec["noise"]["process"]["psd"], spec["sensors"]["dvl"]["sigma"],
                      spec["sensors"]["depth"]["sigma"][0], bathy)
    psi = np.array(spec["controls"]["psi"]["table"], dtype=float)
    acc = np.array(spec["controls"]["a"]["table"], dtype=float)

    def controls(k: int) -> np.ndarray:
        t = float(k)
        return np.array([np.interp(t, psi[:, 0], psi[:, 1]), np.interp(t, acc[:, 0], acc[:, 1])])

    start = spec["fmus"]["vehicle"]["start"]
    return model, controls, np.array([start["x"], start["y"], start["vx"], start["vy"]])


#: estimators whose kernel bandwidth follows the reference's factor (the 10^5-particle clouds)
SCALED = ("RBPF-1e5 replica", "PF-1e5")


def distance(p: np.ndarray, q: np.ndarray, cell: float | None) -> float:
    """Hellinger distance (mass outside kept unless ``cell`` is None); 1 when either density
    has no mass on the grid (disjoint)."""
    if not (p.sum() > 0 and q.sum() > 0):
        return 1.0
    return hellinger(p, q, cell)


def kde(est, axes, factor: float = 1.0) -> np.ndarray:
    """Kernel estimate of a particle filter's position cloud, Silverman's bandwidth x factor."""
    X, w = est.particles[:2].T, est.weights
    return particles_on_grid(X, w, axes, bandwidth=factor * silverman_bandwidth(X, w))


def marginal(est, axes, factor: float = 1.0) -> np.ndarray:
    if hasattr(est, "particles"):
        return kde(est, axes, factor)
    if hasattr(est, "density_grid"):
        return est.density_grid(axes)[1]
    return gaussian_on_grid(est.x[:2], est.P[:2, :2], axes)


def floor(ref: np.ndarray, axes, n: int, rng, cell: float | None) -> float:
    p = ref.ravel() / ref.sum()
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)
    sp = np.array([a[1] - a[0] for a in axes])
    X = nodes[rng.choice(p.size, n, p=p)] + (rng.random((n, 2)) - 0.5) * sp
    return hellinger(ref, particles_on_grid(X, np.ones(n), axes), cell)


def snapshot(ref, ests: dict, factors, seed: int) -> dict:
    """Distances ``{(factor, kept): {label: H}}`` at one time; ``kept`` False is the original
    estimator (renormalized over the window), computed at factor 1 only."""
    axes = grid_around(ref.x[:2], ref.P[:2, :2])
    cell = float(np.prod([a[1] - a[0] for a in axes]))
    fixed = {label: marginal(e, axes) for label, e in ests.items() if label not in SCALED}
    out: dict = {}
    for c in factors:
        p_ref = kde(ref, axes, c)
        dens = {**fixed, **{lab: marginal(ests[lab], axes, c) for lab in SCALED}}
        for kept in (True, False) if c == 1.0 else (True,):
            cl = cell if kept else None
            row = {lab: distance(p_ref, dens[lab], cl) for lab in ests}
            row["floor-1000"] = floor(p_ref, axes, 1000, np.random.default_rng(seed), cl)
            out[c, kept] = row
    return out


def one_run(model, controls, start, args, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    _, _, zs = simulate(model.symbolic, start, controls, args.duration, rng)
    x0 = start + STD0 * rng.standard_normal(4)
    P0 = np.diag(STD0**2)
    n_ref = args.reference_particles
    ref = ESTIMATORS.get("rbpf")(model, x0, P0, n_particles=n_ref, seed=seed + 10_000)
    ests = {
        "RBPF-1e5 replica": ESTIMATORS.get("rbpf")(model, x0, P0, n_particles=n_ref,
                                                   seed=seed + 20_000),
        "PF-1e5": ESTIMATORS.get("pf")(model, x0, P0, n_particles=n_ref, seed=seed + 30_000),
    }
    for label, (name, kw) in filters(args).items():
        kw = dict(kw, seed=seed) if name in ("pf", "rbpf", "rpf") else kw
        ests[label] = ESTIMATORS.get(name)(model, x0, P0, **kw)
    out: dict = {}
    times = set(args.times)
    for k in range(args.duration):
        u = controls(k)
        for e in (ref, *ests.values()):
            e.predict(u, 1.0)
            e.t = k + 1.0
            e.update(zs[k])
        if k + 1 in times:
            out[k + 1] = snapshot(ref, ests, args.bandwidth_factors, seed)
            out[k + 1]["ref sd x, y (m)"] = tuple(np.sqrt(np.diag(ref.P)[:2]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--duration", type=int, default=1000)
    ap.add_argument("--times", type=int, nargs="+", default=[10, 100, 300, 1000])
    ap.add_argument("--reference-particles", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--fine-grid", type=int, default=0,
                    help="also run a point-mass filter with this many points per axis")
    ap.add_argument("--bandwidth-factors", type=float, nargs="+", default=[1.0, 0.5, 0.25],
                    help="the reference's kernel bandwidth as multiples of Silverman's")
    args = ap.parse_args()
    if 1.0 not in args.bandwidth_factors:
        args.bandwidth_factors.insert(0, 1.0)
    model, controls, start = scenario()
    t0 = time.perf_counter()
    rows = [one_run(model, controls, start, args, args.seed + i) for i in range(args.runs)]
    labels = ["RBPF-1e5 replica", "PF-1e5", *filters(args), "floor-1000"]
    print(f"Hellinger distance to the RBPF-{args.reference_particles} reference, mean (max) over "
          f"{args.runs} runs; {time.perf_counter() - t0:.0f} s")
    keys = [(c, True) for c in args.bandwidth_factors] + [(1.0, False)]
    for c, kept in keys:
        print(f"\nreference bandwidth = {c:g} x Silverman, mass outside the window "
              f"{'kept (disjoint)' if kept else 'dropped (renormalized; the original estimator)'}")
        print("| t (s) | " + " | ".join(labels) + " | ref sd x / y (m) |")
        print("|---" * (len(labels) + 2) + "|")
        for t in sorted(rows[0]):
            cells = []
            for lab in labels:
                v = np.array([r[t][c, kept][lab] for r in rows])
                cells.append(f"{v.mean():.2f} ({v.max():.2f})")
            sd = np.mean([r[t]["ref sd x, y (m)"] for r in rows], axis=0)
            print(f"| {t} | " + " | ".join(cells) + f" | {sd[0]:.1f} / {sd[1]:.1f} |")


if __name__ == "__main__":
    main()
