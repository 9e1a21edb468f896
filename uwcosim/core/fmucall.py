"""The FMU call in progress in this process: what the run-wide watchdog times and what the
report of a crashed run names.

Every call into an FMU's library (instantiate, enter/exit initialization, set, get, doStep,
event update, reset, terminate, free) is bracketed by :func:`begin` and :func:`end`
(:class:`uwcosim.fmi.adapter.FMUAdapter`, :class:`uwcosim.fmi.proxy.ProxyAdapter`). The record
lives in a small anonymous shared memory page (``mmap``, ``MAP_SHARED``, a :class:`Page`): a
process forked after the page was made writes it, and its parent reads what the child was doing
when it died (:mod:`uwcosim.core.supervise`). Before each fork the parent makes a new page
(:func:`fresh`), so that children running at the same time (a campaign's supervised workers)
each write their own and the parent reads each child's. One record, the outermost call: a call
made inside another (the event update inside a model-exchange step) keeps the outer one's start
time.

Layout: ``t`` (float64, the FMU's time), ``start`` (float64, ``time.monotonic()`` when the call
began), the FMU's index and the call's index (int32; -1: no call); then the FMU names, 64 bytes
each (UTF-8, NUL-padded; longer names are cut).

The record is on the hot path (a few calls per FMU and step): :func:`begin` and :func:`end`
write through typed views of the page, one item at a time, the FMU's index last (a reader that
sees it sees the call's other fields: the watchdog thread reads between two bytecodes, never
inside one), and :func:`end` clears only the FMU's index. Measured in
``benchmarks/bench_master.py --record`` (docs/benchmarks.md).
"""

from __future__ import annotations

import mmap
import struct
import time

#: the calls, by index (the int32 of the record)
CALLS = ("instantiate", "enter initialization", "exit initialization", "set inputs",
         "get outputs", "doStep", "event update", "reset", "terminate", "free instance",
         "load library")
_HEAD = struct.Struct("=ddii")
_NAME = 64
_MAX_FMUS = 60


class Page:
    """One shared page of the record: ``t``, ``start``, the FMU's and the call's index, the
    FMU names."""

    def __init__(self, names: dict[str, int]) -> None:
        self.buf = mmap.mmap(-1, _HEAD.size + 8 + _NAME * _MAX_FMUS)
        _HEAD.pack_into(self.buf, 0, 0.0, 0.0, -1, -1)
        self.times = memoryview(self.buf)[0:16].cast("d")  # t, start
        self.ids = memoryview(self.buf)[16:24].cast("i")  # fmu, call
        for name, i in names.items():
            self.write_name(name, i)

    def write_name(self, name: str, i: int) -> None:
        raw = name.encode("utf-8", "replace")[:_NAME - 1]
        off = _HEAD.size + 8 + i * _NAME
        self.buf[off:off + _NAME] = raw.ljust(_NAME, b"\0")

    def current(self) -> tuple[str, str, float, float] | None:
        """``(fmu, call, t, start)`` of the call in progress on this page, or None."""
        t, start, fmu, call = _HEAD.unpack_from(self.buf, 0)
        if fmu < 0 or not 0 <= call < len(CALLS):
            return None
        off = _HEAD.size + 8 + fmu * _NAME
        name = bytes(self.buf[off:off + _NAME]).split(b"\0", 1)[0].decode("utf-8", "replace")
        return name, CALLS[call], t, start


_names: dict[str, int] = {}
_page = Page(_names)
_TIMES = _page.times
_IDS = _page.ids
_depth = 0
_clock = time.monotonic


def fresh() -> Page:
    """A new page, this process's record from now on (no call in progress, the FMU names
    kept): called before a fork, the child writes it and the parent keeps it to read."""
    global _page, _TIMES, _IDS, _depth
    _page = Page(_names)
    _TIMES, _IDS = _page.times, _page.ids
    _depth = 0
    return _page


def fmu_index(name: str) -> int:
    """The index of the FMU ``name`` in the record (registered on first use)."""
    i = _names.get(name)
    if i is None:
        i = len(_names) % _MAX_FMUS
        _names[name] = i
        _page.write_name(name, i)
    return i


def begin(fmu: int, call: int, t: float) -> None:
    """The FMU ``fmu`` (:func:`fmu_index`) enters the call ``CALLS[call]`` at time ``t``."""
    global _depth
    _depth += 1
    if _depth == 1:
        _TIMES[0] = t
        _TIMES[1] = _clock()
        _IDS[1] = call
        _IDS[0] = fmu  # last: the call is in progress from here


def end() -> None:
    """The call of the last :func:`begin` returned (or raised)."""
    global _depth
    _depth -= 1
    if _depth <= 0:
        _depth = 0
        _IDS[0] = -1


def current() -> tuple[str, str, float, float] | None:
    """``(fmu, call, t, start)`` of the call in progress in this process, or None."""
    return _page.current()


def clear() -> None:
    """Forget the call in progress (a new run, or a forked child's start)."""
    global _depth
    _depth = 0
    _IDS[0] = -1
