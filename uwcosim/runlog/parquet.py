"""Incremental Parquet log of a run, one row per communication step, ``time`` first.

Columns are float64 unless given another numpy dtype (Integer, Boolean, Float32 and String
outputs of FMUs get the matching Arrow type). Rows are buffered in numpy arrays and written as
one row group per chunk, so an interrupted or failed run leaves a readable file with every
chunk written so far (:meth:`RunLogger.close` is called from a ``finally``). The file's
key-value metadata ``uwcosim`` holds the scenario text and hash, the seed, package versions and
the FMUs' sha256; nothing time-of-day dependent is stored, so the same scenario and seed give a
byte-identical log.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from uwcosim.errors import UwcosimError

#: dtypes whose values are passed exactly (not through the float64 row): String, Int64, UInt64
EXACT = (np.dtype(object), np.dtype(np.int64), np.dtype(np.uint64))


def arrow_type(dtype) -> pa.DataType:
    dtype = np.dtype(dtype)
    return pa.string() if dtype == np.dtype(object) else pa.from_numpy_dtype(dtype)


class RunLogger:
    """Collects named columns per step and writes them to ``path``.

    ``dtypes`` gives the numpy dtype of the columns that are not float64; the values of those in
    :data:`EXACT` come through ``append(..., exact=[...])`` in column order, the others through
    the float64 row (exact for int32 and smaller, bool and float32).
    """

    def __init__(self, path: Path, columns: list[str], bool_columns: list[str],
                 metadata: dict, chunk: int = 1000, dtypes: dict | None = None) -> None:
        self.path = Path(path)
        self.columns = ["time", *columns]
        self.bool_columns = list(bool_columns)
        self.chunk = int(chunk)
        self.dtypes = {c: np.dtype(d) for c, d in (dtypes or {}).items()
                       if np.dtype(d) != np.dtype(np.float64)}
        #: columns whose values come exactly, in the order of ``append(..., exact)``
        self.exact_columns = [c for c in self.columns if self.dtypes.get(c) in EXACT]
        self._e: list[list] = [[] for _ in self.exact_columns]
        self._f = np.full((self.chunk, len(self.columns)), np.nan)
        self._b = np.zeros((self.chunk, len(self.bool_columns)), dtype=bool)
        self._n = 0
        self.rows_written = 0
        fields = [pa.field(c, arrow_type(self.dtypes.get(c, np.float64))) for c in self.columns]
        fields += [pa.field(c, pa.bool_()) for c in self.bool_columns]
        self.schema = pa.schema(fields, metadata={"uwcosim": json.dumps(metadata, sort_keys=True)})
        try:
            self._writer = pq.ParquetWriter(self.path, self.schema, compression="zstd")
        except OSError as exc:
            raise UwcosimError(f"{self.path}: cannot write the run log ({exc.strerror or exc})"
                               ) from None

    def append(self, values: np.ndarray, flags: np.ndarray, exact=()) -> None:
        """Append one row: ``values`` in ``columns`` order (time first), ``flags`` booleans,
        ``exact`` the values of :attr:`exact_columns`."""
        self._f[self._n] = values
        self._b[self._n] = flags
        for store, v in zip(self._e, exact):
            store.append(v)
        self._n += 1
        if self._n == self.chunk:
            self.flush()

    def flush(self) -> None:
        if not self._n or self._writer is None:
            return
        n = self._n
        exact = dict(zip(self.exact_columns, self._e))
        arrays = []
        for i, c in enumerate(self.columns):
            dtype = self.dtypes.get(c)
            if c in exact:
                arrays.append(pa.array(exact[c], type=arrow_type(dtype)))
            elif dtype is not None:
                arrays.append(pa.array(self._f[:n, i].astype(dtype)))
            else:
                arrays.append(pa.array(self._f[:n, i]))
        arrays += [pa.array(self._b[:n, i]) for i in range(len(self.bool_columns))]
        self._e = [[] for _ in self.exact_columns]
        self._writer.write_table(pa.Table.from_arrays(arrays, schema=self.schema))
        self.rows_written += n
        self._n = 0
        self._f[:] = np.nan

    def close(self) -> None:
        if self._writer is None:
            return
        try:
            self.flush()
        finally:
            self._writer.close()
            self._writer = None


def read_log(path: str | Path) -> tuple[dict[str, np.ndarray], dict]:
    """Read a run log: ``(columns as numpy arrays, metadata dict)``."""
    path = Path(path)
    if not path.is_file():
        raise UwcosimError(f"{path}: run log not found")
    try:
        table = pq.read_table(path)
    except Exception as exc:  # noqa: BLE001 - pyarrow raises several types for bad files
        raise UwcosimError(f"{path}: not a readable Parquet run log ({exc})") from None
    meta = table.schema.metadata or {}
    info = json.loads(meta.get(b"uwcosim", b"{}"))
    return {name: table.column(name).to_numpy() for name in table.column_names}, info
