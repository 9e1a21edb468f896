"""The FMU call in progress in this process: what the run-wide watchdog times and what the
report of a crashed run names.

Every call into an FMU's library (instantiate, enter/exit initialization, set, get, doStep,
event update, reset, terminate, free) is bracketed by :func:`begin` and :func:`end`
(:class:`uwcosim.fmi.adapter.FMUAdapter`, :class:`uwcosim.fmi.proxy.ProxyAdapter`). The record
lives in a small anonymous shared memory page (``mmap``, ``MAP_SHARED``): a process forked after
this module was imported writes it, and its parent reads what the child was doing when it died
(:mod:`uwcosim.run.supervise`). One record, the outermost call: a call made inside another
(the event update inside a model-exchange step) keeps the outer one's start time.

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
_BUF = mmap.mmap(-1, _HEAD.size + 8 + _NAME * _MAX_FMUS)
_HEAD.pack_into(_BUF, 0, 0.0, 0.0, -1, -1)
_TIMES = memoryview(_BUF)[0:16].cast("d")  # t, start
_IDS = memoryview(_BUF)[16:24].cast("i")  # fmu, call
_names: dict[str, int] = {}
_depth = 0
_clock = time.monotonic


def fmu_index(name: str) -> int:
    """The index of the FMU ``name`` in the record (registered on first use)."""
    i = _names.get(name)
    if i is None:
        i = len(_names) % _MAX_FMUS
        _names[name] = i
        raw = name.encode("utf-8", "replace")[:_NAME - 1]
        off = _HEAD.size + 8 + i * _NAME
        _BUF[off:off + _NAME] = raw.ljust(_NAME, b"\0")
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
    """``(fmu, call, t, start)`` of the call in progress (in this process or, read by its
    parent, in a forked child), or None."""
    t, start, fmu, call = _HEAD.unpack_from(_BUF, 0)
    if fmu < 0 or not 0 <= call < len(CALLS):
        return None
    off = _HEAD.size + 8 + fmu * _NAME
    name = bytes(_BUF[off:off + _NAME]).split(b"\0", 1)[0].decode("utf-8", "replace")
    return name, CALLS[call], t, start


def clear() -> None:
    """Forget the call in progress (a new run, or a forked child's start)."""
    global _depth
    _depth = 0
    _IDS[0] = -1
