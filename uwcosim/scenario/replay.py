"""The ``[replay]`` section: a recorded mission (CSV or Parquet) read into arrays for the filters.

A replay scenario has no FMUs: its measurements, controls and (optional) reference come from
one file, one step per row. ``[replay]`` says where each comes from::

    [replay]
    file = "mission.csv"              # .csv (pyarrow's reader; delimiter) or .parquet
    time = "t"                        # seconds (time_unit: s, ms, min, h) or an Arrow timestamp
    control_row = "previous"          # the row whose controls drive the step to the next row

    [replay.measurements]             # the filters' model's measurement names -> columns
    "dvl.vx_m" = {column = "ve", unit = "knots"}
    "sounder.depth_m" = "depth"       # a plain column name: already in our (SI) unit

    [replay.controls]                 # [model] controls -> columns (a missing value: held)
    psi = {column = "heading", unit = "deg", negate = true, offset = "pi/2"}

    [replay.reference]                # [model] truth signals -> columns (metrics' reference)
    "vehicle.x" = "gps_x"

    [[replay.geographic]]             # lat/lon columns -> x/y columns of the local frame
    lat = "gps_lat"
    lon = "gps_lon"
    x = "gps_x"
    y = "gps_y"

An entry is a column name (values in SI: m, m/s, rad, m/s2) or a table ``{column, unit,
scale, negate, offset, received}``: ``ours = (-1 if negate) * f * value + offset`` with ``f``
from ``unit`` (any unit of :data:`uwcosim.fmi.varmap.UNITS`: m, cm, km, ft, nmi, m/s, cm/s,
mm/s, knots, km/h, ft/s, rad, deg, m/s2, ...; converted to its SI unit) or ``scale``;
``offset`` a number or ``"pi/2"``; ``received``: a flag column (boolean or 0/1) of a
measurement, false meaning lost whatever the value. A measurement is lost where its value is
NaN or missing (an empty CSV cell) or its flag is false; ``missing_columns = "lost"`` makes a
mapped measurement column the file does not have at all never received (default ``"error"``).

Time is read as the file gives it, never accumulated: step ``k`` is row ``k`` (of the rows
``run.start_time`` and ``run.duration`` keep), ``t_k`` its time stamp, strictly increasing;
the filters predict over ``dt_k = t_k - t_{k-1}``. :func:`read_recording` reads and checks
the file: every problem is one line naming the file, the key and the column.
"""

from __future__ import annotations

import difflib
import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pyarrow as pa  # columns cast by their methods: pyarrow.compute loads at a replay only
import pyarrow.csv as pcsv
import pyarrow.parquet as pq
from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictFloat, StrictInt, StrictStr

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.varmap import UNITS, canonical_unit, parse_offset, unit_conversion
from uwcosim.models.geo import LocalFrame

Str = StrictStr


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class ColumnSpec(_Strict):
    """One column of the file and its conversion to our units."""

    column: Str
    unit: Str | None = Field(None, description="the column's unit, converted to SI (m, m/s, "
                             "rad, m/s2); default: already SI")
    scale: StrictFloat | StrictInt | None = Field(None, description="explicit factor instead "
                                                  "of a unit")
    negate: StrictBool = False
    offset: StrictFloat | StrictInt | Str = Field(0.0, description="added after scaling, in "
                                                  "our units (a number or e.g. 'pi/2')")
    received: Str | None = Field(None, description="a flag column (boolean or 0/1): false "
                                 "marks the measurement lost (measurements only)")


Entry = Str | ColumnSpec


class GeographicColumns(_Strict):
    """Two latitude/longitude columns (degrees) made into two columns ``x``, ``y`` (m) of the
    scenario's local frame, which the mappings may then name."""

    lat: Str
    lon: Str
    x: Str
    y: Str


