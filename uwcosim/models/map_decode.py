"""Reading a NetCDF map's variables as CF says they are encoded, and what a map may cost.

A NetCDF variable is stored packed: ``value = raw * scale_factor + add_offset``, with cells
that hold ``_FillValue`` (or ``missing_value``) meaning "no data", and its ``units``. Read raw,
GEBCO's ``_FillValue = -32767`` was an elevation (32767 m depths) and ``units = "km"`` metres.
:func:`decode` applies the packing, turns fill cells into NaN and converts lengths to metres
(``m``, ``km``, ``ft``; other length units of the depth or an axis are refused, as are axes in
other units than degrees for ``lon``/``lat``).

Fill cells are not filled in: a map must give a depth at every node (the terrain between
nodes is a spline through all of them), so a map with no-data cells is refused in one line
naming how many there are and the first one (crop the map to the surveyed area, or fill the
gaps in a GIS tool by a rule you choose). Maps in ``.npz`` give NaN for no data and are
refused the same way.

:func:`map_memory_problem`: a map costs about :data:`BYTES_PER_CELL` bytes per node in a run
(the grid, its spline coefficients, their padded copy, the FMU's file and its copy, the
filters' spline); it is refused above :func:`uwcosim.core.memory.memory_limit` before its
data is read.
"""

from __future__ import annotations

import numpy as np

from uwcosim.core.memory import memory_problem

#: about what one map node costs in a run (a 3000 x 3000 map: 102 bytes per node to load it
#: and make its spline and CasADi function; a whole run of a 12000 x 12000 map took 23 GB)
BYTES_PER_CELL = 160.0

_METRES = {"m": 1.0, "meter": 1.0, "meters": 1.0, "metre": 1.0, "metres": 1.0,
           "km": 1000.0, "kilometer": 1000.0, "kilometers": 1000.0, "kilometre": 1000.0,
           "kilometres": 1000.0, "ft": 0.3048, "feet": 0.3048, "foot": 0.3048}
#: variables whose values are lengths (depth candidates and metric axes)
LENGTHS = ("depth", "elevation", "z", "x", "y")
DEGREES = ("lon", "lat")
#: the attributes :func:`decode` reads
CF_KEYS = ("_FillValue", "missing_value", "scale_factor", "add_offset", "units")


def _text(v) -> str:
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    return str(v).strip()


def decode(name: str, raw: np.ndarray, attrs: dict, where: str, is_length: bool
           ) -> tuple[np.ndarray, int, object]:
    """``(values, n_fill, fill)``: ``raw`` unpacked (float), fill cells NaN, a length in
    metres. ``is_length``: the variable is the depth or a metric axis (its ``units`` must be
    a length unit)."""
    raw = np.asarray(raw)
    mask = np.zeros(raw.shape, bool)
    fill = None
    for key in ("_FillValue", "missing_value"):
        if key in attrs:
            for f in np.atleast_1d(np.asarray(attrs[key])):
                if raw.dtype.kind in "fc" and np.isnan(f):
                    mask |= np.isnan(raw)
                else:
                    mask |= raw == f
                fill = f if fill is None else fill
    values = raw.astype(float)
    scale = float(np.asarray(attrs.get("scale_factor", 1.0)).ravel()[0])
    offset = float(np.asarray(attrs.get("add_offset", 0.0)).ravel()[0])
    if (scale, offset) != (1.0, 0.0):
        values = values * scale + offset  # value = raw * scale_factor + add_offset (CF 8.1)
    values[mask] = np.nan
    units = _text(attrs.get("units", ""))
    if is_length and units:
        factor = _METRES.get(units.lower())
        if factor is None:
            raise ValueError(f"{where}: variable {name!r} has units {units!r}; expected a "
                             f"length in m, km or ft")
        if factor != 1.0:
            values = values * factor
    if name in DEGREES and units and not units.lower().startswith("degree"):
        raise ValueError(f"{where}: variable {name!r} has units {units!r}; expected degrees")
    return values, int(mask.sum()), fill


def fill_problem(name: str, values: np.ndarray, n_fill: int, fill, where: str) -> str | None:
    """The one-line refusal of a depth grid with no-data cells, or None."""
    if not n_fill:
        return None
    j, i = (int(k[0]) for k in np.nonzero(np.isnan(values)))
    return (f"{where}: {n_fill} of the {values.size} cells of {name!r} hold its fill value "
            f"{np.asarray(fill).item():g} (no data), the first at row {j}, column {i}: a map "
            f"needs a depth at every node (crop it to the surveyed area, or fill the gaps)")


def map_memory_problem(shape: tuple[int, ...], where: str) -> str | None:
    """The one-line refusal of a map grid too large for the memory limit, or None."""
    cells = float(np.prod(np.asarray(shape, dtype=float)))
    dims = " x ".join(str(int(n)) for n in shape)
    return memory_problem(cells * BYTES_PER_CELL, f"{where}: a map of {dims} cells",
                          "crop the map to the area the mission can reach, or coarsen it")
