"""The rows of a run log that are not in its journal yet, in a file that outlives the process.

:class:`~uwcosim.runlog.parquet.RunLogger` writes a row group (and appends it to the journal)
every ``[log] chunk_steps`` rows (default 1000), and with estimators a row waits for its filter
block (``[run] filter_block``, default 64) before the logger gets it. A process that an FMU
ends (``exit``, ``abort``, a segmentation fault) or ``kill -9`` would lose all of those rows: a
crash at t = 5 s of a default run kept none. So every row is also copied into ``log.parquet.tail``
when it is recorded (its estimates NaN until they come: :meth:`Tail.put` by the recorder) and
again when it is complete (by the logger): a file mapped into memory (``mmap``, shared), whose
stores are in the kernel's page cache and so in the file whatever happens to the process (not
after a power loss). :func:`tail_table` reads them back: the rows of consecutive steps from the
journal's last row on, appended by :func:`uwcosim.runlog.recover_log` and :func:`read_log`.
The tail holds float64 values: its 64-bit integer columns are exact up to 2**53 in magnitude
(null beyond), its String columns null. A clean close removes the file.

Layout: ``MAGIC``, then int64 ``width`` (the value columns, ``time`` first), ``n_flags``,
``capacity`` (slots) and the length of the Arrow schema that follows (padded to 8 bytes);
then ``capacity`` slots of ``1 + width + n_flags`` float64: the step (-1: empty), the values,
the flags (0/1). Step ``k`` is in slot ``k % capacity``: the capacity covers the rows the
logger buffers plus those waiting for a filter block, and a slot whose step is not the one
wanted ends the rows read. The space is reserved when the file is made (``posix_fallocate``:
no ``SIGBUS`` on a full disk); a run whose disk has no room for it runs without a tail.
Cost: a copy of a row per step, two with estimators (``benchmarks/bench_master.py``).
"""

from __future__ import annotations

import mmap
import os
import struct
from pathlib import Path

import numpy as np
import pyarrow as pa

MAGIC = b"UWCTAIL1"
_HEAD = struct.Struct("=8sqqqq")
#: the largest tail file (bytes): above it, fewer slots (the oldest unjournaled rows of a run
#: with huge row groups are then not kept)
MAX_BYTES = 64 << 20


def tail_path(path: str | Path) -> Path:
    """The tail file of the log ``path``."""
    path = Path(path)
    return path.with_name(path.name + ".tail")


class Tail:
    """The tail file of a log being written (see the module docstring)."""

    def __init__(self, path: Path, schema: pa.Schema, width: int, n_flags: int,
                 capacity: int) -> None:
        self.path = Path(path)
        self.width, self.n_flags = int(width), int(n_flags)
        cols = 1 + self.width + self.n_flags
        self.capacity = int(max(1, min(capacity, MAX_BYTES // (8 * cols))))
        blob = schema.serialize().to_pybytes()
        head = _HEAD.pack(MAGIC, self.width, self.n_flags, self.capacity, len(blob))
        head += blob + b"\0" * (-len(blob) % 8)
        size = len(head) + 8 * cols * self.capacity
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            os.posix_fallocate(fd, 0, size)  # the space now: a full disk is an error here
            self._map = mmap.mmap(fd, size)
        except BaseException:
            os.close(fd)
            self.path.unlink(missing_ok=True)
            raise
        os.close(fd)
        self._map[:len(head)] = head
        self._a = np.frombuffer(self._map, np.float64, cols * self.capacity,
                                len(head)).reshape(self.capacity, cols)
        self._a[:, 0] = -1.0
        self._values = slice(1, 1 + self.width)
        self._flags = 1 + self.width

    def put(self, k: int, values: np.ndarray, flags) -> None:
        """Row ``k``: ``values`` (``width``), then ``flags`` (the first ones; the rest 0)."""
        slot = self._a[k % self.capacity]
        slot[self._values] = values
        n = len(flags)
        slot[self._flags:self._flags + n] = flags
        if self._flags + n < slot.size:
            slot[self._flags + n:] = 0.0
        slot[0] = k  # last: a slot kill -9 tore while it took another step is not taken

    def close(self) -> None:
        """Unmap and remove the file (the log is complete)."""
        self._a = None
        self._map.close()
        self.path.unlink(missing_ok=True)


def tail_table(path: str | Path, start: int) -> tuple[pa.Schema, pa.Table | None]:
    """The log's schema, and the rows of the steps ``start``, ``start + 1``, ... of the tail
    file ``path`` (None: not one)."""
    with open(path, "rb") as f:
        data = f.read()
    magic, width, n_flags, capacity, n_blob = _HEAD.unpack_from(data, 0)
    if magic != MAGIC:
        raise ValueError(f"{path}: not a log tail")
    off = _HEAD.size
    schema = pa.ipc.read_schema(pa.py_buffer(data[off:off + n_blob]))
    off += n_blob + (-n_blob % 8)
    cols = 1 + width + n_flags
    a = np.frombuffer(data, np.float64, cols * capacity, off).reshape(capacity, cols)
    steps = []
    k = start
    while len(steps) < capacity and a[k % capacity, 0] == k:
        steps.append(k % capacity)
        k += 1
    if not steps:
        return schema, None
    rows = a[steps]
    arrays = []
    for i, field in enumerate(schema):
        if i < width:
            arrays.append(_column(rows[:, 1 + i], field.type))
        else:
            arrays.append(pa.array(rows[:, 1 + i] != 0.0, type=pa.bool_()))
    return schema, pa.Table.from_arrays(arrays, schema=schema)


def _column(values: np.ndarray, type_: pa.DataType) -> pa.Array:
    """A tail column as the log's type: null where float64 cannot hold the values exactly (a
    String column; a 64-bit integer beyond 2**53, NaN in the tail)."""
    if pa.types.is_string(type_):
        return pa.nulls(len(values), type_)
    if type_ in (pa.int64(), pa.uint64()):
        missing = np.isnan(values)
        ints = np.where(missing, 0.0, values).astype(type_.to_pandas_dtype())
        return pa.array(ints, type=type_, mask=missing)
    with np.errstate(invalid="ignore"):  # an integer column's NaN (never set) -> its cast
        return pa.array(values.astype(np.dtype(type_.to_pandas_dtype())), type=type_)
