"""The compiled kernels' on-disk cache is keyed by the sources of every kernel module.

Numba's cache index of a kernel follows its own file only: a kernel that inlines another
module's kernel loaded stale machine code after that module changed (and failed after
``small_linalg`` moved). :func:`uwcosim.core.jit.kernel_cache_dir` names one cache folder per
version of all kernel modules together.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from uwcosim.core import jit

KERNEL_MODULE = "from uwcosim.core.jit import jit\n\n@jit\ndef twice(x):\n    return 2 * x\n"


def test_the_folder_follows_every_kernel_module_and_nothing_else(tmp_path):
    (tmp_path / "sub").mkdir()
    inlined = tmp_path / "sub" / "inlined.py"
    caller = tmp_path / "caller.py"
    plain = tmp_path / "plain.py"
    inlined.write_text(KERNEL_MODULE)
    caller.write_text(KERNEL_MODULE.replace("twice", "thrice"))
    plain.write_text("X = 1\n")
    first = jit.kernel_cache_dir("0.61.0", tmp_path)
    assert first == jit.kernel_cache_dir("0.61.0", tmp_path)  # stable
    assert first.parent.name == "numba"
    plain.write_text("X = 2\n")  # no kernels: the same cache
    assert jit.kernel_cache_dir("0.61.0", tmp_path) == first
    inlined.write_text(KERNEL_MODULE.replace("2 * x", "3 * x"))  # a kernel another inlines
    second = jit.kernel_cache_dir("0.61.0", tmp_path)
    assert second != first
    assert jit.kernel_cache_dir("0.62.0", tmp_path) != second  # another Numba


@pytest.mark.skipif(not jit.ENABLED, reason="Numba not installed or disabled")
def test_a_kernel_is_cached_in_the_folder_of_its_sources(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    code = ("import numba, numpy as np\n"
            "from uwcosim.core import jit, reductions\n"
            "print(jit.kernel_cache_dir(numba.__version__))\n"
            "reductions.sum2(np.ones((3, 3)), False)\n"
            "print(numba.config.CACHE_DIR)\n")
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stderr
    folder, user_dir = res.stdout.split("\n")[:2]
    assert Path(folder).is_relative_to(tmp_path / "uwcosim" / "numba")
    assert any(Path(folder).rglob("*sum2*.nbi")), "the kernel was not cached there"
    assert user_dir == ""  # Numba's own setting is left as the user had it
