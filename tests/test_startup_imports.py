"""What a short ``uwcosim run`` of a Kalman-only scenario imports (issue 22, fast start): no
Numba (no compiled filter), no matplotlib (``--no-figures``), no pandas (the log is written from
Arrow buffers), no ``pyarrow.compute`` (loaded by a replay only). The time itself is measured in
``benchmarks/bench_startup.py``, not here."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_PROBE = """
import sys
from uwcosim.cli import main
code = main(sys.argv[1:])
heavy = ("numba", "matplotlib", "pandas", "pyarrow.compute")
print(code, *[m for m in heavy if m in sys.modules])
"""


def test_a_kalman_run_without_figures_imports_none_of_the_heavy_optional_modules(tmp_path):
    cmd = [sys.executable, "-c", _PROBE, "-q", "run",
           str(ROOT / "scenarios" / "lost_measurements.toml"), "--set", "run.duration=10",
           "--no-figures", "--out", str(tmp_path / "run")]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split("\n")[-2].split() == ["0"], done.stdout[-500:]
