"""What a short ``uwcosim run`` of a Kalman-only scenario imports (issue 22, fast start): no
Numba (no compiled filter), no matplotlib (``--no-figures``), no pandas (the log is written from
Arrow buffers), no ``pyarrow.compute`` (loaded by a replay only), no module of a filter it does
not use (the built-in filters are declared in the registry and imported on first lookup), no
CasADi model builder. The time itself is measured in
``benchmarks/bench_startup.py``, not here; its count of the kernels a run loads is checked
here (the package it gives a cache file)."""

from __future__ import annotations

import hashlib
import importlib
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_PROBE = """
import sys
from uwcosim.cli import main
code = main(sys.argv[1:])
heavy = ("numba", "matplotlib", "pandas", "pyarrow.compute", "uwcosim.filters.sigma_point",
         "uwcosim.filters.particle", "uwcosim.filters.rbpf", "uwcosim.filters.point_mass",
         "uwcosim.filters.projection", "uwcosim.filters.grid", "uwcosim.models.symbolic",
         "scipy.fft", "scipy.sparse.linalg")
print(code, *[m for m in heavy if m in sys.modules])
"""


def test_a_kalman_run_without_figures_imports_none_of_the_heavy_optional_modules(tmp_path):
    cmd = [sys.executable, "-c", _PROBE, "-q", "run",
           str(ROOT / "scenarios" / "lost_measurements.toml"), "--set", "run.duration=10",
           "--no-figures", "--out", str(tmp_path / "run")]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split("\n")[-2].split() == ["0"], done.stdout[-500:]


def _bench():
    """``benchmarks/bench_startup.py`` as a module."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        return importlib.import_module("bench_startup")
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


def test_the_startup_bench_names_the_package_of_a_kernel_cache_file():
    """``bench_startup.py`` counts the kernels a run loads by package, from the folder that
    Numba names after the kernel module's folder (``<name>_<digest>``) in the kernel cache; a
    package whose name holds an underscore keeps it."""
    bench = _bench()
    source = ROOT / "uwcosim" / "filters" / "point_mass" / "bayes_kernels.py"
    # Numba's name for the folder of a module's cache files: its folder's name and digest
    folder = f"point_mass_{hashlib.sha1(str(source.parent).encode()).hexdigest()}"
    cached = Path("/cache/uwcosim/numba/abc") / folder / "bayes_kernels.update-419.py311.nbi"
    assert bench.cache_package(cached) == "point_mass"


def test_the_startup_bench_floor_imports_the_runs_third_party_modules_only(tmp_path):
    """The floor rows of ``bench_startup.py`` time what a run imports besides the standard
    library, uwcosim and Numba: the list taken from a real run's import trace holds numpy and
    scipy's modules and none of those; its command imports them and exits 0."""
    bench = _bench()
    mods = bench.third_party_modules(bench.run_cmd(
        str(ROOT / "scenarios" / "lost_measurements.toml"), tmp_path / "run"))
    tops = {m.split(".")[0] for m in mods}
    assert {"numpy", "scipy", "fmpy"} <= tops, sorted(tops)
    assert not tops & {"uwcosim", "numba", "llvmlite", "json", "os"}, sorted(tops)
    probe = "import sys\nexec(sys.argv[1])\nprint(sorted(m for m in {'numpy', 'uwcosim'} " \
            "if m in sys.modules))"
    code = bench.import_cmd(mods)[2]
    done = subprocess.run([sys.executable, "-c", probe, code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["['numpy']"], done.stdout
