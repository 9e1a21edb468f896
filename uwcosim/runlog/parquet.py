"""Incremental Parquet log of a run, one row per communication step, ``time`` first.

Columns are float64 unless given another numpy dtype (Integer, Boolean, Float32 and String
outputs of FMUs get the matching Arrow type). Rows are buffered in numpy arrays and written as
one row group per chunk, so an interrupted or failed run leaves a readable file with every
chunk written so far (:meth:`RunLogger.close` is called from a ``finally``, or by the signal
watcher of :mod:`uwcosim.core.runguard`; the writer is lock-protected for that).

A process killed outright (``kill -9``, power loss of the process) never writes the Parquet
footer, so ``log.parquet`` is then unreadable. Each row group is therefore also appended to a
side file ``log.parquet.journal`` (an Arrow IPC stream, written unbuffered when the row group
is): :func:`read_log` falls back to it and returns every finished row group, and
:func:`recover_log` rewrites a proper ``log.parquet`` from it. The rows not in a row group yet
(and those waiting for their filter block) are in a third file, ``log.parquet.tail``
(:mod:`uwcosim.runlog.tail`, memory-mapped): both read it after the journal, so a process an
FMU ends keeps its rows up to the crash. A clean close removes both side files.

The file's key-value metadata ``uwcosim`` holds the scenario text and hash, the seed, package
versions and the FMUs' sha256; nothing time-of-day dependent is stored, so the same scenario
and seed give a byte-identical log.
"""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from uwcosim.core.errors import UwcosimError
from uwcosim.runlog.tail import Tail, tail_path, tail_table
from uwcosim.runlog.units import units_of, with_units

if TYPE_CHECKING:
    import pandas as pd

#: dtypes whose values are passed exactly (not through the float64 row): String, Int64, UInt64
EXACT = (np.dtype(object), np.dtype(np.int64), np.dtype(np.uint64))
#: every integer of at most this magnitude is exactly a float64
EXACT_FLOAT = 2 ** 53


def arrow_type(dtype: np.typing.DTypeLike) -> pa.DataType:
    dtype = np.dtype(dtype)
    return pa.string() if dtype == np.dtype(object) else pa.from_numpy_dtype(dtype)


def arrow_array(values: np.ndarray) -> pa.Array:
    """A 1-D numpy array of numbers or booleans as an Arrow array without nulls (NaN stays NaN),
    the values ``pa.array(values)`` gives, built from its buffers: ``pa.array`` imports pandas
    on its first call (to look for pandas objects), 0.3-0.7 s of a short run."""
    values = np.ascontiguousarray(values)
    if values.dtype == np.bool_:
        data = np.packbits(values, bitorder="little")
        return pa.Array.from_buffers(pa.bool_(), len(values), [None, pa.py_buffer(data)])
    return pa.Array.from_buffers(pa.from_numpy_dtype(values.dtype), len(values),
                                 [None, pa.py_buffer(values)])


