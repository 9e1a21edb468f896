"""Memory estimated up front: one limit for every large allocation a scenario can ask for.

A particle filter with 1e9 particles, a PFM-PSI grid of ``grid_factor = 1e6``, a 12000 x 12000
map or a campaign of 1e9 runs would otherwise take the machine's memory (and minutes) before
failing, in ``check`` as well as in ``run``. Each of them estimates what it needs before it
allocates it and is refused in one line above :func:`memory_limit` (default 4 GiB, the
point-mass filter's former limit)::

    key 'estimators.pf': n_particles 1000000000 needs about 179 GiB (limit 4 GiB; raise it
    with UWCOSIM_MEMORY_LIMIT_GIB=N): use fewer particles

The estimates are of the arrays each one allocates (with the work copies its steps make), not
of the Python process around them, and are written where the allocation is.
"""

from __future__ import annotations

import math
import os

from uwcosim.core.errors import ScenarioError

#: environment variable: the limit in GiB (a number > 0)
LIMIT_ENV = "UWCOSIM_MEMORY_LIMIT_GIB"
DEFAULT_LIMIT_GIB = 4.0


def memory_limit() -> float:
    """The limit in bytes: ``UWCOSIM_MEMORY_LIMIT_GIB`` GiB, default 4 GiB."""
    text = os.environ.get(LIMIT_ENV, "").strip()
    if not text:
        return DEFAULT_LIMIT_GIB * 2**30
    try:
        gib = float(text)
    except ValueError:
        gib = math.nan
    if not (math.isfinite(gib) and gib > 0):
        raise ScenarioError(f"{LIMIT_ENV}={text!r}: expected a number of GiB > 0")
    return gib * 2**30


def memory_problem(need_bytes: float, what: str, advice: str) -> str | None:
    """``"WHAT needs about N GiB (limit L GiB; ...): ADVICE"`` when ``need_bytes`` is above the
    limit, else None. The caller raises it as its own error (naming its file or key)."""
    limit = memory_limit()
    if need_bytes <= limit:  # NaN counts as too much
        return None
    need = f"{need_bytes / 2**30:.3g}" if math.isfinite(need_bytes) else "an unbounded amount of"
    return (f"{what} needs about {need} GiB (limit {limit / 2**30:g} GiB; raise it with "
            f"{LIMIT_ENV}=N): {advice}")
