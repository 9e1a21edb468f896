"""Compiled kernels give the same bits whether compiled afresh or loaded from Numba's cache.

With fast-math, LLVM's result depended on how a kernel was compiled: a kernel compiled afresh
and the same kernel loaded from the on-disk cache differed in the last bits, so the same
scenario and seed gave different logs on a fresh machine. The kernels are IEEE (their sums in
a fixed order, see :mod:`uwcosim.core.reductions`); this test runs a short PFM-PSI, point-mass
and marginalized PF (``rbpf_kernels``) sequence in two processes sharing an initially empty
``NUMBA_CACHE_DIR``: the first compiles every kernel (cache misses only), the second loads
them (cache hits only), and the estimates must be identical bytes. (Checked to fail with the
fast-math kernels of commit a3a152a: the estimates of the two processes differed.)
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from uwcosim.core import jit

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="Numba not installed or disabled")

# writes the bytes of every estimate (x, P after each update) to argv[1]; prints the numbers
# of cache hits and misses of the kernels the filters called
_SCRIPT = r"""
import sys
import numpy as np
import uwcosim.filters  # noqa: F401  (registers the estimators)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.models.terrain import synthetic_bathymetry
from uwcosim.models.trajectory import simulate, wandering_heading
from uwcosim.models.tan import tan_model

model = tan_model([0.05, 0.05, 1e-4, 1e-4], 0.03, 2.0, terrain=synthetic_bathymetry(3))
rng = np.random.default_rng(7)
x0 = np.array([3000.0, 16000.0, 0.5, 0.0])
X, U, Z = simulate(model.symbolic, x0, wandering_heading(rng), 25, rng, noise="held")
P0 = np.diag([30.0**2, 30.0**2, 0.05**2, 0.05**2])
xe0 = x0 + rng.standard_normal(4) * np.sqrt(np.diag(P0))
out = []
for name, kw in (("pfm_psi", {"K": 10}), ("pfm_psi", {"K": 10, "k_sigma": 10.0}),
                 ("point_mass", {}), ("rbpf", {"n_particles": 500})):
    est = ESTIMATORS.get(name).from_settings(model, xe0, P0, kw,
                                             rng=np.random.default_rng(0))
    assert est.fast, name
    for k in range(len(U)):
        est.predict(U[k], 1.0)
        est.update(Z[k])
        out += [est.x.tobytes(), est.P.tobytes()]
with open(sys.argv[1], "wb") as f:
    f.write(b"".join(out))
hits = misses = 0
seen = set()
for mod in [m for n, m in list(sys.modules.items()) if n.startswith("uwcosim.")]:
    for value in vars(mod).values():  # every compiled kernel the binder bound
        stats = getattr(value, "stats", None)
        if stats is not None and id(value) not in seen and hasattr(stats, "cache_hits"):
            seen.add(id(value))
            hits += sum(stats.cache_hits.values())
            misses += sum(stats.cache_misses.values())
print(hits, misses)
"""


def _run(cache_dir, out_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), UWCOSIM_NUMBA="1",
               OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", _SCRIPT, str(out_path)], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    hits, misses = (int(v) for v in done.stdout.split()[-2:])
    return out_path.read_bytes(), hits, misses


def test_fresh_compile_and_cache_load_give_identical_estimates(tmp_path):
    cache = tmp_path / "numba_cache"
    cache.mkdir()
    fresh, hits0, misses0 = _run(cache, tmp_path / "fresh.bin")
    assert misses0 > 0 and hits0 == 0, (hits0, misses0)  # compiled afresh
    assert any(cache.rglob("*.nbi")), "the first run wrote no cache"
    loaded, hits1, misses1 = _run(cache, tmp_path / "loaded.bin")
    assert hits1 > 0 and misses1 == 0, (hits1, misses1)  # every kernel from the cache
    assert len(fresh) == 4 * 25 * (4 + 16) * 8
    assert fresh == loaded
