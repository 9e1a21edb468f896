"""Distances between densities sampled on the same grid: :func:`hellinger`.

Used to compare a filter's posterior with a reference posterior (the point-mass filter's, or
an exact one) on a common tensor grid (:mod:`uwcosim.evaluation.density` samples each filter's
posterior there).

Two ways to treat the mass a density has outside the grid (the window):

* ``cell=None`` (the original estimator, kept for the results that quote it): each density is
  renormalized over the window, so mass outside it is dropped and a filter that puts half its
  mass far away is judged on the other half only;
* ``cell=area`` of one grid cell: the arrays are taken as densities of probability 1 over the
  whole plane, ``m = sum p * cell`` is the mass in the window and ``1 - m`` the mass outside,
  which counts as disjoint from the other density. The result is an upper bound of the true
  distance, tight to ``sqrt((1 - m_p)(1 - m_q))`` in ``H^2`` (Cauchy-Schwarz on the outside).
"""

from __future__ import annotations

import numpy as np


def hellinger(p: np.ndarray, q: np.ndarray, cell: float | None = None) -> float:
    """Hellinger distance of two densities sampled on the same uniform grid, in [0, 1].

    ``cell=None``: ``H^2 = 1 - sum sqrt(p q) / sqrt(sum p sum q)``, each density renormalized
    over the grid. ``cell`` (the area of one grid cell): ``H^2 = 1 - sum sqrt(p q) cell``, the
    mass outside the grid kept (as disjoint); a density whose window mass exceeds 1
    (interpolation overshoot) is scaled down to 1. Negative values are clipped.
    """
    p = np.maximum(np.asarray(p, float), 0.0)
    q = np.maximum(np.asarray(q, float), 0.0)
    if cell is None:
        bc = np.sum(np.sqrt(p * q)) / np.sqrt(p.sum() * q.sum())
    else:
        m_p, m_q = p.sum() * cell, q.sum() * cell  # masses in the window
        bc = np.sum(np.sqrt(p * q)) * cell / np.sqrt(max(1.0, m_p) * max(1.0, m_q))
    return float(np.sqrt(max(0.0, 1.0 - bc)))
