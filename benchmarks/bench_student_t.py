"""Time per step of the grid filters with the Student-t likelihood: compiled against numpy steps.

    .venv/bin/python benchmarks/bench_student_t.py [--steps 500] [--repeats 5] [--nu 4]

The trajectory and filters of ``benchmarks/bench_projection.py`` (seed 000 eq. 54, synthetic
terrain of seed 3, 1 s steps), for PFM-PSI (``K = 10``) and the point mass (101 x 101), each
with the Gaussian likelihood and with ``student_t_nu = nu``, each by its compiled steps and by
its numpy steps (``use_kernels`` off), and the 1000-particle PF with both likelihoods (its
likelihood is numpy either way). Run ``--repeats`` times interleaved (one run of every row,
then the next round); per row the run with the best mean is kept and its median and mean time
per step (predict + update) printed, with the position RMSE, and for the Student-t rows the
largest difference of the compiled estimate from the numpy one over the run. BLAS threads: 1.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--nu", type=float, default=4.0, help="Student-t degrees of freedom")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    import numpy as np

    import uwcosim.filters  # noqa: F401  (registers the estimators)
    from uwcosim.core import jit
    from uwcosim.filters.base import ESTIMATORS
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry
    from uwcosim.models.trajectory import simulate, wandering_heading

    if not jit.ENABLED:
        print("compiled kernels are off (no Numba or UWCOSIM_NUMBA=0): nothing to compare")
        return 1
    model = tan_model([0.05, 0.05, 1e-4, 1e-4], 0.03, 2.0, terrain=synthetic_bathymetry(3))
    rng = np.random.default_rng(args.seed)
    x0 = np.array([3000.0, 16000.0, 0.5, 0.0])
    n = args.steps
    X, U, Z = simulate(model.symbolic, x0, wandering_heading(rng), n, rng, noise="held")
    P0 = np.diag([30.0**2, 30.0**2, 0.05**2, 0.05**2])
    xe0 = x0 + rng.standard_normal(4) * np.sqrt(np.diag(P0))

    t = {"student_t_nu": args.nu}
    rows = []  # (label, class, settings)
    for name, kw in (("pfm_psi", {"K": 10}), ("point_mass", {})):
        cls = ESTIMATORS.get(name)
        numpy_form = type(cls.__name__, (cls,), {"use_kernels": False})
        rows += [(f"{name} gaussian compiled", cls, kw),
                 (f"{name} student-t compiled", cls, {**kw, **t}),
                 (f"{name} student-t numpy", numpy_form, {**kw, **t}),
                 (f"{name} gaussian numpy", numpy_form, kw)]
    pf = ESTIMATORS.get("pf")
    rows += [("pf-1000 gaussian", pf, {"n_particles": 1000}),
             ("pf-1000 student-t", pf, {"n_particles": 1000, **t})]

    def run_once(cls, kw):
        est = cls.from_settings(model, xe0, P0, kw, rng=np.random.default_rng(0))
        times = np.empty(n)
        xs = np.empty((n, 4))
        for k in range(n):
            t0 = time.perf_counter()
            est.predict(U[k], 1.0)
            est.update(Z[k])
            times[k] = time.perf_counter() - t0
            xs[k] = est.x
        return times, xs, bool(getattr(est, "fast", False))

    for _, cls, kw in rows:  # warm-up (compiled kernels load, caches fill)
        run_once(cls, kw)
    best: dict = {}
    for _ in range(args.repeats):
        for label, cls, kw in rows:
            times, xs, fast = run_once(cls, kw)
            if label not in best or times.mean() < best[label][0].mean():
                best[label] = (times, xs, fast)
    print(f"TAN model, synthetic terrain, {n} steps of 1 s, nu = {args.nu:g}, best of "
          f"{args.repeats} interleaved runs, BLAS threads {os.environ['OPENBLAS_NUM_THREADS']}")
    print(f"{'filter':30s} {'fast':>5s} {'median ms':>10s} {'mean ms':>8s} {'RMSE m':>7s} "
          f"{'max |x - x_numpy|':>18s}")
    for label, (times, xs, fast) in best.items():
        rmse = float(np.sqrt(np.mean(np.sum((xs[:, :2] - X[1:, :2]) ** 2, axis=1))))
        diff = ""
        if "student-t compiled" in label:
            ref = best[label.replace("compiled", "numpy")][1]
            diff = f"{float(np.max(np.abs(xs - ref))):.1e}"
        print(f"{label:30s} {str(fast):>5s} {1e3 * np.median(times):10.3f} "
              f"{1e3 * times.mean():8.3f} {rmse:7.2f} {diff:>18s}")
    for name in ("pfm_psi", "point_mass"):
        med = {k: float(np.median(v[0])) for k, v in best.items() if k.startswith(name)}
        tc, tn = med[f"{name} student-t compiled"], med[f"{name} student-t numpy"]
        gc = med[f"{name} gaussian compiled"]
        print(f"{name}: student-t numpy / compiled = {tn / tc:.2f} (median); student-t "
              f"compiled / gaussian compiled = {tc / gc:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
