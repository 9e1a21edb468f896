"""What one compiled EKF step costs, call by call: the filter's step, the kernel through Numba's
dispatcher, the kernel's entry point, a no-op kernel of the same signature, the kernel in a
compiled loop.

The TAN truth and filter of ``bench_filters.py`` (2000 steps, the synthetic map of seed 7). Each
row times one call per step, in the step loop of ``bench_filters.py`` (``perf_counter`` around
the call, the step's ``u`` and ``z`` fresh from the data), median over the steps, best of
``--repeats`` interleaved runs; the compiled-loop row is one call over all steps divided by
their number. Every row but the no-ops computes the same steps from the same state, so their
differences are what the calling costs:

- ``est.step``: the filter's step, the estimator bank's one call (:mod:`uwcosim.filters.kalman`:
  the argument checks, the entry point, the diagnostics);
- ``kernel (dispatcher)``: ``kalman_kernels.ekf_step(ws, table, u, dt, z, mask)``, Numba's
  dispatcher typing the six arguments at every call;
- ``kernel (entry point)``: the same kernel's compiled entry point for those types
  (:func:`uwcosim.core.jit.entry_point`, what the step calls);
- ``no-op (dispatcher | entry point)``: a kernel of the same signature returning the same four
  results at once: the call alone; ``equal dtype``: the workspace viewed through a copy of its
  dtype object (what every workspace had before :func:`uwcosim.filters.kalman_kernels.
  workspace_dtype` shared one per layout): the dispatcher finds its cached type of the
  structured array after numpy compares the two dtypes field by field;
- ``kernel (compiled loop)``: the kernel called from a Numba loop over the steps, no Python
  between the steps.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/kalman_call.py [--steps 2000] [--repeats 7]
"""

from __future__ import annotations

import argparse
import pickle
import time

import numba
import numpy as np
from bench_filters import controls, ours_filter, simulate

from uwcosim.core import jit
from uwcosim.filters import kalman_kernels
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry


@numba.njit(nogil=True, error_model="numpy")
def no_op(ws, table, u, dt, z, mask):
    return 0, 0.0, 0.0, 0.0


def per_step(us, zs, call) -> np.ndarray:
    """Seconds of ``call(u, z)`` at each step."""
    times = np.empty(len(zs))
    for k in range(len(zs)):
        u, z = us[k], zs[k]
        t0 = time.perf_counter()
        call(u, z)
        times[k] = time.perf_counter() - t0
    return times


def fresh(model, x0):
    """A compiled EKF after its first step, and its workspace (``x``, ``P`` in it)."""
    est = ours_filter("ekf", model, x0, {"compiled": True})
    est.step(controls(0), 1.0, None)
    return est, est.workspace


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, synthetic_bathymetry(7))
    _, zs, x0 = simulate(model, args.steps)
    zs = [np.array(z) for z in zs]
    us = [controls(k) for k in range(len(zs))]
    U, Z = np.array(us), np.array(zs)
    kernel = jit.bound(kalman_kernels.ekf_step)

    @numba.njit(nogil=True, error_model="numpy")
    def loop(ws, table, U, Z, mask):
        for k in range(Z.shape[0]):
            kernel(ws, table, U[k], 1.0, Z[k], mask)

    def job_step():
        est, _ = fresh(model, x0)
        return per_step(us, zs, lambda u, z: est.step(u, 1.0, z))

    def job_kernel(entry: bool, body=kernel, equal_dtype: bool = False):
        def job():
            _, w = fresh(model, x0)
            ws, table, mask = w.ws, w.table, w.everything
            if equal_dtype:  # the same layout in a dtype object of its own
                ws = ws.view(pickle.loads(pickle.dumps(ws.dtype)))
                assert ws.dtype == w.ws.dtype and ws.dtype is not w.ws.dtype
            call = jit.entry_point(body, (ws, table, us[0], 1.0, zs[0], mask)) if entry else body
            return per_step(us, zs, lambda u, z: call(ws, table, u, 1.0, z, mask))
        return job

    def job_loop():
        _, w = fresh(model, x0)
        t0 = time.perf_counter()
        loop(w.ws, w.table, U, Z, w.everything)
        return np.array([(time.perf_counter() - t0) / len(zs)])

    jobs = {"est.step": job_step,
            "kernel (dispatcher)": job_kernel(False),
            "kernel (entry point)": job_kernel(True),
            "no-op (dispatcher)": job_kernel(False, no_op),
            "no-op (entry point)": job_kernel(True, no_op),
            "no-op (dispatcher), equal dtype": job_kernel(False, no_op, True),
            "kernel (compiled loop)": job_loop}
    for job in jobs.values():  # warm-up: compile the loop and the no-op, load the kernels
        job()
    best: dict[str, float] = {}
    for _ in range(args.repeats):
        for label, job in jobs.items():
            med = float(np.median(job())) * 1e6
            best[label] = min(med, best.get(label, np.inf))
    print(f"compiled EKF, TAN model, {len(zs)} steps, best of {args.repeats} interleaved runs "
          f"(Numba {numba.__version__})")
    print(f"{'call':34s} {'median us':>10s}")
    for label, med in best.items():
        print(f"{label:34s} {med:10.2f}")
    kernel_gain = best["kernel (dispatcher)"] - best["kernel (entry point)"]
    no_op_gain = best["no-op (dispatcher)"] - best["no-op (entry point)"]
    print(f"\ndispatcher - entry point: kernel {kernel_gain:.2f} us, no-op {no_op_gain:.2f} us")


if __name__ == "__main__":
    main()
