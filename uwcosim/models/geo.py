"""The local metric frame of a georeferenced run: :class:`LocalFrame`, with ``pyproj``.

Everything inside a run (the map, the truth, the filters' states) is in metres, ``x`` east and
``y`` north. A run is georeferenced when it has a geographic origin (``[geo] origin``, or the
centre of a map given in latitude/longitude): the local frame is then the **transverse
Mercator projection of the WGS 84 ellipsoid centred on the origin**, scale 1 on its central
meridian, no false easting or northing::

    +proj=tmerc +lat_0=LAT0 +lon_0=LON0 +k_0=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs

so the origin is ``(0, 0)``, ``x`` is the easting and ``y`` the northing from it. Over the
tens of kilometres of a terrain-navigation map its scale differs from 1 by less than 1e-5
(``(x / R)^2 / 2`` at ``x`` from the central meridian), so distances in the frame are the
ground distances; geographic coordinates are WGS 84 latitude and longitude in degrees
(EPSG:4326). The frame's definition (PROJ string, origin) is written in the log's metadata
(``geo``), from which the report stage rebuilds it (:meth:`LocalFrame.from_metadata`).

:func:`project_grid` resamples a latitude/longitude grid (GEBCO's NetCDF) onto a regular grid
of the local frame: the projected grid is curvilinear, the filters and the DepthSounder FMU
need a regular one.

``pyproj`` is imported when a frame is first used (it costs 60 ms at start-up).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

#: WGS 84 latitude, longitude (degrees)
GEOGRAPHIC_CRS = "EPSG:4326"


@dataclass(frozen=True)
class LocalFrame:
    """The local transverse Mercator frame at ``(lat0, lon0)`` (degrees): metres east/north."""

    lat0: float
    lon0: float

    def __post_init__(self) -> None:
        if not (-90.0 < self.lat0 < 90.0 and -180.0 <= self.lon0 <= 360.0):
            raise ValueError(f"origin latitude {self.lat0:g} must be in (-90, 90) and longitude "
                             f"{self.lon0:g} in [-180, 360] degrees")

    @property
    def proj(self) -> str:
        """The PROJ definition of the frame."""
        return (f"+proj=tmerc +lat_0={self.lat0!r} +lon_0={self.lon0!r} +k_0=1 +x_0=0 +y_0=0 "
                f"+ellps=WGS84 +units=m +no_defs")

    @cached_property
    def _transformer(self):
        from pyproj import CRS, Transformer

        return Transformer.from_crs(GEOGRAPHIC_CRS, CRS.from_proj4(self.proj), always_xy=True)

    def to_xy(self, lat, lon) -> tuple[np.ndarray, np.ndarray]:
        """``(x, y)`` in metres of points in degrees (arrays or scalars; NaN stays NaN)."""
        x, y = self._transformer.transform(np.asarray(lon, dtype=float),
                                           np.asarray(lat, dtype=float))
        return np.asarray(x, dtype=float), np.asarray(y, dtype=float)

    def to_latlon(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """``(lat, lon)`` in degrees of points in metres (NaN stays NaN)."""
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        lon, lat = self._transformer.transform(x, y, direction="INVERSE")
        bad = ~(np.isfinite(x) & np.isfinite(y))
        lat, lon = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
        if bad.any():
            lat, lon = np.where(bad, np.nan, lat), np.where(bad, np.nan, lon)
        return lat, lon

    def metadata(self) -> dict:
        """What the log records of the frame (``geo`` in its metadata)."""
        return {"crs": self.proj, "origin": {"lat": self.lat0, "lon": self.lon0},
                "geographic_crs": GEOGRAPHIC_CRS,
                "definition": "local transverse Mercator (WGS 84) centred on the origin: "
                              "x east, y north (m), scale 1 on the central meridian"}

    @classmethod
    def from_metadata(cls, meta: dict | None) -> LocalFrame | None:
        """The frame a log's ``geo`` metadata describes (None without one)."""
        if not meta or "origin" not in meta:
            return None
        return cls(float(meta["origin"]["lat"]), float(meta["origin"]["lon"]))


def grid_centre(lat: np.ndarray, lon: np.ndarray) -> tuple[float, float]:
    """The centre ``(lat, lon)`` of a latitude/longitude grid's box."""
    return 0.5 * (float(lat[0]) + float(lat[-1])), 0.5 * (float(lon[0]) + float(lon[-1]))


def project_grid(lat: np.ndarray, lon: np.ndarray, frame: LocalFrame,
                 resolution: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A regular grid of the local frame inside the projected ``lat``/``lon`` grid (increasing
    axes, degrees): ``(x, y, (lat, lon) of every node)``.

    The rectangle is the largest one aligned with the frame inside the projected box (its
    edges are curves: a meridian's image leans towards the central one). Its nodes are as many
    as the source grid's (``resolution`` None) or spaced by ``resolution`` metres. The
    returned ``(lat, lon)`` arrays, shaped ``[len(y), len(x)]``, are where the caller
    interpolates the source grid.
    """
    # the boundary of the box, densely, in the frame
    lon_edge = np.linspace(lon[0], lon[-1], 4 * lon.size)
    lat_edge = np.linspace(lat[0], lat[-1], 4 * lat.size)
    xw, _ = frame.to_xy(lat_edge, np.full_like(lat_edge, lon[0]))
    xe, _ = frame.to_xy(lat_edge, np.full_like(lat_edge, lon[-1]))
    _, ys = frame.to_xy(np.full_like(lon_edge, lat[0]), lon_edge)
    _, yn = frame.to_xy(np.full_like(lon_edge, lat[-1]), lon_edge)
    x0, x1, y0, y1 = float(xw.max()), float(xe.min()), float(ys.max()), float(yn.min())
    if not (x0 < x1 and y0 < y1):
        raise ValueError("the latitude/longitude grid has no area in the local frame")
    if resolution is None:
        nx, ny = lon.size, lat.size
    else:
        nx = max(int(np.floor((x1 - x0) / resolution)) + 1, 4)
        ny = max(int(np.floor((y1 - y0) / resolution)) + 1, 4)
        x1, y1 = x0 + (nx - 1) * resolution, y0 + (ny - 1) * resolution
    x = np.linspace(x0, x1, nx)
    y = np.linspace(y0, y1, ny)
    X, Y = np.meshgrid(x, y)
    la, lo = frame.to_latlon(X, Y)
    # round-off at the edges: stay inside the source box
    la = np.clip(la, lat[0], lat[-1])
    lo = np.clip(lo, lon[0], lon[-1])
    return x, y, (la, lo)
