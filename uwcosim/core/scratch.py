"""Scratch folders of a run (unzipped FMUs, extracted SSP members), removed on every exit.

A folder made by :func:`make` is removed by :func:`remove` (its owner's ``close``), at the
owner's garbage collection (:class:`Scratch`), at interpreter exit, and also when the process
ends with ``os._exit`` after the signal guard or the run-wide FMU watchdog
(:mod:`uwcosim.core.runguard` calls :func:`remove_all` first): ``atexit`` handlers and
finalizers do not run then, and the unzipped FMUs of every such run were left in the temporary
folder.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import threading
import weakref
from pathlib import Path

#: folder -> the process that made it (a forked child inherits the table, not the folders)
_LIVE: dict[str, int] = {}
_LOCK = threading.Lock()


def make(prefix: str) -> str:
    """A new folder in the temporary directory, registered for removal."""
    path = tempfile.mkdtemp(prefix=prefix)
    with _LOCK:
        _LIVE[path] = os.getpid()
    return path


def remove(path: str | Path) -> None:
    """Remove the folder ``path`` now (idempotent) and forget it."""
    p = str(path)
    with _LOCK:
        _LIVE.pop(p, None)
    shutil.rmtree(p, ignore_errors=True)


def remove_all() -> None:
    """Remove every folder this process registered (it is about to end)."""
    pid = os.getpid()
    with _LOCK:
        paths = [p for p, owner in _LIVE.items() if owner == pid]
        for p in paths:
            del _LIVE[p]
    for p in paths:
        shutil.rmtree(p, ignore_errors=True)


def live() -> list[str]:
    """The folders this process registered and has not removed yet."""
    pid = os.getpid()
    with _LOCK:
        return sorted(p for p, owner in _LIVE.items() if owner == pid)


class Scratch:
    """A scratch folder owned by an object: removed by :meth:`cleanup`, or when ``owner`` is
    garbage collected, or at any exit."""

    def __init__(self, owner: object, prefix: str) -> None:
        self.path = make(prefix)
        self._finalizer = weakref.finalize(owner, remove, self.path)

    def cleanup(self) -> None:
        self._finalizer()


atexit.register(remove_all)
