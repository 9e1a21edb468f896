"""Build the event test FMUs of ``tests/data/event_fmus`` (import this; it is not a conftest).

Small FMUs written for uwcosim in C (see ``tests/data/event_fmus/README.md`` for their
equations and events): BouncingBall (state events), Stair (time events, Integer output,
termination), TypedBlock (every FMI variable type, a discrete input), Feedthrough (direct
feed-through). Each as ``<Model>_fmi2.fmu`` and ``<Model>_fmi3.fmu``, both with Co-Simulation and
Model Exchange, built once per session with CMake against fmpy's FMI headers into a temporary
folder (never committed). A missing cmake skips the tests that use them.

Use the session fixture ``event_fmus`` (``{(model, "2.0" | "3.0"): Path}``) or, once it has run,
``event_fmu(model, version)``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EVENT_FMUS_DIR = Path(__file__).resolve().parent / "data" / "event_fmus"
MODELS = tuple(sorted(p.parent.name for p in EVENT_FMUS_DIR.glob("*/model.c")))
VERSIONS = ("2.0", "3.0")


def build_event_fmus(out: Path) -> dict[tuple[str, str], Path]:
    """Configure and build every model for FMI 2.0 and 3.0 into ``out``; return their paths."""
    import fmpy

    # the venv's cmake (pip package) first, then the system's
    cmake = shutil.which("cmake", path=str(Path(sys.executable).parent)) or shutil.which("cmake")
    if cmake is None:
        pytest.skip("cmake is not installed")
    out.mkdir(parents=True, exist_ok=True)
    headers = Path(fmpy.__file__).parent / "c-code"
    build = out / "build"
    for cmd in ([cmake, "-S", str(EVENT_FMUS_DIR), "-B", str(build), f"-DFMI_HEADERS={headers}",
                 f"-DFMU_DIR={out}", f"-DFMI2_PLATFORM={fmpy.platform}",
                 f"-DFMI3_PLATFORM={fmpy.platform_tuple}", "-DCMAKE_BUILD_TYPE=Release"],
                [cmake, "--build", str(build), "--config", "Release", "--parallel", "2"]):
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stdout + r.stderr
    fmus = {(m, v): out / f"{m}_fmi{v[0]}.fmu" for m in MODELS for v in VERSIONS}
    missing = [str(p) for p in fmus.values() if not p.is_file()]
    assert not missing, f"the build did not produce {missing}"
    return fmus


_BUILT: dict[tuple[str, str], Path] = {}


@pytest.fixture(scope="session")
def event_fmus(tmp_path_factory) -> dict[tuple[str, str], Path]:
    """``{(model, "2.0" | "3.0"): path of the .fmu}`` for every event test FMU."""
    if not _BUILT:
        _BUILT.update(build_event_fmus(tmp_path_factory.mktemp("event_fmus")))
    return dict(_BUILT)


def event_fmu(model: str, version: str) -> Path:
    """Path of one built event test FMU (``version`` "2.0"/"3.0", or "2"/"3")."""
    key = (model, version if "." in version else f"{version}.0")
    if not _BUILT:
        raise RuntimeError("the event test FMUs are not built yet: request the event_fmus fixture")
    if key not in _BUILT:
        raise KeyError(f"no event test FMU {key}; there are {sorted(_BUILT)}")
    return _BUILT[key]
