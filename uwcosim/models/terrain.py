"""Bathymetry maps and the terrain-depth function ``h_d(x, y)`` of seed 000 eq. (55).

A map is a regular grid of depths (m, positive down) at ``x = x0 + i*dx`` (east) and
``y = y0 + j*dy`` (north), stored as ``depth[j, i]`` (rows are y). ``h_d`` is the C2 cubic
B-spline that interpolates the grid (coefficients from :func:`scipy.ndimage.spline_filter` with
mirror boundaries, padded by three mirrored coefficients on each side), defined once in
:mod:`uwcosim.core.bspline` (which lists its other forms and their tests). It is evaluated by

- :meth:`Bathymetry.depth` / :meth:`Bathymetry.gradient` (numpy, vectorized over points),
- :meth:`Bathymetry.casadi_function` (``casadi.bspline``: exact Jacobians for the EKF),
- the DepthSounder FMU's C kernel, which reads :meth:`Bathymetry.write_coefficients` files.

Maps come from :func:`synthetic_bathymetry` (seeded spectral synthesis) or :func:`load_map`
(``.npz`` or NetCDF as GEBCO distributes it). A map in latitude/longitude is projected to the
local transverse Mercator frame of :mod:`uwcosim.models.geo` (centred on the map, or on the
origin the caller gives) and resampled onto a regular grid of that frame.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from uwcosim.core import bspline
from uwcosim.core.errors import MapError
from uwcosim.models.geo import LocalFrame, grid_centre, project_grid
from uwcosim.models.map_decode import CF_KEYS, LENGTHS, decode, fill_problem, map_memory_problem

PAD = 3
MAGIC = b"UWCBATH1"
_HEADER = struct.Struct("<8sii4d")
EARTH_RADIUS_M = 6_371_000.0
#: names of the depth variable of a map file, in the order they are looked for
DEPTH_NAMES = ("depth", "elevation", "z")


@dataclass(frozen=True)
class Bathymetry:
    """A depth grid and its interpolating cubic B-spline."""

    x0: float
    y0: float
    dx: float
    dy: float
    depth_grid: np.ndarray  # [ny, nx], metres, positive down
    coefficients: np.ndarray = field(init=False, repr=False)  # [ny + 6, nx + 6]

    def __post_init__(self) -> None:
        z = np.asarray(self.depth_grid, dtype=float)
        if z.ndim != 2 or min(z.shape) < 4:
            raise MapError(f"bathymetry grid must be 2-D with at least 4x4 cells, got {z.shape}")
        if not np.all(np.isfinite(z)):
            raise MapError("bathymetry grid contains NaN or infinite depths")
        if not (self.dx > 0 and self.dy > 0):
            raise MapError(f"bathymetry spacing must be positive, got dx={self.dx}, dy={self.dy}")
        c = ndimage.spline_filter(z, order=3, mode="mirror")
        object.__setattr__(self, "depth_grid", z)
        object.__setattr__(self, "coefficients", np.pad(c, PAD, mode="reflect"))

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth_grid.shape

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` of the grid."""
        ny, nx = self.shape
        return (self.x0, self.x0 + (nx - 1) * self.dx, self.y0, self.y0 + (ny - 1) * self.dy)

    def inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        xmin, xmax, ymin, ymax = self.extent
        return (x >= xmin) & (x <= xmax) & (y >= ymin) & (y <= ymax)

    def _weights(self, x: np.ndarray, y: np.ndarray):
        ny, nx = self.shape
        iu, fu = bspline.cell((np.asarray(x, dtype=float) - self.x0) / self.dx, nx)
        iv, fv = bspline.cell((np.asarray(y, dtype=float) - self.y0) / self.dy, ny)
        return iu, fu, iv, fv

    def _eval(self, x, y, grad: bool):
        iu, fu, iv, fv = self._weights(x, y)
        wu, dwu = bspline.basis(fu)
        wv, dwv = bspline.basis(fv)
        c = self.coefficients
        val = np.zeros(np.shape(fu))
        gx = np.zeros_like(val)
        gy = np.zeros_like(val)
        # coefficient of grid node j sits at padded index j + PAD; the stencil is j-1..j+2
        for b in range(4):
            row = iv + b - 1 + PAD
            for a in range(4):
                cab = c[row, iu + a - 1 + PAD]
                val += wu[a] * wv[b] * cab
                if grad:
                    gx += dwu[a] * wv[b] * cab
                    gy += wu[a] * dwv[b] * cab
        if grad:
            return val, gx / self.dx, gy / self.dy
        return val

    def depth(self, x, y) -> np.ndarray:
        """``h_d(x, y)``; points outside the grid take the value at the nearest edge."""
        return self._eval(x, y, grad=False)

    def gradient(self, x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(h_d, dh_d/dx, dh_d/dy)`` at the points."""
        return self._eval(x, y, grad=True)

    def knots(self) -> tuple[np.ndarray, np.ndarray]:
        """B-spline knots (x and y) matching :attr:`coefficients`."""
        ny, nx = self.shape
        kx = self.x0 + self.dx * np.arange(-5, nx + 5, dtype=float)
        ky = self.y0 + self.dy * np.arange(-5, ny + 5, dtype=float)
        return kx, ky

    def casadi_function(self):
        """``h_d`` as a CasADi function of ``[x, y]`` (same spline; exact derivatives)."""
        import casadi as ca

        kx, ky = self.knots()
        xy = ca.MX.sym("xy", 2)
        coef = ca.DM(self.coefficients.ravel())  # x fastest: column-major in (x, y)
        h = ca.bspline(xy, coef, [list(kx), list(ky)], [3, 3], 1, {})
        return ca.Function("terrain_depth", [xy], [h], ["xy"], ["h"])

    def write_coefficients(self, path: str | Path) -> Path:
        """Write the binary file the DepthSounder FMU reads (little-endian)::

        magic 'UWCBATH1', int32 nx, int32 ny, float64 x0, y0, dx, dy,
        float64 coefficients[(ny + 6) * (nx + 6)] (x fastest, 3 padding nodes on each side).
        """
        path = Path(path)
        ny, nx = self.shape
        with open(path, "wb") as fh:
            fh.write(_HEADER.pack(MAGIC, nx, ny, self.x0, self.y0, self.dx, self.dy))
            fh.write(np.ascontiguousarray(self.coefficients, dtype="<f8").tobytes())
        return path

    def save_npz(self, path: str | Path) -> Path:
        ny, nx = self.shape
        x = self.x0 + self.dx * np.arange(nx)
        y = self.y0 + self.dy * np.arange(ny)
        np.savez_compressed(path, x=x, y=y, depth=self.depth_grid)
        return Path(path)


def read_coefficients(path: str | Path) -> Bathymetry:
    """The map of a :meth:`Bathymetry.write_coefficients` file (a run directory's ``map.bin``).

    The depth grid is the spline evaluated at the nodes (weights 1/6, 4/6, 1/6 per axis), from
    which the same coefficients follow again up to rounding.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
        magic, nx, ny, x0, y0, dx, dy = _HEADER.unpack_from(raw)
    except (OSError, struct.error) as exc:
        raise MapError(f"{path}: cannot read the map coefficients ({exc})") from None
    n = (ny + 2 * PAD) * (nx + 2 * PAD)
    if magic != MAGIC or len(raw) != _HEADER.size + 8 * n:
        raise MapError(f"{path}: not a uwcosim map coefficient file (expected {MAGIC.decode()}, "
                       f"{n} coefficients)")
    c = np.frombuffer(raw, dtype="<f8", offset=_HEADER.size).reshape(ny + 2 * PAD, nx + 2 * PAD)
    w = np.array([1.0, 4.0, 1.0]) / 6.0
    rows = sum(w[b] * c[PAD - 1 + b:PAD - 1 + b + ny, :] for b in range(3))
    depth = sum(w[a] * rows[:, PAD - 1 + a:PAD - 1 + a + nx] for a in range(3))
    return Bathymetry(x0, y0, dx, dy, depth)


def synthetic_bathymetry(
    seed: int,
    extent: tuple[float, float, float, float] = (0.0, 25_000.0, 0.0, 25_000.0),
    resolution: float = 50.0,
    mean_depth: float = 1000.0,
    relief_std: float = 60.0,
    spectral_slope: float = 3.6,
) -> Bathymetry:
    """A seeded synthetic seafloor with realistic relief.

    Fractal relief by spectral synthesis (isotropic power spectrum ~ k^-slope, slope 3-4 as
    measured for abyssal hills), scaled to ``relief_std``, on top of a regional slope and a few
    Gaussian seamounts. The same seed gives the same map on every machine.
    """
    xmin, xmax, ymin, ymax = (float(v) for v in extent)
    nx = int(round((xmax - xmin) / resolution)) + 1
    ny = int(round((ymax - ymin) / resolution)) + 1
    rng = np.random.default_rng(seed)
    kx = np.fft.fftfreq(nx, d=resolution)
    ky = np.fft.fftfreq(ny, d=resolution)
    k = np.hypot(*np.meshgrid(kx, ky))
    k[0, 0] = np.inf
    amp = np.maximum(k, 1.0 / 20_000.0) ** (-spectral_slope / 2.0)
    amp[0, 0] = 0.0
    phase = rng.standard_normal((ny, nx)) + 1j * rng.standard_normal((ny, nx))
    relief = np.real(np.fft.ifft2(amp * phase))
    relief *= relief_std / relief.std()
    x = xmin + resolution * np.arange(nx)
    y = ymin + resolution * np.arange(ny)
    X, Y = np.meshgrid(x, y)
    slope_dir = rng.uniform(0, 2 * np.pi)
    regional = 0.01 * ((X - X.mean()) * np.cos(slope_dir) + (Y - Y.mean()) * np.sin(slope_dir))
    seamounts = np.zeros_like(X)
    for _ in range(4):
        cx, cy = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
        r = rng.uniform(800.0, 2500.0)
        height = rng.uniform(80.0, 250.0)
        seamounts -= height * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * r**2))
    depth = mean_depth + relief + regional + seamounts
    return Bathymetry(xmin, ymin, resolution, resolution, depth)


