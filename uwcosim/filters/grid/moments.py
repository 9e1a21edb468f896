"""Mean and covariance of a density sampled on a tensor grid (seed 000 eqs. 50-51 as
quadratures), shared by the projection and point-mass filters.

:func:`axes_moments` is the numpy form, any dimension. The compiled forms take two
dimensions: :func:`moments2` (one running sum per row and column; optionally of the clipped
weights), :func:`moments2_marginals` from marginals already summed (:func:`marginals2`, in the
fixed order of :mod:`uwcosim.core.reductions`), :func:`moments2_cols` with the cross term
summed by columns, and :func:`moments2_ordered`, marginals and moments in one call. All equal
the numpy form to round-off (``tests/test_point_mass.py``, ``tests/test_projection_kernels.py``).
"""

from __future__ import annotations

import numpy as np

from uwcosim.core.jit import jit
from uwcosim.core.reductions import row_dot, row_sum


def axes_moments(axes, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of nonnegative weights ``values`` (any scale) on a tensor grid."""
    n = len(axes)
    if n == 2:  # two marginals and one bilinear form
        m0 = values.sum(axis=1)
        total = m0.sum()
        m1 = values.sum(axis=0)
        mu = np.array([m0 @ axes[0], m1 @ axes[1]]) / total
        d0 = axes[0] - mu[0]
        d1 = axes[1] - mu[1]
        c01 = d0 @ values @ d1 / total
        return mu, np.array([[m0 @ (d0 * d0) / total, c01], [c01, m1 @ (d1 * d1) / total]])
    w = values / values.sum()
    marg = [w.sum(axis=tuple(i for i in range(n) if i != d)) for d in range(n)]
    mu = np.array([marg[d] @ axes[d] for d in range(n)])
    cov = np.zeros((n, n))
    for r in range(n):
        dr = axes[r] - mu[r]
        cov[r, r] = marg[r] @ (dr * dr)
        for s in range(r + 1, n):
            m2 = w if n == 2 else w.sum(axis=tuple(i for i in range(n) if i not in (r, s)))
            cov[r, s] = cov[s, r] = dr @ m2 @ (axes[s] - mu[s])
    return mu, cov


@jit
def moments2(post, xs, ys, clip):
    """Mean and covariance of (signed, or clipped when ``clip``) weights ``post`` on the grid
    ``xs x ys`` (eqs. 50-51)."""
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
def marginals2(values):
    """Row sums ``m0`` (fixed order of ``row_sum``) and column sums ``m1`` (row after row) of
    a 2-D grid: the marginals :func:`moments2_marginals` takes."""
    M0, M1 = values.shape
    m0 = np.empty(M0)
    m1 = np.zeros(M1)
    for i in range(M0):
        for j in range(M1):
            m1[j] += values[i, j]
        m0[i] = row_sum(values, i, False)
    return m0, m1


@jit
def moments2_marginals(post, m0, m1, xs, ys):
    """:func:`moments2` (signed weights) from the marginals ``m0``, ``m1`` already summed."""
    total, mx, my, d0, d1 = _centred_axes(m0, m1, xs, ys)
    c01 = 0.0
    for i in range(post.shape[0]):
        c01 += d0[i] * row_dot(post, i, d1)
    c01 /= total
    return _pack_moments(m0, m1, d0, d1, total, mx, my, c01)


@jit
def moments2_ordered(values, xs, ys):
    """Mean and covariance of the grid density, its marginals and cross term in the fixed
    order of :func:`marginals2` and :func:`moments2_marginals` (where :func:`moments2` keeps
    one running sum per row, a chain of dependent additions)."""
    m0, m1 = marginals2(values)
    return moments2_marginals(values, m0, m1, xs, ys)


@jit
def moments2_cols(post, m0, m1, xs, ys):
    """:func:`moments2_marginals` with the cross term summed by columns: ``t = d0' post``
    (row after row, an elementwise loop that vectorizes) then ``t . d1`` in the fixed order of
    ``row_dot`` (the projection filter's moments; the same to round-off)."""
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