class RunLogger:
    """Collects named columns per step and writes them to ``path``.

    ``dtypes`` gives the numpy dtype of the columns that are not float64; the values of those in
    :data:`EXACT` come through ``append(..., exact=[...])`` in column order, the others through
    the float64 row (exact for int32 and smaller, bool and float32). ``units``: the unit of
    each column that has one, written as its field metadata ``unit``
    (:mod:`uwcosim.runlog.units`). ``pending``: how many rows may be recorded
    (:meth:`stage`) before the logger gets them (a filter block), for the size of the tail
    file (:mod:`uwcosim.runlog.tail`); ``tail=False``: none (the benchmark of its cost).
    """

    def __init__(self, path: Path, columns: list[str], bool_columns: list[str],
                 metadata: dict, chunk: int = 1000, dtypes: dict | None = None,
                 units: dict[str, str] | None = None, pending: int = 0,
                 tail: bool = True) -> None:
        self.path = Path(path)
        self.columns = ["time", *columns]
        self.bool_columns = list(bool_columns)
        self.chunk = int(chunk)
        self.dtypes = {c: np.dtype(d) for c, d in (dtypes or {}).items()
                       if np.dtype(d) != np.dtype(np.float64)}
        #: columns whose values come exactly, in the order of ``append(..., exact)``
        self.exact_columns = [c for c in self.columns if self.dtypes.get(c) in EXACT]
        #: (row position, position in ``exact``) of the 64-bit integer columns: the tail file
        #: holds their values as float64 where that is exact (``|v| <= 2**53``)
        self._exact_ints = [(self.columns.index(c), j) for j, c in enumerate(self.exact_columns)
                            if self.dtypes[c] != np.dtype(object)]
        self._e: list[list] = [[] for _ in self.exact_columns]
        self._f = np.full((self.chunk, len(self.columns)), np.nan)
        self._b = np.zeros((self.chunk, len(self.bool_columns)), dtype=bool)
        self._n = 0
        self.rows_written = 0
        self.last_time = float("nan")  # time of the last appended row
        self._lock = threading.Lock()
        self.journal_path = journal_path(self.path)
        self._journal = self._journal_file = None
        fields = [pa.field(c, arrow_type(self.dtypes.get(c, np.float64))) for c in self.columns]
        fields += [pa.field(c, pa.bool_()) for c in self.bool_columns]
        fields = [with_units(f, units or {}) for f in fields]
        self.schema = pa.schema(fields, metadata={"uwcosim": json.dumps(metadata, sort_keys=True)})
        try:
            self._writer = pq.ParquetWriter(self.path, self.schema, compression="zstd")
            self._journal_file = open(self.journal_path, "wb", buffering=0)  # noqa: SIM115
            self._journal = pa.ipc.new_stream(self._journal_file, self.schema)
        except OSError as exc:
            raise UwcosimError(f"{self.path}: cannot write the run log ({exc.strerror or exc})"
                               ) from None
        self._tail = None
        try:  # best effort: a disk without room for it still gets the log
            if tail:
                self._tail = Tail(tail_path(self.path), self.schema, len(self.columns),
                                  len(self.bool_columns), self.chunk + int(pending) + 1)
        except OSError:
            pass

    def stage(self, k: int, values: np.ndarray, flags: Sequence[bool],
              exact: Sequence = ()) -> None:
        """Row ``k`` as recorded so far (``values`` NaN where it waits for estimates; the
        first ``flags``; ``exact`` as :meth:`append`'s): kept in the tail file only, until
        :meth:`append` gets it whole."""
        if self._tail is not None:
            self._tail.put(k, self._tail_row(values, exact), flags)

    def _tail_row(self, values: np.ndarray, exact: Sequence) -> np.ndarray:
        """``values`` with the 64-bit integer columns' values where float64 holds them
        exactly (NaN, read back as null, where it does not or none was given)."""
        if not self._exact_ints or not exact:
            return values
        row = np.array(values, dtype=np.float64)
        for i, j in self._exact_ints:
            v = exact[j]
            row[i] = float(v) if v is not None and -EXACT_FLOAT <= v <= EXACT_FLOAT else np.nan
        return row

    def append(self, values: np.ndarray, flags: np.ndarray, exact: Sequence = ()) -> None:
        """Append one row: ``values`` in ``columns`` order (time first), ``flags`` booleans,
        ``exact`` the values of :attr:`exact_columns`."""
        with self._lock:
            if self._writer is None:  # closed by the signal watcher
                return
            self._f[self._n] = values
            self._b[self._n] = flags
            if self._tail is not None:
                self._tail.put(self.rows_written + self._n, self._tail_row(values, exact), flags)
            for store, v in zip(self._e, exact):
                store.append(v)
            self._n += 1
            self.last_time = float(values[0])
            if self._n == self.chunk:
                self._flush()

    def flush(self) -> None:
        with self._lock:
            self._flush()

    def _flush(self) -> None:
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
                arrays.append(arrow_array(self._f[:n, i].astype(dtype)))
            else:
                arrays.append(arrow_array(self._f[:n, i]))
        arrays += [arrow_array(self._b[:n, i]) for i in range(len(self.bool_columns))]
        self._e = [[] for _ in self.exact_columns]
        table = pa.Table.from_arrays(arrays, schema=self.schema)
        self._writer.write_table(table)
        self._journal.write_table(table)
        self.rows_written += n
        self._n = 0
        self._f[:] = np.nan

    def close(self) -> None:
        with self._lock:
            if self._writer is None:
                return
            try:
                self._flush()
            finally:
                self._writer.close()
                self._writer = None
                self._journal.close()
                self._journal_file.close()
                os.unlink(self.journal_path)
                if self._tail is not None:
                    self._tail.close()
                    self._tail = None


def numpy_column(column: pa.ChunkedArray) -> np.ndarray:
    """A column as numpy, the values ``column.to_numpy()`` gives; read from the buffers for
    numbers and booleans without nulls (``to_numpy`` imports pandas on its first call)."""
    t = column.type
    if column.null_count or not (pa.types.is_floating(t) or pa.types.is_integer(t)
                                 or pa.types.is_boolean(t)):
        return column.to_numpy()
    if pa.types.is_boolean(t):
        dtype = np.dtype(bool)
    else:
        kind = "f" if pa.types.is_floating(t) else "i" if pa.types.is_signed_integer(t) else "u"
        dtype = np.dtype(f"{kind}{t.bit_width // 8}")
    parts = []
    for chunk in column.chunks:
        buf = chunk.buffers()[1]
        if dtype == np.dtype(bool):
            bits = np.unpackbits(np.frombuffer(buf, np.uint8), bitorder="little")
            parts.append(bits[chunk.offset:chunk.offset + len(chunk)].astype(bool))
        else:
            parts.append(np.frombuffer(buf, dtype, len(chunk), chunk.offset * dtype.itemsize))
    return np.concatenate(parts) if parts else np.empty(0, dtype)


