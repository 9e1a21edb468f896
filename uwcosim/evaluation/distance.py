"""Distances between densities sampled on the same grid: :func:`hellinger`.

Used to compare a filter's posterior with a reference posterior (the point-mass filter's, or
an exact one) on a common tensor grid (:mod:`uwcosim.evaluation.density` samples each filter's
posterior there).
"""

from __future__ import annotations

import numpy as np


def hellinger(p: np.ndarray, q: np.ndarray) -> float:
    """Hellinger distance of two densities sampled on the same uniform grid.

    ``H^2 = 1 - sum sqrt(p q) / sqrt(sum p sum q)`` (negative values clipped), in [0, 1].
    """
    p = np.maximum(np.asarray(p, float), 0.0)
    q = np.maximum(np.asarray(q, float), 0.0)
    bc = np.sum(np.sqrt(p * q)) / np.sqrt(p.sum() * q.sum())
    return float(np.sqrt(max(0.0, 1.0 - bc)))
