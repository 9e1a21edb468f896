"""Position marginals of different filters on one grid, for Hellinger distances.

Every filter's posterior of the position ``(x, y)`` is turned into a density sampled on a
common tensor grid ``axes``: a Gaussian (Kalman-family filters) exactly, weighted particles by a
Gaussian kernel density estimate (binned on the grid, then smoothed with the kernel; Silverman's
rule for the bandwidth unless given), and grid filters by their own interpolation. The
distance is :func:`uwcosim.evaluation.distance.hellinger` of two such arrays.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def gaussian_on_grid(mean, cov, axes) -> np.ndarray:
    """``N(mean, cov)`` sampled on the tensor grid ``axes`` (2-D)."""
    X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
    d = np.stack([X - mean[0], Y - mean[1]], axis=-1)
    L = np.linalg.cholesky(np.asarray(cov, float))
    y = np.linalg.solve(L, d.reshape(-1, 2).T)
    return np.exp(-0.5 * np.sum(y * y, axis=0)).reshape(X.shape) / (
        2.0 * np.pi * np.prod(np.diag(L)))


def silverman_bandwidth(X: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-axis bandwidth ``sigma_j n_eff^(-1/(d+4))`` (Silverman's rule for a Gaussian kernel,
    ``d = 2``, ``n_eff = 1 / sum w^2``)."""
    w = np.asarray(w, float) / np.sum(w)
    m = w @ X
    sd = np.sqrt(w @ (X - m) ** 2)
    n_eff = 1.0 / float(w @ w)
    return sd * n_eff ** (-1.0 / 6.0)


def particles_on_grid(X: np.ndarray, w: np.ndarray, axes, bandwidth=None) -> np.ndarray:
    """Kernel density estimate of weighted 2-D points ``X`` (rows) on the grid ``axes``.

    The points are binned (linear binning onto the grid nodes), then smoothed by a Gaussian of
    standard deviation ``bandwidth`` (per axis; default Silverman's). Mass outside the grid is
    lost, as for any density restricted to the grid.
    """
    X = np.asarray(X, float)
    w = np.asarray(w, float)
    w = w / w.sum()
    h = silverman_bandwidth(X, w) if bandwidth is None else np.broadcast_to(bandwidth, (2,))
    sp = np.array([a[1] - a[0] for a in axes])
    n = [a.size for a in axes]
    g = (X - np.array([axes[0][0], axes[1][0]])) / sp  # fractional node coordinates
    i = np.floor(g).astype(int)
    f = g - i
    out = np.zeros(n)
    for dx in (0, 1):
        for dy in (0, 1):
            ii, jj = i[:, 0] + dx, i[:, 1] + dy
            wt = w * np.where(dx, f[:, 0], 1 - f[:, 0]) * np.where(dy, f[:, 1], 1 - f[:, 1])
            ok = (ii >= 0) & (ii < n[0]) & (jj >= 0) & (jj < n[1])
            np.add.at(out, (ii[ok], jj[ok]), wt[ok])
    out = ndimage.gaussian_filter(out, sigma=h / sp, mode="constant")
    return out / np.prod(sp)


def grid_around(mean, cov, n: int = 161, span: float = 6.0) -> list[np.ndarray]:
    """A square-ish tensor grid ``mean -+ span * sigma`` with ``n`` points per axis."""
    sd = np.sqrt(np.diag(np.asarray(cov, float)))
    return [np.linspace(mean[d] - span * sd[d], mean[d] + span * sd[d], n) for d in range(2)]
