"""The DepthSounder's C terrain kernel agrees with ``Bathymetry.depth`` (to 1e-9 m), alone
(ctypes on ``uwc_map.c``) and inside the FMU (default map, user maps via ``mapFile``, a
2000 x 2000 grid, out-of-map errors, bad map files).
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest
from fmpy import simulate_fmu

from uwcosim.fmu.build import build_map_kernel
from uwcosim.models.terrain import Bathymetry, synthetic_bathymetry

try:
    from fmu_fixtures import CS, ME, Instance, fmu_dir, fmu_path
except ImportError:  # tests/ imported as a package
    from tests.fmu_fixtures import CS, ME, Instance, fmu_dir, fmu_path

__all__ = ["fmu_dir"]  # the session fixture, re-exported for pytest

TOL = 1e-9
VERSIONS = ("3.0", "2.0")


class _Map(ctypes.Structure):
    _fields_ = [("nx", ctypes.c_int), ("ny", ctypes.c_int), ("x0", ctypes.c_double),
                ("y0", ctypes.c_double), ("dx", ctypes.c_double), ("dy", ctypes.c_double),
                ("c", ctypes.POINTER(ctypes.c_double))]


class Kernel:
    """ctypes wrapper of the compiled ``uwc_map.c``."""

    def __init__(self, lib_path) -> None:
        lib = ctypes.CDLL(str(lib_path))
        lib.uwc_map_load.argtypes = [ctypes.POINTER(_Map), ctypes.c_char_p, ctypes.c_char_p,
                                     ctypes.c_size_t]
        lib.uwc_map_depth.argtypes = [ctypes.POINTER(_Map), ctypes.c_double, ctypes.c_double]
        lib.uwc_map_depth.restype = ctypes.c_double
        lib.uwc_map_inside.argtypes = lib.uwc_map_depth.argtypes
        lib.uwc_map_extent.argtypes = [ctypes.POINTER(_Map), ctypes.c_double * 4]
        lib.uwc_map_free.argtypes = [ctypes.POINTER(_Map)]
        self.lib = lib

    def load(self, path) -> tuple[_Map | None, str]:
        m, err = _Map(), ctypes.create_string_buffer(1024)
        rc = self.lib.uwc_map_load(ctypes.byref(m), str(path).encode(), err, len(err))
        return (m if rc == 0 else None), err.value.decode()

    def depth(self, m, x, y) -> np.ndarray:
        return np.array([self.lib.uwc_map_depth(ctypes.byref(m), a, b)
                         for a, b in zip(x, y, strict=True)])

    def inside(self, m, x, y) -> np.ndarray:
        return np.array([bool(self.lib.uwc_map_inside(ctypes.byref(m), a, b))
                         for a, b in zip(x, y, strict=True)])


@pytest.fixture(scope="module")
def kernel(tmp_path_factory) -> Kernel:
    return Kernel(build_map_kernel(tmp_path_factory.mktemp("kernel") / "libuwcmap.so"))


@pytest.fixture(scope="module")
def default_map() -> Bathymetry:
    return synthetic_bathymetry(7)


def _random_map(seed, nx, ny, x0, y0, dx, dy) -> Bathymetry:
    rng = np.random.default_rng(seed)
    z = 500 + np.cumsum(rng.standard_normal((ny, nx)), axis=0) + 10 * rng.random((ny, nx))
    return Bathymetry(x0, y0, dx, dy, z)


def _test_points(b: Bathymetry, n: int, seed: int = 0, margin: float = 0.0):
    """Random points plus grid nodes, edges and corners (outside by ``margin`` if > 0)."""
    xmin, xmax, ymin, ymax = b.extent
    rng = np.random.default_rng(seed)
    x = list(rng.uniform(xmin - margin, xmax + margin, n))
    y = list(rng.uniform(ymin - margin, ymax + margin, n))
    ny, nx = b.shape
    for i, j in [(0, 0), (nx - 1, ny - 1), (nx - 2, 1), (1, ny - 2), (nx // 2, ny // 3)]:
        x.append(b.x0 + i * b.dx)
        y.append(b.y0 + j * b.dy)
    for cx, cy in [(xmin, ymin), (xmax, ymin), (xmin, ymax), (xmax, ymax),
                   (xmax, (ymin + ymax) / 2), ((xmin + xmax) / 2, ymax)]:
        x.append(cx)
        y.append(cy)
    return np.array(x), np.array(y)


MAPS = {
    "synthetic": lambda: synthetic_bathymetry(3, extent=(0.0, 4000.0, -1000.0, 2000.0),
                                           resolution=80.0),
    "offset_anisotropic": lambda: _random_map(1, 37, 23, -1234.5, 987.0, 13.0, 41.0),
    "minimal_4x4": lambda: _random_map(2, 4, 4, 0.0, 0.0, 1.0, 1.0),
    "tall": lambda: _random_map(3, 5, 60, 100.0, -50.0, 2.5, 0.75),
}


# ---- the kernel alone ---------------------------------------------------------------------

@pytest.mark.parametrize("name", MAPS)
def test_kernel_matches_numpy(kernel, tmp_path, name):
    b = MAPS[name]()
    m, err = kernel.load(b.write_coefficients(tmp_path / "map.uwcbath"))
    assert m is not None, err
    assert (m.nx, m.ny) == (b.shape[1], b.shape[0])
    ext = (ctypes.c_double * 4)()
    kernel.lib.uwc_map_extent(ctypes.byref(m), ext)
    assert list(ext) == list(b.extent)
    x, y = _test_points(b, 2000)
    np.testing.assert_allclose(kernel.depth(m, x, y), b.depth(x, y), rtol=0, atol=TOL)
    # outside the grid the kernel clamps like the numpy reference (the FMU rejects)
    xo, yo = _test_points(b, 300, seed=1, margin=5 * max(b.dx, b.dy))
    np.testing.assert_allclose(kernel.depth(m, xo, yo), b.depth(xo, yo), rtol=0, atol=TOL)
    np.testing.assert_array_equal(kernel.inside(m, xo, yo), b.inside(xo, yo))
    kernel.lib.uwc_map_free(ctypes.byref(m))


def test_kernel_rejects_bad_files(kernel, tmp_path):
    good = _random_map(4, 6, 5, 0, 0, 1, 1).write_coefficients(tmp_path / "good.uwcbath")
    data = good.read_bytes()
    cases = {
        "missing.uwcbath": (None, "cannot be opened"),
        "magic.uwcbath": (b"NOTBATH1" + data[8:], "not a UWCBATH1"),
        "header.uwcbath": (data[:20], "incomplete header"),
        "truncated.uwcbath": (data[:-8], "truncated (131 of 132 coefficients)"),
        "size.uwcbath": (data[:8] + (2).to_bytes(4, "little") + data[12:], "invalid grid size"),
    }
    for name, (content, message) in cases.items():
        path = tmp_path / name
        if content is not None:
            path.write_bytes(content)
        m, err = kernel.load(path)
        assert m is None
        assert str(path) in err and message in err, err


# ---- inside the DepthSounder FMU ------------------------------------------------------------

@pytest.mark.parametrize("version", VERSIONS)
def test_depth_sounder_default_map(fmu_dir, default_map, version):
    inst = Instance(fmu_path(fmu_dir, "DepthSounder", version))
    inst.init()
    assert inst.get("map_xmin", "map_xmax", "map_ymin", "map_ymax") == list(default_map.extent)
    x, y = _test_points(default_map, 400, seed=5)
    e = np.random.default_rng(6).normal(size=x.size)
    got = []
    for xi, yi, ei in zip(x, y, e, strict=True):
        inst.set(x=xi, y=yi, e_h=ei)
        got.append(inst.get("depth_m")[0])
    np.testing.assert_allclose(got, default_map.depth(x, y) + e, rtol=0, atol=TOL)
    inst.free()


@pytest.mark.parametrize("version", VERSIONS)
def test_default_map_found_in_resource_path_with_special_characters(fmu_dir, tmp_path,
                                                                   default_map, version):
    import zipfile

    unzipdir = tmp_path / "dir with space, 100% & é"
    with zipfile.ZipFile(fmu_path(fmu_dir, "DepthSounder", version)) as zf:
        zf.extractall(unzipdir)
    inst = Instance(fmu_path(fmu_dir, "DepthSounder", version), unzipdir=str(unzipdir))
    inst.init(x=1234.0, y=4321.0)
    assert inst.get("depth_m")[0] == pytest.approx(default_map.depth(1234.0, 4321.0), abs=TOL)
    inst.free()


@pytest.mark.parametrize("interface", (CS, ME))
@pytest.mark.parametrize("version", VERSIONS)
def test_depth_sounder_user_map(fmu_dir, tmp_path, version, interface):
    b = MAPS["offset_anisotropic"]()
    path = b.write_coefficients(tmp_path / "user map.uwcbath")  # a space in the path
    inst = Instance(fmu_path(fmu_dir, "DepthSounder", version), interface)
    inst.init(mapFile=str(path), x=b.x0, y=b.y0)
    x, y = _test_points(b, 300, seed=7)
    got = []
    for xi, yi in zip(x, y, strict=True):
        inst.set(x=xi, y=yi)
        got.append(inst.get("depth_m")[0])
    np.testing.assert_allclose(got, b.depth(x, y), rtol=0, atol=TOL)
    inst.free()
    # the same through fmpy's simulate_fmu, with the map given as a start value
    xc, yc = b.x0 + 100.0, b.y0 + 300.0
    result = simulate_fmu(str(fmu_path(fmu_dir, "DepthSounder", version)), fmi_type=interface,
                          stop_time=1.0, output_interval=0.5,
                          start_values={"mapFile": str(path), "x": xc, "y": yc, "e_h": 0.5})
    np.testing.assert_allclose(result["depth_m"], b.depth(xc, yc) + 0.5, rtol=0, atol=TOL)


def test_depth_sounder_loads_2000_x_2000_grid(fmu_dir, tmp_path):
    b = _random_map(8, 2000, 2000, -10_000.0, 5_000.0, 10.0, 12.5)
    path = b.write_coefficients(tmp_path / "big.uwcbath")
    inst = Instance(fmu_path(fmu_dir, "DepthSounder"))
    inst.init(mapFile=str(path))
    assert inst.get("map_xmax", "map_ymax") == [b.extent[1], b.extent[3]]
    x, y = _test_points(b, 200, seed=9)
    got = []
    for xi, yi in zip(x, y, strict=True):
        inst.set(x=xi, y=yi)
        got.append(inst.get("depth_m")[0])
    np.testing.assert_allclose(got, b.depth(x, y), rtol=0, atol=TOL)
    inst.free()


@pytest.mark.parametrize("interface", (CS, ME))
@pytest.mark.parametrize("version", VERSIONS)
def test_depth_sounder_out_of_map_is_an_error(fmu_dir, version, interface):
    path = fmu_path(fmu_dir, "DepthSounder", version)
    leave = np.array([(0.0, 24_000.0, 100.0), (2.0, 26_000.0, 100.0)],
                     dtype=[("time", float), ("x", float), ("y", float)])
    with pytest.raises(Exception, match="status 3"):
        simulate_fmu(str(path), fmi_type=interface, stop_time=2.0, output_interval=0.1,
                     input=leave)
    inst = Instance(path, interface, name="sounder")
    inst.init(x=100.0, y=200.0)
    inst.get("depth_m")
    inst.set(x=25_000.5, y=-3.25)
    with pytest.raises(Exception, match="status 3"):
        inst.get("depth_m")
    assert "sounder: position (x, y) = (25000.5, -3.25) m" in inst.log
    assert "outside the map" in inst.log
    # reset brings the instance back after the error
    inst.fmu.reset()
    inst.init(x=100.0, y=200.0)
    assert np.isfinite(inst.get("depth_m")[0])
    inst.free()


@pytest.mark.parametrize("version", VERSIONS)
def test_depth_sounder_bad_map_file_fails_initialization(fmu_dir, tmp_path, version):
    bad = tmp_path / "bad.uwcbath"
    bad.write_bytes(b"garbage")
    for path, message in ((tmp_path / "none.uwcbath", "cannot be opened"),
                          (bad, "incomplete header")):
        inst = Instance(fmu_path(fmu_dir, "DepthSounder", version))
        with pytest.raises(Exception, match="status 3"):
            inst.init(mapFile=str(path))
        assert f"map file '{path}'" in inst.log and message in inst.log
        inst.free()


def test_two_sounders_with_different_maps(fmu_dir, tmp_path, default_map):
    b = MAPS["synthetic"]()
    path = b.write_coefficients(tmp_path / "other.uwcbath")
    a = Instance(fmu_path(fmu_dir, "DepthSounder"), name="a")
    c = Instance(fmu_path(fmu_dir, "DepthSounder"), name="c", unzipdir=a.dir)
    a.init()
    c.init(mapFile=str(path))
    for xi, yi in [(100.0, 50.0), (3000.0, 1500.0), (2500.0, 10.0)]:
        a.set(x=xi, y=yi)
        c.set(x=xi, y=yi)
        assert a.get("depth_m")[0] == pytest.approx(default_map.depth(xi, yi), abs=TOL)
        assert c.get("depth_m")[0] == pytest.approx(b.depth(xi, yi), abs=TOL)
    c.free()
    a.free()