class ReplaySpec(_Strict):
    """``[replay]``: the recorded file and where the filters' inputs are in it."""

    file: Str
    time: Str = "time"
    time_unit: Str = Field("s", description="unit of a numeric time column (s, ms, min, h)")
    delimiter: Str = Field(",", min_length=1, max_length=1, description="CSV field separator")
    measurements: dict[Str, Entry]
    controls: dict[Str, Entry] = {}
    reference: dict[Str, Entry] = {}
    geographic: list[GeographicColumns] = []
    #: which row's controls drive the step from t_{k-1} to t_k
    control_row: Literal["previous", "same"] = Field(
        "previous", description="'previous': the controls of row k-1 are held over the gap "
        "to row k (recorded data); 'same': row k holds the controls applied over the step "
        "that ends at it (a uwcosim log)")
    missing_columns: Literal["error", "lost"] = Field(
        "error", description="a mapped measurement column the file does not have: an error, "
        "or never received")


def replay_problems(spec, where: str) -> list[str]:
    """Cross-references of ``[replay]`` that need no file (one line each, without ``where``):
    the mapped names against ``[model]``, units, derived columns."""
    r = spec.replay
    out: list[str] = []
    why = "a replay has no FMUs: its measurements and controls come from replay.file"
    if spec.run.step is not None:
        out.append("key 'run.step': a replay takes its steps from the file's time column "
                   "(leave run.step out)")
    for key, given in (("fmus", spec.fmus), ("connections", spec.connections),
                       ("noise", spec.noise), ("system", spec.system)):
        if given:
            out.append(f"key '{key}': {why}" + ("; the filters' process noise is model.q_psd"
                                                 if key == "noise" else ""))
    if spec.controls:
        out.append(f"key 'controls': {why} (map the model's controls in replay.controls)")
    for name, sen in spec.sensors.items():
        if sen.noise_inputs or sen.loss is not None or sen.period != 1:
            out.append(f"key 'sensors.{name}': a replay takes only 'outputs' (the measurement "
                       f"names) and 'sigma' (the filters' R); losses and sampling are the "
                       f"file's")
    if spec.model is None or not spec.estimators:
        out.append("key 'model': a replay needs the filters' model and [estimators] (it "
                   "replays the measurements through them)")
    m = spec.model
    if m is not None:
        outputs = [o for s in m.sensors if s in spec.sensors for o in spec.sensors[s].outputs]
        for name in r.measurements:
            if name not in outputs:
                out.append(f"key 'replay.measurements.{name}': not a measurement of the "
                           f"filters' model (model.sensors outputs: {', '.join(outputs)})")
        missing = [o for o in outputs if o not in r.measurements]
        if missing:
            out.append(f"key 'replay.measurements': no column for {', '.join(missing)} "
                       f"(every measurement of model.sensors needs one)")
        for c in m.controls:
            if c not in r.controls:
                out.append(f"key 'model.controls': control {c!r} has no column in "
                           f"replay.controls ({', '.join(r.controls) or 'none'})")
        for c in r.controls:
            if c not in m.controls:
                out.append(f"key 'replay.controls.{c}': not among model.controls "
                           f"({', '.join(m.controls) or 'none'})")
        for name in r.reference:
            if name not in m.truth:
                out.append(f"key 'replay.reference.{name}': not a truth signal of the model "
                           f"(model.truth: {', '.join(m.truth)})")
    for part in ("measurements", "controls", "reference"):
        for name, e in getattr(r, part).items():
            if not isinstance(e, ColumnSpec):
                continue
            key = f"key 'replay.{part}.{name}"
            if e.unit is not None and e.scale is not None:
                out.append(f"{key}': give 'unit' or 'scale', not both")
            try:
                conversion(e, "")
            except ValueError as exc:
                out.append(f"{key}': {exc}")
            if e.received is not None and part != "measurements":
                out.append(f"{key}.received': a received flag is for measurements only")
    if canonical_unit(r.time_unit) not in UNITS or UNITS[canonical_unit(r.time_unit)][1] != "s":
        out.append(f"key 'replay.time_unit': unknown time unit {r.time_unit!r} (expected s, "
                   f"ms, min or h)")
    derived = [n for g in r.geographic for n in (g.x, g.y)]
    dup = sorted({n for n in derived if derived.count(n) > 1})
    if dup:
        out.append(f"key 'replay.geographic': columns {', '.join(dup)} made twice")
    return out


