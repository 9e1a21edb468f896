"""The run's random streams: one independent generator per named purpose, derived from the seed.

All randomness of a run comes from :func:`stream`, and the master owns the seed: the truth's
noise (``noise:NAME``), the sensors' noise and losses (``sensor-noise:NAME``, ``loss:NAME``),
the estimators' initial error (``initial-error``) and each estimator's own stream
(``estimator:NAME``). Adding a sensor does not change another sensor's noise, and the same
scenario and seed always give the same samples.
"""

from __future__ import annotations

import zlib

import numpy as np


def stream(seed: int, purpose: str) -> np.random.Generator:
    """An independent generator for ``purpose`` (e.g. ``'noise:process'``, ``'loss:dvl'``)."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(purpose.encode())])
