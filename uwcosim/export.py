"""Export a run's log to CSV (pyarrow's writer) or MATLAB ``.mat`` (scipy's ``savemat``).

CSV: one header row with the log's column names (``time`` first, quoted), each followed by its
unit in brackets when it has one (``"time [s]"``, ``"vehicle.x [m]"``, ``"est.ekf.var.vx
[m2/s2]"``, the flags bare; the units of :mod:`uwcosim.runlog.units`; ``units=False``: the bare
names), one row per
communication step, floats with full precision, NaN as ``nan``, booleans as ``true``/``false``
(as pyarrow writes them).

MAT (version 5): ``data`` (steps x columns, booleans as 0/1), ``columns`` (the column names, a
cell array), ``log`` (a struct with one field per column: the name with every character that is
not a letter, digit or underscore replaced by ``_``, shortened to MATLAB's 63 characters and made
unique with a numeric suffix) and ``metadata`` (the log's ``uwcosim`` metadata as JSON text).

A log whose writer was killed (no Parquet footer) is exported from its journal
(``log.parquet.journal``: every finished row group) and tail file (the rows after them), as
``report`` and ``regress`` read it.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from uwcosim.core.errors import UwcosimError
from uwcosim.runlog.parquet import read_unfinished, unfinished
from uwcosim.runlog.units import labelled, units_of

MATLAB_NAME_MAX = 63


def _log_path(run: str | Path) -> Path:
    run = Path(run)
    path = run / "log.parquet" if run.is_dir() else run
    if not path.is_file():
        raise UwcosimError(f"{path}: run log not found")
    return path


def _read(run: str | Path):
    path = _log_path(run)
    try:
        return path, pq.read_table(path)
    except Exception as exc:  # noqa: BLE001 - pyarrow raises several types for bad files
        if unfinished(path):  # the run was killed before the footer: as read_log
            return path, read_unfinished(path)
        raise UwcosimError(f"{path}: not a readable Parquet run log ({exc})") from None


def matlab_names(columns: list[str]) -> list[str]:
    """Valid, unique MATLAB identifiers for ``columns`` (see the module docstring)."""
    out: list[str] = []
    seen: set[str] = set()
    for c in columns:
        name = re.sub(r"\W", "_", c, flags=re.ASCII)
        if not name or not name[0].isalpha():
            name = "v_" + name
        name = name[:MATLAB_NAME_MAX]
        base, i = name, 1
        while name in seen:
            suffix = f"_{i}"
            name = base[:MATLAB_NAME_MAX - len(suffix)] + suffix
            i += 1
        seen.add(name)
        out.append(name)
    return out


def export_csv(run: str | Path, out: str | Path | None = None, units: bool = True) -> Path:
    """Write the log of ``run`` (a run directory or a ``.parquet`` log) as CSV; ``units``: the
    header names ``name [unit]``."""
    import pyarrow.csv as pcsv

    path, table = _read(run)
    out = Path(out) if out is not None else path.with_suffix(".csv")
    if units:
        known = units_of(table.schema)
        table = table.rename_columns([labelled(c, known) for c in table.column_names])
    try:
        pcsv.write_csv(table.replace_schema_metadata(None), out)
    except OSError as exc:
        raise UwcosimError(f"{out}: cannot write ({exc.strerror or exc})") from None
    return out


def export_mat(run: str | Path, out: str | Path | None = None) -> Path:
    """Write the log of ``run`` as a MATLAB v5 ``.mat`` file."""
    from scipy.io import savemat

    path, table = _read(run)
    out = Path(out) if out is not None else path.with_suffix(".mat")
    columns = table.column_names
    for c in columns:
        kind = np.asarray(table.column(c).to_numpy(zero_copy_only=False)).dtype.kind
        if kind not in "fiub":
            raise UwcosimError(f"{path}: column {c!r} is not numeric or boolean; a .mat export "
                               f"holds numbers only (use --csv)")
    arrays = [np.asarray(table.column(c).to_numpy(), dtype=float) for c in columns]
    data = np.column_stack(arrays) if arrays else np.zeros((0, 0))
    meta = (table.schema.metadata or {}).get(b"uwcosim", b"{}").decode()
    content = {
        "data": data,
        "columns": np.array(columns, dtype=object),
        "log": dict(zip(matlab_names(columns), arrays)),
        "metadata": json.dumps(json.loads(meta), sort_keys=True),
    }
    try:
        with open(out, "wb") as fh:  # scipy turns an OSError on a path into a ValueError
            savemat(fh, content, do_compression=True, oned_as="column")
    except OSError as exc:
        raise UwcosimError(f"{out}: cannot write ({exc.strerror or exc})") from None
    return out
