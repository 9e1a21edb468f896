"""Child processes of a run: the registry of live workers and their death with the parent.

FMU workers (:class:`uwcosim.fmi.proxy.ProxyAdapter`) are registered here when they start
(:func:`register`) and removed when they end (:func:`reap`); :func:`kill_workers` kills every
live one at once (the signal guard, :mod:`uwcosim.core.runguard`, calls it before the process
ends). A child calls :func:`die_with_parent` first thing: it is killed when its parent ends.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys

_LIVE: set[subprocess.Popen] = set()  # running workers of this process


def register(proc: subprocess.Popen) -> None:
    """Count ``proc`` among this process's live workers."""
    _LIVE.add(proc)


def workers() -> list[subprocess.Popen]:
    """The live workers of this process."""
    return list(_LIVE)


def reap(proc: subprocess.Popen) -> None:
    """Kill ``proc`` if it still runs, wait for it and forget it."""
    if proc.poll() is None:
        proc.kill()
    proc.wait()
    _LIVE.discard(proc)


def kill_workers() -> None:
    """Kill every worker of this process now (the process is about to end)."""
    for proc in list(_LIVE):
        try:
            proc.kill()
        except OSError:
            pass


def die_with_parent(parent: int | None = None) -> None:
    """Have this process killed when its parent ends (Linux; elsewhere a no-op). ``parent``:
    the pid the parent had; if it is already gone, exit now."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if parent is not None and os.getppid() != parent:
        os._exit(1)