def conversion(e: Entry, where: str) -> tuple[float, float]:
    """``(f, g)``: ``ours = f * value + g`` of an entry; ValueError for a bad unit/offset."""
    if isinstance(e, str):
        return 1.0, 0.0
    if e.scale is not None:
        f = float(e.scale)
    elif e.unit is not None:
        u = canonical_unit(e.unit)
        if u not in UNITS:
            raise ValueError(f"unknown unit {e.unit!r} (known: {', '.join(UNITS)})")
        f, _ = unit_conversion(u, UNITS[u][1])
    else:
        f = 1.0
    try:
        g = parse_offset(e.offset, where or "offset")
    except ScenarioError as exc:
        raise ValueError(str(exc).removeprefix("offset: ")) from None
    return (-f if e.negate else f), g


def read_columns(path: Path, names: Sequence[str], keys: Sequence[str], where: str,
                 delimiter: str = ",") -> list[np.ndarray]:
    """The numeric columns ``names`` of a CSV/Parquet file as float arrays (NaN where empty);
    ``keys``: the scenario key of each, for the messages."""
    if not path.is_file():
        raise ScenarioError(f"{where}: key '{keys[0].rsplit('.', 1)[0]}.file': file not found: "
                            f"{path}")
    table = _read_table(path, delimiter, where, keys[0].rsplit(".", 1)[0] + ".file")
    cols = list(table.column_names)
    out = []
    for name, key in zip(names, keys):
        if name not in cols:
            raise _missing(name, cols, key, where, path)
        out.append(_floats(table, name, key, where, path))
    return out


def _column(e: Entry) -> str:
    return e if isinstance(e, str) else e.column


@dataclass(frozen=True)
class Recording:
    """A replay file read into arrays, one row per step (rows ``run.start_time``/``duration``
    kept): time stamps, measurements (NaN where lost) and their received mask, the controls
    held over each step, the reference (NaN where absent)."""

    path: Path
    sha256: str
    time: np.ndarray  # (n,)
    z: np.ndarray  # (n, nz), NaN where not received
    received: np.ndarray  # (n, nz) bool
    u: np.ndarray  # (n, nu): the controls applied over the step that ends at row k (k >= 1)
    reference: np.ndarray  # (n, nr)
    measurement_names: tuple[str, ...]
    control_names: tuple[str, ...]
    reference_names: tuple[str, ...]
    rows_in_file: int
    first_row: int  # the file's data row of step 0
    notes: list[str] = field(default_factory=list)
    columns: dict = field(default_factory=dict)  # name -> the file column it came from

    @property
    def steps(self) -> int:
        return self.time.size - 1

    def metadata(self) -> dict:
        """What the log records of the recording (``replay`` in its metadata)."""
        dt = np.diff(self.time)
        return {"file": self.path.name, "path": str(self.path), "sha256": self.sha256,
                "rows": int(self.time.size), "rows_in_file": self.rows_in_file,
                "first_row": self.first_row, "columns": self.columns,
                "dt_min_s": float(dt.min()), "dt_max_s": float(dt.max()),
                "dt_median_s": float(np.median(dt))}


