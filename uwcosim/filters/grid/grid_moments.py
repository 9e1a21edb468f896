"""Compiled moments of a two-dimensional grid density (mean, covariance, marginals), with
the resolution floor of the variances: the point-mass and projection filters' kernels share them
(reached through :mod:`uwcosim.filters.grid.projection_kernels`)."""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.jit import jit
from uwcosim.core.reductions import row_dot, row_sum


@jit
def moments2(post, xs, ys):
    """Mean and covariance of the weights ``post`` on the grid ``xs x ys``."""
    return _moments2(post, xs, ys, False)


@jit
def _moments2(post, xs, ys, clip):
    """Mean and covariance of (signed, or clipped) weights on the tensor grid (eqs. 50-51)."""
    Mx, My = post.shape
    m0 = np.zeros(Mx)
    m1 = np.zeros(My)
    for i in range(Mx):
        for j in range(My):
            v = post[i, j]
            if clip and v < 0.0:
                v = 0.0
            m0[i] += v
            m1[j] += v
    total = m0.sum()
    mx = (m0 @ xs) / total
    my = (m1 @ ys) / total
    d0 = xs - mx
    d1 = ys - my
    c01 = 0.0
    for i in range(Mx):
        acc = 0.0
        for j in range(My):
            v = post[i, j]
            if clip and v < 0.0:
                v = 0.0
            acc += v * d1[j]
        c01 += d0[i] * acc
    c01 /= total
    mean = np.array([mx, my])
    cov = np.array([[(m0 @ (d0 * d0)) / total, c01], [c01, (m1 @ (d1 * d1)) / total]])
    return mean, cov


@jit
def _floor_moments(post, xs, ys, mean, cov, floor0, floor1):
    """The checks of :meth:`ProjectionFilter._grid_moments` on the signed moments ``(mean,
    cov)``: moments of the clip when they are not valid, variances floored."""
    c00, c11, c01 = cov[0, 0], cov[1, 1], cov[0, 1]
    ok = (math.isfinite(c00 + c11 + 2.0 * c01) and c00 > floor0 and c11 > floor1
          and c00 * c11 - c01 * c01 > 0.0)
    if not ok:
        mean, cov = _moments2(post, xs, ys, True)
    v0, v1 = cov[0, 0], cov[1, 1]
    if v0 >= floor0 and v1 >= floor1:
        return mean, cov
    d0 = math.sqrt(max(v0, floor0) / max(v0, 1e-300))
    d1 = math.sqrt(max(v1, floor1) / max(v1, 1e-300))
    cov[0, 0] *= d0 * d0
    cov[1, 1] *= d1 * d1
    cov[0, 1] *= d0 * d1
    cov[1, 0] *= d0 * d1
    return mean, cov


@jit
def grid_moments2(post, xs, ys, floor0, floor1):
    """:meth:`ProjectionFilter._grid_moments` for two gridded states."""
    mean, cov = _moments2(post, xs, ys, False)
    return _floor_moments(post, xs, ys, mean, cov, floor0, floor1)


@jit
def _marginals2(values):
    """Row sums ``m0`` (fixed order of ``row_sum``) and column sums ``m1`` (row after row) of
    a 2-D grid: the marginals :func:`_moments2_marginals` takes."""
    M0, M1 = values.shape
    m0 = np.empty(M0)
    m1 = np.zeros(M1)
    for i in range(M0):
        for j in range(M1):
            m1[j] += values[i, j]
        m0[i] = row_sum(values, i, False)
    return m0, m1


@jit
def _moments2_marginals(post, m0, m1, xs, ys):
    """:func:`_moments2` (signed weights) from the marginals ``m0``, ``m1`` already summed."""
    total, mx, my, d0, d1 = _centred_axes(m0, m1, xs, ys)
    c01 = 0.0
    for i in range(post.shape[0]):
        c01 += d0[i] * row_dot(post, i, d1)
    c01 /= total
    return _pack_moments(m0, m1, d0, d1, total, mx, my, c01)


@jit
def _moments2_cols(post, m0, m1, xs, ys):
    """:func:`_moments2_marginals` with the cross term summed by columns: ``t = d0' post``
    (row after row, an elementwise loop that vectorizes) then ``t . d1`` in the fixed order of
    :func:`row_dot` (the projection filter's moments; the same to round-off)."""
    total, mx, my, d0, d1 = _centred_axes(m0, m1, xs, ys)
    t = np.zeros((1, post.shape[1]))
    for i in range(post.shape[0]):
        _axpy_row(t, d0[i], post, i)
    c01 = row_dot(t, 0, d1) / total
    return _pack_moments(m0, m1, d0, d1, total, mx, my, c01)


@jit
def _centred_axes(m0, m1, xs, ys):
    """The mass (in sums), the mean and the centred axes of marginals ``m0``, ``m1``."""
    total = m0.sum()
    mx = (m0 @ xs) / total
    my = (m1 @ ys) / total
    return total, mx, my, xs - mx, ys - my


@jit
def _pack_moments(m0, m1, d0, d1, total, mx, my, c01):
    """Mean and covariance from the marginals, the centred axes and the cross term."""
    mean = np.array([mx, my])
    cov = np.array([[(m0 @ (d0 * d0)) / total, c01], [c01, (m1 @ (d1 * d1)) / total]])
    return mean, cov


@jit
def _axpy_row(t, a, x, i):
    """``t[0] += a x[i]`` (a function of its own: its loop vectorizes)."""
    for j in range(x.shape[1]):
        t[0, j] += a * x[i, j]