def journal_path(path: str | Path) -> Path:
    """The side file that keeps the finished row groups of ``path`` until it is closed."""
    path = Path(path)
    return path.with_name(path.name + ".journal")


def read_journal(path: str | Path) -> pa.Table:
    """Every complete row group of a journal (a torn last message is dropped)."""
    batches, schema = [], None
    with open(path, "rb") as f:
        try:
            reader = pa.ipc.open_stream(f)
            schema = reader.schema
            while True:
                try:
                    batches.append(reader.read_next_batch())
                except StopIteration:
                    break
        except (pa.ArrowInvalid, OSError):
            pass  # torn tail
    if schema is None:
        raise UwcosimError(f"{path}: journal has no complete schema")
    return pa.Table.from_batches(batches, schema=schema)


def _read_table(path: Path) -> pa.Table:
    try:  # ParquetFile: pq.read_table goes through pyarrow.dataset, which imports pandas
        with pq.ParquetFile(path) as f:
            return f.read()
    except Exception as exc:  # noqa: BLE001 - pyarrow raises several types for bad files
        if unfinished(path):  # the writer was killed before it wrote the footer
            return read_unfinished(path)
        raise UwcosimError(f"{path}: not a readable Parquet run log ({exc})") from None


def unfinished(path: str | Path) -> bool:
    """True when the log ``path`` has a journal or a tail file (its writer did not close it)."""
    return journal_path(path).is_file() or tail_path(path).is_file()


def read_unfinished(path: str | Path) -> pa.Table:
    """The rows of a log whose writer did not close it: every finished row group (the
    journal), then the tail file's rows that follow (:mod:`uwcosim.runlog.tail`)."""
    path = Path(path)
    journal, tail = journal_path(path), tail_path(path)
    table = None
    try:
        table = read_journal(journal)
    except (UwcosimError, OSError):
        if not tail.is_file():
            raise
    try:
        _, rows = tail_table(tail, table.num_rows if table is not None else 0)
    except (OSError, ValueError, pa.ArrowException):  # none, or not a tail: the journal's
        rows = None
    if table is None:
        if rows is None:
            raise UwcosimError(f"{journal}: journal has no complete schema")
        return rows
    return table if rows is None else pa.concat_tables([table, rows.cast(table.schema)])


def recover_log(path: str | Path) -> int:
    """Rewrite ``path`` from its journal and tail after the writer was killed; returns the
    rows kept."""
    path = Path(path)
    table = read_unfinished(path)
    pq.write_table(table, path, compression="zstd")
    for side in (journal_path(path), tail_path(path)):
        side.unlink(missing_ok=True)
    return table.num_rows


def read_log(path: str | Path, as_dataframe: bool = False
             ) -> tuple[dict[str, np.ndarray], dict] | pd.DataFrame:
    """Read a run log: ``(columns as numpy arrays, metadata dict)``; with ``as_dataframe`` a
    ``pandas.DataFrame`` (pandas: the optional extra ``uwcosim[pandas]``) with the columns'
    units in ``df.attrs["units"]`` (``{column: unit}``) and the metadata in
    ``df.attrs["uwcosim"]``. A log whose writer was killed (no Parquet footer) is read from its
    journal: every finished row group."""
    path = Path(path)
    if not path.is_file():
        raise UwcosimError(f"{path}: run log not found")
    table = _read_table(path)
    meta = table.schema.metadata or {}
    info = json.loads(meta.get(b"uwcosim", b"{}"))
    if as_dataframe:
        return to_dataframe(table, info)
    return {name: numpy_column(table.column(name)) for name in table.column_names}, info


def read_units(path: str | Path) -> dict[str, str]:
    """``{column: unit}`` of a run log (the columns that carry a unit)."""
    path = Path(path)
    if not path.is_file():
        raise UwcosimError(f"{path}: run log not found")
    return units_of(_read_table(path).schema)


def to_dataframe(table: pa.Table, info: dict) -> pd.DataFrame:
    """A log's table as a ``pandas.DataFrame``, its units and metadata in ``attrs``."""
    try:
        import pandas  # noqa: F401 - optional dependency: only the DataFrame needs it
    except ImportError:
        raise UwcosimError("read_log(..., as_dataframe=True) needs pandas: pip install "
                           "'uwcosim[pandas]'") from None
    df = table.replace_schema_metadata(None).to_pandas()
    df.attrs["units"] = units_of(table.schema)
    df.attrs["uwcosim"] = info
    return df
