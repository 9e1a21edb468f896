"""Cost of the VB-AKF's partial update of ``U``: :func:`partial_iw_update` against the old
write-back (the observed block replaced, cross terms kept), side by side in one process.

    .venv/bin/python benchmarks/bench_vb_partial.py [--steps 3000] [--repeats 5]

Two rows per round, interleaved: the write-back alone on the current-navigation shape
(``m = 4``: a DVL pair observed, the two ranges not; ``U`` and the new block random SPD), and
a whole ``vbakf`` step (predict + update) on the seed 001 model with sensor A (components 0, 1)
every step and sensor B (2, 3) every 5th. For the filter the old rule runs on a seed where it
is not stopped (seed 3 of ``tests/test_vb_multirate.py``'s two-rate case over 60 steps,
repeated). Per row the best round's mean time per call is printed, and the ratio. BLAS
threads: 1.
"""

from __future__ import annotations

import argparse
import os
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def main(argv=None) -> int:
    import numpy as np

    from uwcosim.filters import variational
    from uwcosim.filters.numerics import symmetrize
    from uwcosim.models.linear import seed001_model

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)

    def old_rule(U, idx, U_oo):
        out = U.copy()
        out[np.ix_(idx, idx)] = U_oo
        return symmetrize(out)

    new_rule = variational.partial_iw_update
    rng = np.random.default_rng(0)
    A = rng.standard_normal((4, 4))
    U = A @ A.T + np.eye(4)
    B = rng.standard_normal((2, 2))
    U_oo = B @ B.T + np.eye(2)
    idx = np.array([0, 1])

    model = seed001_model()
    x0 = np.array([0.0, 1.0, 0.0, 0.5])
    srng = np.random.default_rng(3)
    zs = model.h(x0) + srng.standard_normal((60, 4))
    masks = [np.array([True, True, k % 5 == 0, k % 5 == 0]) for k in range(60)]

    def time_rule(rule):
        t0 = time.perf_counter()
        for _ in range(args.steps):
            rule(U, idx, U_oo)
        return (time.perf_counter() - t0) / args.steps

    def time_filter(rule):
        variational.partial_iw_update = rule
        try:
            done, t0 = 0, time.perf_counter()
            while done < args.steps:
                est = variational.VariationalBayesAKF(model, x0, np.eye(4))
                for k in range(60):
                    est.predict(None, 1.0)
                    est.update(np.where(masks[k], zs[k], np.nan), masks[k])
                done += 60
            return (time.perf_counter() - t0) / done
        finally:
            variational.partial_iw_update = new_rule

    best: dict[str, float] = {}
    rows = {"write-back, old": lambda: time_rule(old_rule),
            "write-back, partial_iw_update": lambda: time_rule(new_rule),
            "vbakf step, old write-back": lambda: time_filter(old_rule),
            "vbakf step, partial_iw_update": lambda: time_filter(new_rule)}
    for _ in range(args.repeats):
        for name, fn in rows.items():
            t = fn()
            best[name] = min(best.get(name, np.inf), t)
    for name, t in best.items():
        print(f"{name:32s} {t * 1e6:9.1f} us per call")
    print(f"write-back ratio new/old: "
          f"{best['write-back, partial_iw_update'] / best['write-back, old']:.2f}")
    print(f"vbakf step ratio new/old: "
          f"{best['vbakf step, partial_iw_update'] / best['vbakf step, old write-back']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
