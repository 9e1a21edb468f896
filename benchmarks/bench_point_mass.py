"""Where the point-mass filter's step goes: per-kernel timers (or cProfile) in the loop of
``bench_projection.py`` (TAN model, synthetic terrain, 101 x 101 grid, one BLAS thread).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_point_mass.py [--steps 500] [--profile]

Each compiled kernel, FFT and Python method of the step is wrapped in a timer (about 0.3 us of
overhead per wrapped call, so the parts add up to a little more than the unwrapped step); the
table gives the median per step over the last of ``--repeats`` runs. The FFTs are timed
where this tree calls them (``FFTPlan.forward``/``inverse``).
``--profile``: cProfile of one run instead (sorted by own time).
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# (module, kernel): the compiled kernels of the point mass's step, called through their module
KERNELS = (("uwcosim.filters.point_mass.prediction_kernels", "grid_shift"),
           ("uwcosim.filters.point_mass.prediction_kernels", "gauss_prefilter"),
           ("uwcosim.filters.point_mass.prediction_kernels", "finish"),
           ("uwcosim.filters.point_mass.bayes_kernels", "terrain_exponent"),
           ("uwcosim.filters.point_mass.bayes_kernels", "grid_product_moments"),
           ("uwcosim.filters.grid.conditional_kernels", "kalman_increment"),
           ("uwcosim.filters.grid.conditional_kernels", "kalman_update"),
           ("uwcosim.filters.grid.conditional_kernels", "assemble"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--profile", action="store_true", help="cProfile instead of timers")
    args = ap.parse_args(argv)

    import importlib

    import numpy as np

    import uwcosim.filters  # noqa: F401  (registers the estimators)
    from uwcosim.filters.base import ESTIMATORS
    from uwcosim.filters.grid import conditional
    from uwcosim.filters.point_mass import fft, prediction_kernels
    from uwcosim.models.tan import tan_model
    from uwcosim.models.terrain import synthetic_bathymetry
    from uwcosim.models.trajectory import simulate, wandering_heading

    model = tan_model([0.05, 0.05, 1e-4, 1e-4], 0.03, 2.0, terrain=synthetic_bathymetry(3))
    rng = np.random.default_rng(1)  # as bench_projection.py
    x0 = np.array([3000.0, 16000.0, 0.5, 0.0])
    n = args.steps
    X, U, Z = simulate(model.symbolic, x0, wandering_heading(rng), n, rng, noise="held")
    P0 = np.diag([30.0**2, 30.0**2, 0.05**2, 0.05**2])
    xe0 = x0 + rng.standard_normal(4) * np.sqrt(np.diag(P0))
    cls = ESTIMATORS.get("point_mass")

    def run():
        est = cls.from_settings(model, xe0, P0, {}, rng=np.random.default_rng(0))
        times = np.empty(n)
        for k in range(n):
            t0 = time.perf_counter()
            est.predict(U[k], 1.0)
            est.update(Z[k])
            times[k] = time.perf_counter() - t0
        return times

    run()  # warm-up: kernels loaded, caches filled
    if args.profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.runcall(run)
        pstats.Stats(prof).sort_stats("tottime").print_stats(25)
        return 0

    acc: dict[str, list[float]] = {}

    def wrap(owner, name, label=None):
        fn = getattr(owner, name)
        label = label or name

        @functools.wraps(fn)
        def timed(*a, **kw):
            t0 = time.perf_counter()
            out = fn(*a, **kw)
            acc.setdefault(label, []).append(time.perf_counter() - t0)
            return out

        setattr(owner, name, timed)

    for module, name in KERNELS:
        wrap(importlib.import_module(module), name)
    wrap(fft.FFTPlan, "forward", "FFT forward")
    wrap(fft.FFTPlan, "inverse", "FFT inverse")
    wrap(conditional.CompiledConditionalKalman, "increment", "Kalman increment (all)")
    wrap(prediction_kernels.CompiledPrediction, "shift", "prediction on the grid (all)")
    wrap(cls, "predict", "predict (all)")
    wrap(cls, "update", "update (all)")
    for _ in range(args.repeats):
        acc.clear()
        times = run()
    print(f"point mass 101 x 101, {n} steps: median {1e6 * np.median(times):.1f} us/step "
          f"(timers included)")
    for label, v in acc.items():
        print(f"  {label:32s} {1e6 * np.median(v):7.1f} us  ({len(v) / n:.0f} per step)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
