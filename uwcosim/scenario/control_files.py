"""``[controls.NAME] file = ...``: a control's time table read from a CSV or Parquet file.

The master's :class:`~uwcosim.master.system.Control` takes a table ``[[t, value], ...]``; a
scenario may instead name a file and its columns::

    [controls.a]
    target = "vehicle.a"
    file = "thrust.csv"        # .csv (pyarrow's reader) or .parquet
    time = "t"                 # the time column (default "time"; time_unit s, ms, min, h)
    column = "accel"           # the value column (unit, scale, negate, offset as in [replay])
    interpolation = "hold"     # or "linear"

Two rows with the same time are a step discontinuity (the value jumps there), as in an
inline ``table`` and as fmpy's ``simulate_fmu(input=...)`` and OMSimulator read input files.
The file is read by the scenario layer when the scenario becomes the master's system
(:func:`control_table`, from :func:`uwcosim.scenario.system.to_system`); the master gets the
table. Every problem is one line naming the file, the key and the column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field, model_validator
from pydantic.dataclasses import dataclass as record

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.varmap import UNITS, canonical_unit, unit_conversion
from uwcosim.master.system import RECORD_CONFIG, Bool, Control, Float, Int, Str, table_problem
from uwcosim.scenario.replay import ColumnSpec, conversion, read_columns


@record(config=RECORD_CONFIG)
class ControlSpec(Control):
    """A scenario's ``[controls.NAME]``: the master's control, or a table read from a file."""

    file: Str | None = None
    time: Str = "time"
    time_unit: Str = "s"
    column: Str | None = None
    delimiter: Str = Field(",", min_length=1, max_length=1)
    unit: Str | None = None
    scale: Float | Int | None = None
    negate: Bool = False
    offset: Float | Int | Str = 0.0

    @model_validator(mode="after")
    def _one_kind(self) -> ControlSpec:
        kinds = [k for k in ("table", "waypoints", "file") if getattr(self, k) is not None]
        if len(kinds) != 1:
            raise ValueError("give exactly one of 'table' or 'waypoints' (or 'file' with its "
                             "'column')")
        if self.table is not None:
            problem = table_problem(self.table)
            if problem:
                raise ValueError(problem)
        if self.waypoints is not None and len(self.waypoints) < 1:
            raise ValueError("'waypoints' needs at least one [x, y] point")
        if self.file is not None and self.column is None:
            raise ValueError("'file' needs 'column' (the column of the values)")
        if self.file is None and self.column is not None:
            raise ValueError("'column' is for a control read from a 'file'")
        if self.unit is not None and self.scale is not None:
            raise ValueError("give 'unit' or 'scale', not both")
        return self

    def entry(self) -> ColumnSpec:
        """The value column as a replay entry (same conversions)."""
        return ColumnSpec(column=self.column, unit=self.unit, scale=self.scale,
                          negate=self.negate, offset=self.offset)


def control_table(name: str, c: Control, base: Path, where: str) -> Control:
    """The master's control of ``[controls.NAME]``: ``c`` itself, or for a file control the
    same control with the file's rows as its ``table``."""
    if not isinstance(c, ControlSpec):
        return c
    plain = {k: getattr(c, k) for k in ("target", "table", "waypoints", "interpolation",
                                        "position", "acceptance_radius")}
    if c.file is None:
        return Control(**plain)
    plain["table"] = read_table_file(c, base, where, f"controls.{name}")
    return Control(**plain)


def read_table_file(c: ControlSpec, base: Path, where: str, key: str) -> list[list[float]]:
    """``[[t, value], ...]`` from ``c.file``'s time and value columns (converted units)."""
    path = Path(c.file)
    path = path if path.is_absolute() else (Path(base) / path).resolve()
    t, v = read_columns(path, [c.time, c.column], [f"{key}.time", f"{key}.column"], where,
                        c.delimiter)
    u = canonical_unit(c.time_unit)
    if u not in UNITS or UNITS[u][1] != "s":
        raise ScenarioError(f"{where}: key '{key}.time_unit': unknown time unit "
                            f"{c.time_unit!r} (expected s, ms, min or h)")
    t = t * unit_conversion(u, "s")[0]
    try:
        f, g = conversion(c.entry(), where)
    except ValueError as exc:
        raise ScenarioError(f"{where}: key '{key}': {exc}") from None
    v = f * v + g
    bad = np.flatnonzero(~(np.isfinite(t) & np.isfinite(v)))
    if bad.size:
        raise ScenarioError(f"{where}: key '{key}': {path} has no time or value at data row "
                            f"{int(bad[0]) + 1} (columns {c.time!r}, {c.column!r})")
    table = [[float(a), float(b)] for a, b in zip(t, v)]
    problem = table_problem(table)
    if problem:
        raise ScenarioError(f"{where}: key '{key}.file': {path}: "
                            f"{problem.replace(chr(39) + 'table' + chr(39), 'the rows')}")
    return table

