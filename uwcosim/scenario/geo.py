"""The ``[geo]`` section: a scenario's geographic frame and positions given in latitude/longitude.

A scenario is georeferenced when it has a geographic origin: ``[geo] origin = {lat, lon}``, or
a ``[map]`` file in latitude/longitude (GEBCO's NetCDF), whose grid centre is then the origin.
Its local frame is :class:`uwcosim.models.geo.LocalFrame` (a transverse Mercator centred on
the origin, metres east/north). A map in metres (``.npz``, a synthetic map) with
``[geo] origin`` is taken to be in that frame: its ``(0, 0)`` is the origin.

- ``[geo] start = {lat, lon}``: the vehicle's position at the start time; in a simulation it
  becomes the start values of the truth's position signals (``[geo] position``, default: the
  ``[model] truth`` signals of the states ``x``, ``y``), e.g. ``fmus.vehicle.start.x`` and
  ``.y``; in a replay it is the reference position of the first row when the file has none
  there (:mod:`uwcosim.scenario.replay`);
- a georeferenced run's log has the latitude and longitude of the truth and of every
  estimate beside ``x``/``y`` (:mod:`uwcosim.runlog.columns`), and its metadata the frame;
- ``[output] trajectory_axes = "latlon"`` labels the trajectory figure in degrees.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, StrictStr

from uwcosim.core.errors import MapError, ScenarioError
from uwcosim.models.geo import LocalFrame
from uwcosim.models.states import MODEL_STATES, position_velocity_indices
from uwcosim.models.terrain import map_frame

# ``loaded`` below is a :class:`uwcosim.scenario.loaded.LoadedScenario` (not imported: the
# schema imports this module, and the loaded scenario the schema)

class LatLon(BaseModel):
    """A geographic position (WGS 84, degrees)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    lat: float = Field(ge=-90.0, le=90.0, strict=True)
    lon: float = Field(ge=-180.0, le=360.0, strict=True)


class GeoSpec(BaseModel):
    """``[geo]``: the geographic origin of the local frame and positions in degrees."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    origin: LatLon | None = Field(None, description="origin of the local frame (default: the "
                                  "centre of a latitude/longitude map)")
    start: LatLon | None = Field(None, description="the vehicle's position at the start time")
    position: tuple[StrictStr, StrictStr] | None = Field(
        None, description="the truth signals the start position sets (default: the [model] "
        "truth signals of the states x, y)")


def position_signals(spec) -> tuple[str, str] | None:
    """The truth's position signals: ``[geo] position``, else the ``[model] truth`` signals
    of the model's position states (built-in models), else None."""
    geo = spec.geo
    if geo is not None and geo.position is not None:
        return tuple(geo.position)
    m = spec.model
    if m is None or m.kind not in MODEL_STATES or len(m.truth) != len(MODEL_STATES[m.kind]):
        return None
    pos = position_velocity_indices(MODEL_STATES[m.kind])[0]
    return (m.truth[pos[0]], m.truth[pos[1]]) if len(pos) == 2 else None


def geo_problems(spec, where: str) -> list[str]:
    """Cross-references of ``[geo]`` that need no file (one line each, without ``where``)."""
    geo = spec.geo
    out = []
    if geo is None or geo.start is None:
        return out
    pos = position_signals(spec)
    if pos is None:
        return ["key 'geo.start': needs the truth's position signals: give geo.position "
                "(e.g. [\"vehicle.x\", \"vehicle.y\"]) or a [model] with its truth"]
    if spec.replay is None:
        for sig in pos:
            fmu, _, var = sig.partition(".")
            if fmu not in spec.fmus:
                out.append(f"key 'geo.position': {sig!r} names no FMU of [fmus] "
                           f"({', '.join(spec.fmus)})")
            elif var in spec.fmus[fmu].start:
                out.append(f"key 'geo.start': the start position is also given as "
                           f"fmus.{fmu}.start.{var}: give it once")
    if geo.origin is None and (spec.map is None or spec.map.kind != "file"):
        out.append("key 'geo.start': needs a geographic origin: geo.origin, or a [map] file "
                   "in latitude/longitude")
    return out


def scenario_frame(loaded) -> LocalFrame | None:
    """The local frame of a scenario (None when it is not georeferenced): ``[geo] origin``,
    else the centre of its latitude/longitude ``[map]`` file."""
    spec = loaded.spec
    geo = getattr(spec, "geo", None)
    try:
        if geo is not None and geo.origin is not None:
            return LocalFrame(geo.origin.lat, geo.origin.lon)
    except ValueError as exc:
        raise ScenarioError(f"{loaded.path}: key 'geo.origin': {exc}") from None
    m = spec.map
    if m is not None and m.kind == "file" and m.projection == "tmerc":
        try:
            return map_frame(loaded.resolve(m.file))
        except MapError:
            return None  # the map's own reading says what is wrong with it
    return None


def start_values(loaded, frame: LocalFrame | None) -> dict[str, dict]:
    """``{fmu: {variable: value}}``: the start values ``[geo] start`` gives (simulation)."""
    spec = loaded.spec
    geo = getattr(spec, "geo", None)
    if geo is None or geo.start is None:
        return {}
    pos = position_signals(spec)
    if frame is None or pos is None:
        raise ScenarioError(f"{loaded.path}: key 'geo.start': needs a geographic origin and "
                            f"the truth's position signals (see uwcosim check)")
    x, y = frame.to_xy(geo.start.lat, geo.start.lon)
    out: dict[str, dict] = {}
    for sig, v in zip(pos, (float(x), float(y))):
        fmu, _, var = sig.partition(".")
        out.setdefault(fmu, {})[var] = v
    return out
