"""Build the third-party vehicle FMUs of the tests (import them; this is not a conftest).

- ``NorthEastVehicle.fmu``: FMI 2.0 co-simulation exported by pythonfmu from
  ``tests/data/pythonfmu_vehicle/NorthEastVehicle.py`` (north-east order, compass heading in
  degrees, knots, no declared units, start values as parameters).
- ``FeetVehicle.fmu``: FMI 3.0 co-simulation built from hand-written C
  (``tests/data/fmi3_vehicle``) with CMake against fmpy's FMI 3 headers (feet, km/h through
  its UnitDefinitions, yaw from north, process-noise inputs).

Both are built into temporary folders, never committed; a missing tool skips the tests.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"
PYFMU_DIR = DATA / "pythonfmu_vehicle"
FMI3_DIR = DATA / "fmi3_vehicle"


def build_pythonfmu_vehicle(out: Path) -> Path:
    pytest.importorskip("pythonfmu", reason="pythonfmu is not installed")
    out.mkdir(parents=True, exist_ok=True)
    r = subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f",
                        str(PYFMU_DIR / "NorthEastVehicle.py"), "-d", str(out)],
                       capture_output=True, text=True, cwd=out, timeout=300)
    fmu = out / "NorthEastVehicle.fmu"
    assert r.returncode == 0 and fmu.is_file(), r.stdout + r.stderr
    return fmu


def build_fmi3_vehicle(out: Path) -> Path:
    import fmpy

    # the venv's cmake (pip package) first, then the system's
    cmake = shutil.which("cmake", path=str(Path(sys.executable).parent)) or shutil.which("cmake")
    if cmake is None:
        pytest.skip("cmake is not installed")
    headers = Path(fmpy.__file__).parent / "c-code"
    build = out / "build"
    for cmd in ([cmake, "-S", str(FMI3_DIR), "-B", str(build), f"-DFMI_HEADERS={headers}",
                 "-DCMAKE_BUILD_TYPE=Release"],
                [cmake, "--build", str(build), "--config", "Release"]):
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stdout + r.stderr
    lib = next(p for p in build.rglob(f"FeetVehicle{fmpy.sharedLibraryExtension}"))
    fmu = out / "FeetVehicle.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.write(FMI3_DIR / "modelDescription.xml", "modelDescription.xml")
        zf.write(lib, f"binaries/{fmpy.platform_tuple}/{lib.name}")
    return fmu


_BUILT: dict[str, Path] = {}


@pytest.fixture(scope="session")
def pythonfmu_vehicle(tmp_path_factory) -> Path:
    if "py" not in _BUILT:
        _BUILT["py"] = build_pythonfmu_vehicle(tmp_path_factory.mktemp("pythonfmu"))
    return _BUILT["py"]


@pytest.fixture(scope="session")
def fmi3_vehicle(tmp_path_factory) -> Path:
    if "c3" not in _BUILT:
        _BUILT["c3"] = build_fmi3_vehicle(tmp_path_factory.mktemp("fmi3c"))
    return _BUILT["c3"]
