"""The example package ``examples/current_nav`` for the tests (import this; not a conftest).

``example_fmus``: the example's truth FMUs (``CurrentVehicle``, ``BeaconRanger``) built from its
CasADi equations by ``uwcosim fmu build --spec`` in a subprocess (so that the builder's models of
this test process stay the project's), into ``examples/current_nav/fmus`` (incremental, not
committed), and the project's FMUs. ``uwcosim_env``: the environment of a ``uwcosim``
subprocess (this venv's ``bin`` on the ``PATH``). ``install_example``: the example installed
with ``pip install --no-deps --no-build-isolation --target`` (no network), its folder.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "current_nav"
SCENARIO = EXAMPLE / "scenario.toml"
BIN = Path(sys.executable).parent


def uwcosim_env(**extra: str) -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env.update(extra)
    return env


@pytest.fixture(scope="session")
def example_fmus(project_fmus) -> Path:
    subprocess.run([str(BIN / "uwcosim"), "fmu", "build", "--spec", "current_nav.fmus:specs",
                    "--out", "fmus"], cwd=EXAMPLE, env=uwcosim_env(), check=True,
                   capture_output=True)
    return EXAMPLE / "fmus"


def install_example(target: Path) -> Path:
    """``pip install`` the example package into ``target`` (its dist-info carries the entry
    points); no network: no dependencies, the venv's setuptools."""
    src = target.parent / "current_nav-src"  # a copy: pip builds in the source tree
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns(
        "fmus", "__pycache__", "build", "*.egg-info"))
    target.mkdir(parents=True, exist_ok=True)
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
         "--no-index", "--target", str(target), str(src)],
        capture_output=True, text=True, env=uwcosim_env())
    if proc.returncode != 0:
        pytest.fail(f"pip install of the example failed: {proc.stderr[-2000:]}")
    return target