def _read_table(path: Path, delimiter: str, where: str, key: str = "replay.file") -> pa.Table:
    suffix = path.suffix.lower()
    try:
        if suffix in (".parquet", ".pq"):
            return pq.read_table(path)
        if suffix in (".csv", ".txt", ".tsv"):
            delim = "\t" if suffix == ".tsv" and delimiter == "," else delimiter
            return _with_bare_names(pcsv.read_csv(
                path, parse_options=pcsv.ParseOptions(delimiter=delim)))
    except (pa.ArrowException, OSError, ValueError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ScenarioError(f"{where}: key '{key}': cannot read {path} ({msg})") from None
    raise ScenarioError(f"{where}: key '{key}': {path}: unknown format {suffix!r} "
                        f"(expected .csv, .tsv or .parquet)")


def _with_bare_names(table: pa.Table) -> pa.Table:
    """A CSV whose header has units (``name [unit]``, as ``uwcosim export --csv`` writes it):
    each such column also under its bare name (unless the file has that name already)."""
    names = table.column_names
    bare = {}
    for n in names:
        m = re.fullmatch(r"(.+) \[[^\[\]]*\]", n)
        if m and m.group(1) not in names and m.group(1) not in bare:
            bare[m.group(1)] = table.column(n)
    for name, col in bare.items():
        table = table.append_column(name, col)
    return table


def _floats(table, name: str, key: str, where: str, path: Path, allow_bool: bool = False):
    col = table.column(name)
    t = col.type
    if pa.types.is_boolean(t) and allow_bool or pa.types.is_integer(t) or \
            pa.types.is_floating(t) or pa.types.is_null(t) or pa.types.is_decimal(t):
        arr = col.cast(pa.float64()) if not pa.types.is_floating(t) or t != pa.float64() \
            else col
        return arr.to_numpy(zero_copy_only=False).astype(float, copy=False)
    raise ScenarioError(f"{where}: key '{key}': column {name!r} of {path} holds {t}, expected "
                        f"numbers")


def _missing(name: str, names: list[str], key: str, where: str, path: Path) -> ScenarioError:
    near = difflib.get_close_matches(name, names, n=1)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
    return ScenarioError(f"{where}: key '{key}': column {name!r} is not in {path} (columns: "
                         f"{shown}{hint})")


def _time(table, spec: ReplaySpec, where: str, path: Path) -> np.ndarray:
    col = table.column(spec.time)
    if pa.types.is_timestamp(col.type):  # seconds since the Unix epoch
        ns = col.cast(pa.timestamp("ns", tz=col.type.tz)).cast(pa.int64())
        t = ns.to_numpy(zero_copy_only=False).astype(float) / 1e9
        if col.null_count:
            t[np.asarray(col.is_null().to_numpy(zero_copy_only=False))] = np.nan
    else:
        t = _floats(table, spec.time, "replay.time", where, path)
        f, _ = unit_conversion(canonical_unit(spec.time_unit), "s")
        t = t * f if f != 1.0 else t
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ScenarioError(f"{where}: key 'replay.time': column {spec.time!r} of {path} has no "
                            f"time at data row {int(bad[0]) + 1}")
    dt = np.diff(t)
    back = np.flatnonzero(dt <= 0)
    if back.size:
        i = int(back[0]) + 1
        what = "repeats" if dt[i - 1] == 0 else "goes back to"
        raise ScenarioError(f"{where}: key 'replay.time': column {spec.time!r} of {path} must "
                            f"increase strictly: data row {i + 1} {what} t={t[i]:.17g} after "
                            f"t={t[i - 1]:.17g} (one row per time stamp)")
    return t


def read_recording(spec: ReplaySpec, base: Path, where: str, *,
                   measurements: Sequence[str], controls: Sequence[str],
                   reference: Sequence[str], frame: LocalFrame | None = None,
                   start_time: float | None = None, duration: float | None = None,
                   start_position: tuple[str, str, float, float] | None = None) -> Recording:
    """Read and check the replay file of ``spec`` (relative to ``base``).

    ``measurements``, ``controls``, ``reference``: the names, in the filters' order, whose
    columns ``spec`` maps (every measurement and control must be mapped; a reference name
    without a column is NaN throughout). ``frame``: the local frame of ``[[geographic]]``
    columns. ``start_time``/``duration``: keep the rows with ``t >= start_time`` and
    ``t <= t_first + duration``. ``start_position``: ``(x name, y name, x, y)`` for the first
    row's reference when it has none (``[geo] start``). Raises ScenarioError with one line
    naming the file, the key and the column.
    """
    path = Path(spec.file)
    path = path if path.is_absolute() else (Path(base) / path).resolve()
    if not path.is_file():
        raise ScenarioError(f"{where}: key 'replay.file': file not found: {path}")
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    table = _read_table(path, spec.delimiter, where)
    names = list(table.column_names)
    if spec.time not in names:
        raise _missing(spec.time, names, "replay.time", where, path)
    t = _time(table, spec, where, path)
    n_file = t.size
    keep = np.ones(n_file, dtype=bool)
    if start_time is not None:
        keep &= t >= start_time
    if duration is not None and keep.any():
        keep &= t <= t[np.argmax(keep)] + duration * (1 + 1e-12)
    rows = np.flatnonzero(keep)
    if rows.size < 2:
        raise ScenarioError(f"{where}: key 'replay.file': {path} has {rows.size} row(s) in the "
                            f"replayed window (run.start_time, run.duration): at least 2 needed")
    first = int(rows[0])
    t = t[rows]
    cols: dict[str, np.ndarray] = {}
    derived: dict[str, tuple[str, int]] = {}
    for i, g in enumerate(spec.geographic):
        key = f"replay.geographic.{i}"
        if frame is None:
            raise ScenarioError(f"{where}: key '{key}': latitude/longitude columns need a "
                                f"geographic frame: [geo] origin or a [map] in latitude/"
                                f"longitude")
        for c in (g.lat, g.lon):
            if c not in names:
                raise _missing(c, names, key, where, path)
        lat = _floats(table, g.lat, key, where, path)[rows]
        lon = _floats(table, g.lon, key, where, path)[rows]
        cols[g.x], cols[g.y] = frame.to_xy(lat, lon)
        derived[g.x], derived[g.y] = (g.lat, i), (g.lon, i)
    notes: list[str] = []
    sources: dict[str, str] = {}

    def values(part: str, name: str, e: Entry, optional: bool = False) -> np.ndarray | None:
        key = f"replay.{part}.{name}"
        c = _column(e)
        if c not in cols:
            if c not in names:
                if optional:
                    return None
                raise _missing(c, names, key, where, path)
            cols[c] = _floats(table, c, key, where, path)[rows]
        try:
            f, g = conversion(e, where)
        except ValueError as exc:
            raise ScenarioError(f"{where}: key '{key}': {exc}") from None
        v = cols[c]
        sources[f"{part}.{name}"] = c if c not in derived else f"{c} (from {derived[c][0]})"
        return v if (f, g) == (1.0, 0.0) else f * v + g

    n = t.size
    z = np.full((n, len(measurements)), np.nan)
    rec = np.zeros((n, len(measurements)), dtype=bool)
    for j, name in enumerate(measurements):
        e = spec.measurements.get(name)
        if e is None:
            raise ScenarioError(f"{where}: key 'replay.measurements': no column for the "
                                f"measurement {name!r} of the filters' model")
        v = values("measurements", name, e, optional=spec.missing_columns == "lost")
        if v is None:
            notes.append(f"replay: measurement {name} has no column {_column(e)!r} in "
                         f"{path.name}: never received")
            continue
        ok = np.isfinite(v)
        flag = e.received if isinstance(e, ColumnSpec) else None
        if flag is not None:
            key = f"replay.measurements.{name}.received"
            if flag not in names:
                raise _missing(flag, names, key, where, path)
            fv = _floats(table, flag, key, where, path, allow_bool=True)[rows]
            ok &= np.nan_to_num(fv, nan=0.0) != 0.0
        rec[:, j] = ok
        z[:, j] = np.where(ok, v, np.nan)
    u_rows = np.zeros((n, len(controls)))
    for j, name in enumerate(controls):
        e = spec.controls.get(name)
        if e is None:
            raise ScenarioError(f"{where}: key 'replay.controls': no column for the control "
                                f"{name!r} of the filters' model")
        v = values("controls", name, e)
        fin = np.isfinite(v)
        if not fin.any():
            raise ScenarioError(f"{where}: key 'replay.controls.{name}': column "
                                f"{_column(e)!r} of {path} has no value")
        idx = np.where(fin, np.arange(n), 0)
        np.maximum.accumulate(idx, out=idx)  # a missing value holds the previous one
        if not fin[0]:
            raise ScenarioError(f"{where}: key 'replay.controls.{name}': column "
                                f"{_column(e)!r} of {path} has no value at the first replayed "
                                f"row (data row {first + 1})")
        u_rows[:, j] = v[idx]
    # the controls held over the step that ends at row k (row 0: its own)
    u = u_rows.copy()
    if spec.control_row == "previous":
        u[1:] = u_rows[:-1]
    ref = np.full((n, len(reference)), np.nan)
    for j, name in enumerate(reference):
        e = spec.reference.get(name)
        if e is not None:
            ref[:, j] = values("reference", name, e)
    if start_position is not None:
        for name, v in zip(start_position[:2], start_position[2:]):
            if name in reference and not np.isfinite(ref[0, list(reference).index(name)]):
                ref[0, list(reference).index(name)] = v
    return Recording(path, sha, t, z, rec, u, ref, tuple(measurements), tuple(controls),
                     tuple(reference), n_file, first, notes, sources)
