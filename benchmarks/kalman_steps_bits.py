"""Whether two trees' Kalman steps give the same numbers: save, then compare.

Runs every Kalman filter (EKF, UKF, CKF, CUKF, dead reckoning), numpy and ``compiled = true``,
through ``predict`` and ``update`` over 1000 TAN steps (the synthetic map of seed 7, the
terrain row lost every third step, no data at all every 17th) and saves ``x``, ``P`` and the
NIS of every step; ``--compare`` reports, per filter and path, whether two such files are
identical bit for bit and their largest difference. Run it from each tree with that tree's
code first on the path::

    PYTHONPATH=OLD .venv/bin/python benchmarks/kalman_steps_bits.py --save old.npz
    .venv/bin/python benchmarks/kalman_steps_bits.py --save new.npz
    .venv/bin/python benchmarks/kalman_steps_bits.py --compare old.npz new.npz
"""

from __future__ import annotations

import argparse

import numpy as np

STD0 = np.array([30.0, 30.0, 0.05, 0.05])
START = np.array([2000.0, 18000.0, 0.5, 0.0])
KINDS = ["ekf", "ukf", "ckf", "cukf", "dead_reckoning"]


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 100 else 0.0])


def save(path: str, steps: int) -> None:
    import uwcosim
    from uwcosim.filters import kalman, sigma_point  # noqa: F401  (registers the filters)
    from uwcosim.filters.base import ESTIMATORS
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry
    from uwcosim.models.trajectory import simulate

    print(f"uwcosim from {uwcosim.__file__}")
    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7))
    rng = np.random.default_rng(3)
    _, _, zs = simulate(model.symbolic, START, controls, steps, rng)
    x0 = START + STD0 * rng.standard_normal(4)
    out = {}
    for kind in KINDS:
        for compiled in (False, True):
            est = ESTIMATORS.get(kind)(model, x0, np.diag(STD0**2), compiled=compiled)
            xs, Ps, nis = [], [], []
            for k, z in enumerate(zs):
                est.predict(controls(k), 1.0)
                mask = None if k % 3 else np.array([True, True, False])
                est.update(None if k % 17 == 5 else z, mask)
                xs.append(est.x.copy())
                Ps.append(est.P.copy())
                nis.append(est.diagnostics.get("nis", np.nan))
            key = f"{kind} {'compiled' if compiled else 'numpy'}"
            out[f"{key}/x"], out[f"{key}/P"], out[f"{key}/nis"] = map(np.array, (xs, Ps, nis))
    np.savez(path, **out)
    print(f"saved {len(out)} arrays to {path}")


def compare(a: str, b: str) -> None:
    A, B = np.load(a), np.load(b)
    for key in A.files:
        x, y = A[key], B[key]
        same = np.array_equal(x, y, equal_nan=True)
        print(f"{key:28s} {'identical' if same else 'DIFFERENT'}  largest difference "
              f"{np.nanmax(np.abs(x - y)):.1e}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--save", metavar="PATH")
    ap.add_argument("--compare", nargs=2, metavar=("A", "B"))
    ap.add_argument("--steps", type=int, default=1000)
    args = ap.parse_args()
    if args.save:
        save(args.save, args.steps)
    if args.compare:
        compare(*args.compare)


if __name__ == "__main__":
    main()
