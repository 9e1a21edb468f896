"""The unit of every column of a run's log, kept in the Parquet schema's field metadata.

Each float column of a log whose unit is known carries the field metadata ``unit`` (UTF-8, the
FMI/Modelica unit string: ``m``, ``m/s``, ``rad``; ``1`` for a dimensionless number):

- ``time``: ``s``;
- a logged signal: the unit its FMU's model description declares for it (the variable's own
  ``unit`` or its ``declaredType``'s; a variable map's role: the role's unit; a master's source:
  the unit of the FMU input it drives), see :meth:`uwcosim.master.master.Master.signal_unit`;
- a measurement ``z.NAME``: the unit of the signal ``NAME``;
- an estimator's mean ``est.E.STATE``: the unit of the truth signal of ``STATE`` (the model's
  ``truth`` list), its variance ``est.E.var.STATE`` that unit squared (``m2``, ``m2/s2``), its
  ``nis`` and ``nees`` ``1``;
- latitude and longitude: ``deg``.

Boolean flags and columns whose unit nothing declares have no ``unit`` entry. The data columns
and the file's ``uwcosim`` metadata are not changed by it. :func:`units_of` reads the units back
from a schema.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence

import pyarrow as pa

from uwcosim.runlog import columns
from uwcosim.runlog.columns import LogLayout

#: the field metadata key
UNIT_KEY = b"unit"

_SYMBOL = re.compile(r"[A-Za-z]+")


def squared(unit: str) -> str:
    """``unit`` squared in the FMI/Modelica unit syntax: ``m`` -> ``m2``, ``m/s`` -> ``m2/s2``,
    ``rad`` -> ``rad2``, ``1`` -> ``1``; anything else ``(unit)2``."""
    if unit == "1":
        return unit
    parts = unit.split("/")
    if all(_SYMBOL.fullmatch(p) for p in parts):
        return "/".join(f"{p}2" for p in parts)
    return f"({unit})2"


def layout_units(layout: LogLayout, signal_unit: Callable[[str], str | None],
                 truth: Sequence[str] = ()) -> dict[str, str]:
    """The known units of a log's float columns (``time`` included): ``signal_unit(name)`` the
    unit of a bus signal, ``truth`` the truth signal of each state (in ``layout.states``
    order)."""
    out: dict[str, str | None] = {columns.TIME: "s"}
    for s in layout.signals:
        out[s] = signal_unit(s)
    for m in layout.measurements:
        out[columns.measurement(m)] = signal_unit(m)
    state_units = {state: signal_unit(sig) for state, sig in zip(layout.states, truth)}
    for e in layout.estimators:
        for state in layout.states:
            u = state_units.get(state)
            out[columns.estimate(e, state)] = u
            out[columns.variance(e, state)] = squared(u) if u else None
        out[columns.nis(e)] = out[columns.nees(e)] = "1"
    if layout.geo:
        for owner in (columns.TRUTH, *layout.estimators):
            out[columns.latitude(owner)] = out[columns.longitude(owner)] = "deg"
    return {c: u for c, u in out.items() if u}


def with_units(field: pa.Field, units: Mapping[str, str]) -> pa.Field:
    """``field`` with its ``unit`` metadata, if ``units`` knows it."""
    unit = units.get(field.name)
    return field if not unit else field.with_metadata({UNIT_KEY: unit.encode()})


def units_of(schema: pa.Schema) -> dict[str, str]:
    """``{column: unit}`` of the columns of ``schema`` that carry one."""
    return {f.name: f.metadata[UNIT_KEY].decode() for f in schema
            if f.metadata and UNIT_KEY in f.metadata}


def labelled(name: str, units: Mapping[str, str]) -> str:
    """``name [unit]`` (the CSV header), or ``name`` without a unit."""
    unit = units.get(name)
    return f"{name} [{unit}]" if unit else name