def _grid_from_axes(x: np.ndarray, y: np.ndarray, z: np.ndarray, where: str) -> Bathymetry:
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    z = np.asarray(z, dtype=float)
    if z.shape != (y.size, x.size):
        raise MapError(
            f"{where}: depth grid shape {z.shape} does not match y ({y.size}) x x ({x.size})"
        )
    for name, ax in (("x", x), ("y", y)):
        d = np.diff(ax)
        if ax.size < 4 or not np.all(d > 0) or not np.allclose(d, d[0], rtol=1e-6):
            raise MapError(f"{where}: axis {name!r} must be increasing and uniformly spaced")
    return Bathymetry(float(x[0]), float(y[0]), float(x[1] - x[0]), float(y[1] - y[0]), z)


def _local_metric(lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equirectangular projection about the grid centre (metres east/north of the SW corner):
    ``projection = "equirectangular"``, the projection of earlier versions."""
    lat0 = np.deg2rad(0.5 * (lat[0] + lat[-1]))
    x = EARTH_RADIUS_M * np.cos(lat0) * np.deg2rad(lon - lon[0])
    y = EARTH_RADIUS_M * np.deg2rad(lat - lat[0])
    return x, y


def load_map(path: str | Path, variable: str | None = None, *,
             origin: tuple[float, float] | None = None, projection: str = "tmerc",
             resolution: float | None = None) -> Bathymetry:
    """Read a user grid.

    - ``.npz`` with arrays ``x``, ``y`` (m) and ``depth`` (m, positive down) or ``elevation``
      (m, negative below sea level), shaped ``[len(y), len(x)]``;
    - NetCDF (``.nc``), as GEBCO distributes it: ``x``/``y`` in metres, or ``lon``/``lat``
      in degrees, and ``elevation`` (or ``depth``, or ``variable``); read as CF encodes
      them (``scale_factor``/``add_offset``, ``_FillValue`` refused, ``units`` m/km/ft:
      :mod:`uwcosim.models.map_decode`).

    A grid above the memory limit (:mod:`uwcosim.core.memory`) is refused before it is used.

    A latitude/longitude grid is projected (``projection = "tmerc"``, the default) to the
    local transverse Mercator frame centred on ``origin`` (``(lat, lon)`` in degrees; default:
    the grid's centre, :func:`map_frame`) and resampled by the grid's cubic spline in
    longitude/latitude onto a regular grid of that frame with as many nodes as the source (or
    spaced by ``resolution`` metres): :func:`uwcosim.models.geo.project_grid`.
    ``projection = "equirectangular"`` keeps the grid's nodes and places them by an
    equirectangular projection about its centre (metres from its south-west corner), as
    earlier versions did.
    """
    arrays, path = _read_arrays(path, variable)
    try:
        return _bathymetry_from_arrays(arrays, variable, str(path), origin, projection,
                                       resolution)
    except MapError as exc:  # name the file in every message
        msg = str(exc)
        raise MapError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None
    except (ValueError, TypeError) as exc:
        raise MapError(f"{path}: map arrays are not numeric ({exc})") from None


def _read_arrays(path: str | Path, variable: str | None = None) -> tuple[dict, Path]:
    path = Path(path)
    if not path.is_file():
        raise MapError(f"{path}: map file not found")
    try:
        if path.suffix == ".npz":
            with np.load(path) as data:
                return {k: data[k] for k in data.files}, path
        if path.suffix in (".nc", ".nc4", ".netcdf"):
            return _read_netcdf(path, variable), path
        raise MapError(f"{path}: unknown map format (expected .npz or .nc)")
    except MapError:
        raise
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad file
        raise MapError(f"{path}: cannot read map ({exc})") from None


def map_frame(path: str | Path) -> LocalFrame | None:
    """The local frame of a latitude/longitude map file (centred on its grid), or None for a
    map in metres."""
    arrays, path = _read_arrays(path)
    if "x" in arrays and "y" in arrays or not ("lon" in arrays and "lat" in arrays):
        return None
    try:
        lat, lon = _increasing(arrays["lat"], "lat", str(path)), \
            _increasing(arrays["lon"], "lon", str(path))
        return LocalFrame(*grid_centre(lat, lon))
    except ValueError as exc:
        raise MapError(f"{path}: {exc}") from None


def _read_netcdf(path: Path, variable: str | None = None) -> dict[str, np.ndarray]:
    """The variables of a NetCDF map, decoded (:mod:`uwcosim.models.map_decode`: packing,
    fill values, units); a depth grid too large for the memory limit is refused before its
    data is read, one with no-data cells after."""
    try:
        import h5netcdf

        with h5netcdf.File(path, "r") as f:
            return _decoded(f.variables, str(path), variable, lambda v: dict(v.attrs))
    except OSError:
        from scipy.io import netcdf_file  # NetCDF-3 classic files

        with netcdf_file(path, "r", mmap=False) as f:
            # scipy keeps a variable's attributes as its instance attributes
            return _decoded(f.variables, str(path), variable,
                            lambda v: {k: a for k, a in vars(v).items() if k in CF_KEYS})


def _decoded(variables, where: str, variable: str | None, attrs) -> dict[str, np.ndarray]:
    depth = next((n for n in ([variable] if variable else DEPTH_NAMES) if n in variables), None)
    if depth is not None:
        why = map_memory_problem(tuple(variables[depth].shape), where)
        if why:
            raise MapError(why)
    out = {}
    for k, v in variables.items():
        raw = np.asarray(v[...])
        if raw.dtype.kind not in "iuf":  # text, a crs container...: as stored
            out[k] = raw
            continue
        try:
            out[k], n_fill, fill = decode(k, raw, attrs(v), where, k in LENGTHS or k == depth)
        except ValueError as exc:
            raise MapError(str(exc)) from None
        if k == depth:
            why = fill_problem(k, out[k], n_fill, fill, where)
            if why:
                raise MapError(why)
    return out


def _increasing(axis, name: str, where: str) -> np.ndarray:
    a = np.asarray(axis, dtype=float).ravel()
    if a.size < 4 or not np.all(np.diff(a) > 0):
        raise MapError(f"{where}: axis {name!r} must be increasing and uniformly spaced")
    return a


def _bathymetry_from_arrays(arrays: dict, variable: str | None, where: str,
                            origin: tuple[float, float] | None = None,
                            projection: str = "tmerc",
                            resolution: float | None = None) -> Bathymetry:
    names = [variable] if variable else list(DEPTH_NAMES)
    key = next((n for n in names if n in arrays), None)
    if key is None:
        raise MapError(f"{where}: no depth variable (looked for {', '.join(names)})")
    why = map_memory_problem(np.shape(arrays[key]), where)
    if why:
        raise MapError(why)
    z = np.asarray(arrays[key], dtype=float)
    if key == "elevation":
        z = -z
    if "x" in arrays and "y" in arrays:
        return _grid_from_axes(arrays["x"], arrays["y"], z, where)
    if not ("lon" in arrays and "lat" in arrays):
        raise MapError(f"{where}: no coordinate axes (expected x/y in metres or lon/lat)")
    lon, lat = np.asarray(arrays["lon"], float).ravel(), np.asarray(arrays["lat"], float).ravel()
    if lat.size > 1 and np.all(np.diff(lat) < 0):  # north to south: turn it over
        lat, z = lat[::-1], z[::-1]
    if projection == "equirectangular":
        x, y = _local_metric(lon, lat)
        return _grid_from_axes(x, y, z, where)
    if projection != "tmerc":
        raise MapError(f"{where}: unknown projection {projection!r} (expected tmerc or "
                       f"equirectangular)")
    src = _grid_from_axes(lon, lat, z, where)  # the spline in longitude/latitude
    try:
        frame = LocalFrame(*(origin if origin is not None else grid_centre(lat, lon)))
        x, y, (la, lo) = project_grid(lat, lon, frame, resolution)
    except ValueError as exc:
        raise MapError(f"{where}: {exc}") from None
    return Bathymetry(float(x[0]), float(y[0]), float(x[1] - x[0]), float(y[1] - y[0]),
                      src.depth(lo, la))
