"""Build the event test FMUs of ``tests/data/event_fmus`` (import this; it is not a conftest).

Small FMUs written for uwcosim in C (see ``tests/data/event_fmus/README.md`` for their
equations and events): BouncingBall (state events), Stair (time events, Integer output,
termination), TypedBlock (every FMI variable type, a discrete input), Feedthrough (direct
feed-through), and for the coupling algorithms Polynomial (feed-through with directional
derivatives), PController and Lag (a controller around a plant with feed-through), SpringMass
(two of them: two masses with a spring) and TwoMasses (both masses in one FMU). Each as
``<Model>_fmi2.fmu`` and ``<Model>_fmi3.fmu``, both with Co-Simulation and Model Exchange, built
once per session with CMake against fmpy's FMI headers into a temporary folder (never
committed). A missing cmake skips the tests that use them.

Use the session fixture ``event_fmus`` (``{(model, "2.0" | "3.0"): Path}``) or, once it has run,
``event_fmu(model, version)``. Closed forms to compare with: ``ball_exact`` (BouncingBall) and
``typed_expected`` (TypedBlock, with ``declared_start_values``).
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
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


# ---- closed forms of the models ----


def ball_exact(t, h0=1.0, g=9.81, e=0.7, v_min=0.1):
    """Closed form of the ball dropped from rest at h0: (h, v, bounces) at t, bounce times."""
    t_b = [math.sqrt(2.0 * h0 / g)]
    v = math.sqrt(2.0 * g * h0)  # impact speed
    v_up = []  # speed after each bounce (0: rests)
    while True:
        v *= e
        if v < v_min:
            v_up.append(0.0)
            break
        v_up.append(v)
        t_b.append(t_b[-1] + 2.0 * v / g)
    t_b, v_up = np.array(t_b), np.array(v_up)
    t = np.asarray(t, dtype=float)
    k = np.searchsorted(t_b, t, side="right")  # bounces done by t
    tau = np.where(k == 0, t, t - t_b[np.maximum(k - 1, 0)])
    v0 = np.where(k == 0, 0.0, v_up[np.maximum(k - 1, 0)])
    h = np.where(k == 0, h0, 0.0) + v0 * tau - 0.5 * g * tau**2
    vel = v0 - g * tau
    rest = k == len(t_b)
    return np.where(rest, 0.0, h), np.where(rest, 0.0, vel), k, t_b


def _wrap(x, bits):
    """Two's complement wrap-around of an integer to ``bits`` bits."""
    return (x + 2 ** (bits - 1)) % 2**bits - 2 ** (bits - 1)


def declared_start_values(md):
    """The declared start values of a model description as Python values."""
    out = {}
    for v in md.modelVariables:
        if v.start is None:
            continue
        if v.type == "String":
            out[v.name] = v.start
        elif v.type == "Boolean":
            out[v.name] = v.start in ("true", "1", True)
        elif v.type in ("Real", "Float32", "Float64"):
            values = [float(x) for x in str(v.start).split()]
            out[v.name] = values if v.dimensions else values[0]
        else:
            out[v.name] = int(v.start)
    return out


def typed_expected(version, s):
    """TypedBlock's outputs for the inputs and parameters ``s`` (name -> value)."""
    v3 = version == "3.0"
    f32 = np.float32 if v3 else float
    gains = s["gains"] if v3 else [s["gains[1]"], s["gains[2]"], s["gains[3]"]]
    return {
        "f32_out": f32(2.0) * f32(s["f32_in"]) + f32(0.5),
        "i8_out": s["i8_in"],
        "u16_out": (s["u16_in"] + 1) % 65536,
        "i32_out": _wrap(s["i32_in"] + 1, 32),
        "i64_out": _wrap(2 * s["i64_in"], 64 if v3 else 32),
        "u64_out": (s["u64_in"] + 1) % 2**64 if v3 else _wrap(s["u64_in"] + 1, 32),
        "b_out": not s["b_in"],
        "mode_out": s["mode_in"],
        "d_out": s["d_in"],
        "label_len": len(s["label"]),
        "gain_sum": sum(gains),
    }
