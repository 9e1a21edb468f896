"""Compiled form of the point-mass prediction for a drift independent of the gridded states
(two gridded states; the TAN model): :class:`CompiledPrediction`.

Three kernels around the two FFTs of :class:`~uwcosim.filters.point_mass.fft.FFTPlan`:
:func:`grid_shift` (the new grid, the old grid's coordinates of its points pulled back by the
increment, the zero-padded input), :func:`gauss_prefilter` (the Gaussian ``exp(-w' D w / 2)``
and the spline prefilter on the spectrum) and :func:`finish` (the cubic B-spline at the
shifted points, :func:`spline_shift_2d`, clipped at 0, and the normalization). The same
arithmetic as :func:`~uwcosim.filters.point_mass.prediction.shift_blur` to round-off
(``tests/test_projection_kernels.py``, ``tests/test_point_mass.py``). Bundles as NamedTuples or
plain tuples of their fields (:mod:`uwcosim.core.jit`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from uwcosim.core import bspline
from uwcosim.core.errors import FilterDivergence
from uwcosim.core.jit import jit
from uwcosim.core.reductions import sum2
from uwcosim.filters.point_mass.fft import FFTPlan, fast_len
from uwcosim.filters.point_mass.grid import GridDensity, scale_values
from uwcosim.filters.point_mass.prediction import SPLINE_PAD, Prediction
from uwcosim.filters.small_linalg import sym

TWO_PI = 2.0 * np.pi


class Grid2(NamedTuple):
    """A density on a two-dimensional grid: values ``(n0, n1)`` and the two axes."""

    values: np.ndarray
    x0: np.ndarray
    x1: np.ndarray


class GridRule(NamedTuple):
    """How the grids are chosen (:meth:`GridDensity.grid <uwcosim.filters.point_mass.grid.
    GridDensity.grid>`): the half-width in standard deviations and ``linspace(-1, 1, n)`` of
    each axis."""

    span: float
    unit0: np.ndarray
    unit1: np.ndarray


@jit
def _spline_rows(coords, n, size):
    """Rows of the cubic B-spline evaluation matrix of
    :func:`~uwcosim.filters.point_mass.prediction.spline_matrix`: indices (wrapped into
    ``size``) and weights (:func:`uwcosim.core.bspline.weights`; zero outside ``[0, n - 1]``)."""
    N = coords.size
    idx = np.empty((N, 4), np.int64)
    w = np.empty((N, 4))
    for a in range(N):
        c = coords[a]
        inside = 0.0 <= c <= n - 1.0
        if not inside:
            c = 0.0
        i = int(math.floor(c))
        s = 1.0 if inside else 0.0
        w0, w1, w2, w3 = bspline.weights(c - i)
        w[a, 0] = s * w0
        w[a, 1] = s * w1
        w[a, 2] = s * w2
        w[a, 3] = s * w3
        for t in range(4):  # (i - 1 + t) % size, i - 1 + t in [-1, n + 1] (and n < size)
            v = i - 1 + t
            while v < 0:
                v += size
            while v >= size:
                v -= size
            idx[a, t] = v
    return idx, w


@jit
def spline_shift_2d(X, coords0, coords1, n0, n1):
    """Cubic B-spline of the prefiltered periodic coefficients ``X`` at the fractional grid
    coordinates ``coords0 x coords1`` (zero outside the old ``n0 x n1`` grid), clipped at 0.

    Both passes combine whole contiguous rows (the second one on the transpose), so that the
    inner loops vectorize instead of gathering."""
    i0, w0 = _spline_rows(coords0, n0, X.shape[0])
    i1, w1 = _spline_rows(coords1, n1, X.shape[1])
    N0, N1, S1 = coords0.size, coords1.size, X.shape[1]
    rows = np.empty((N0, S1))
    for a in range(N0):
        r0, r1, r2, r3 = i0[a, 0], i0[a, 1], i0[a, 2], i0[a, 3]
        u0, u1, u2, u3 = w0[a, 0], w0[a, 1], w0[a, 2], w0[a, 3]
        for c in range(S1):
            rows[a, c] = u0 * X[r0, c] + u1 * X[r1, c] + u2 * X[r2, c] + u3 * X[r3, c]
    rowsT = np.ascontiguousarray(rows.T)  # (S1, N0)
    outT = np.empty((N1, N0))
    for b in range(N1):
        r0, r1, r2, r3 = i1[b, 0], i1[b, 1], i1[b, 2], i1[b, 3]
        u0, u1, u2, u3 = w1[b, 0], w1[b, 1], w1[b, 2], w1[b, 3]
        for a in range(N0):
            v = u0 * rowsT[r0, a] + u1 * rowsT[r1, a] + u2 * rowsT[r2, a] + u3 * rowsT[r3, a]
            outT[b, a] = max(v, 0.0)
    return np.ascontiguousarray(outT.T)


@jit
def grid_shift(grid, mean, cov, d, D, rule, buf):
    """First part of the point-mass prediction (drift independent of the grid), for the
    density ``grid`` (a :class:`Grid2`) with the moments ``(mean, cov)`` and the increment
    ``(d, D)``.

    The new grid ``mean + d -+ span sigma`` (``sigma`` from ``cov + D``; the
    :class:`GridRule` ``rule``, :meth:`GridDensity.grid <uwcosim.filters.point_mass.grid.
    GridDensity.grid>`), the fractional coordinates on the old grid of its points pulled back
    by ``d``, and the values copied into the top-left block of the zero-padded FFT buffer
    ``buf``. Returns
    ``(new0, new1, coords0, coords1, mean, cov)`` (the predicted moments: exact for a
    translation and a Gaussian convolution)."""
    values, ax0, ax1 = grid
    span, unit0, unit1 = rule
    mean2 = mean + d
    cov2 = cov + D
    out = []
    for k in range(2):
        sig = math.sqrt(max(cov2[k, k], 0.0))
        half = max(span * sig, 1e-9 * max(1.0, abs(mean2[k])))
        u = unit0 if k == 0 else unit1
        a = u * half
        a += mean2[k]
        out.append(a)
    new0, new1 = out[0], out[1]
    sp0 = ax0[1] - ax0[0]
    sp1 = ax1[1] - ax1[0]
    c0 = (new0 - d[0] - ax0[0]) / sp0
    c1 = (new1 - d[1] - ax1[0]) / sp1
    n0, n1 = values.shape
    B0, B1 = buf.shape
    for i in range(B0):
        if i < n0:
            for j in range(n1):
                buf[i, j] = values[i, j]
            for j in range(n1, B1):
                buf[i, j] = 0.0
        else:
            for j in range(B1):
                buf[i, j] = 0.0
    return new0, new1, c0, c1, mean2, sym(cov2)


@jit
def gauss_prefilter(X, D, sp0, sp1, prefilter):
    """``X *= exp(-w' D w / 2) * prefilter`` on a real-FFT spectrum (two dimensions, grid
    spacings ``sp0``, ``sp1``; the :class:`~uwcosim.filters.point_mass.fft.Prefilter`
    ``prefilter``: its factors and the padded length ``L1`` of the last axis): the diagonal
    factors per index, the cross term ``exp(-D01 a_i b_j) = q_i^j`` (``b_j = j b_1`` on the
    last, real-FFT axis) by powers."""
    col, row, L1 = prefilter
    N0, N1 = X.shape
    b1 = TWO_PI / L1 / sp1
    eb = np.empty(N1)
    for j in range(N1):
        b = j * b1
        eb[j] = math.exp(-0.5 * D[1, 1] * b * b) * row[0, j]
    ea = np.empty(N0)
    qs = np.empty(N0)
    for i in range(N0):
        k = i if i < (N0 + 1) // 2 else i - N0
        a = TWO_PI * k / N0 / sp0
        ea[i] = math.exp(-0.5 * D[0, 0] * a * a) * col[i, 0]
        qs[i] = math.exp(-D[0, 1] * a * b1)
    # the powers q_i^j by the recurrence p *= q_i along each row (the same products in the same
    # order), four rows at a time: four independent chains instead of one
    m = N0 - N0 % 4
    for i in range(0, m, 4):
        e0, e1, e2, e3 = ea[i], ea[i + 1], ea[i + 2], ea[i + 3]
        q0, q1, q2, q3 = qs[i], qs[i + 1], qs[i + 2], qs[i + 3]
        p0 = p1 = p2 = p3 = 1.0
        for j in range(N1):
            e = eb[j]
            _cscale(X, i, j, e0 * e * p0)
            _cscale(X, i + 1, j, e1 * e * p1)
            _cscale(X, i + 2, j, e2 * e * p2)
            _cscale(X, i + 3, j, e3 * e * p3)
            p0 *= q0
            p1 *= q1
            p2 *= q2
            p3 *= q3
    for i in range(m, N0):
        e0, q0 = ea[i], qs[i]
        p0 = 1.0
        for j in range(N1):
            _cscale(X, i, j, e0 * eb[j] * p0)
            p0 *= q0


@jit
def _cscale(X, i, j, g):
    """``X[i, j] *= g`` for a real ``g``: two real products instead of a complex one."""
    v = X[i, j]
    X[i, j] = complex(v.real * g, v.imag * g)


@jit
def finish(X, coords0, coords1, n0, n1, cell):
    """Spline at the shifted points (clipped at 0) and normalization: ``(values, mass)``;
    ``values`` are divided by the mass when it is finite and positive."""
    out = spline_shift_2d(X, coords0, coords1, n0, n1)
    mass = sum2(out, False) * cell
    if math.isfinite(mass) and mass > 0.0:
        scale_values(out, 1.0 / mass)
    return out, mass


class CompiledPrediction(Prediction):
    """:class:`~uwcosim.filters.point_mass.prediction.Prediction` with the drift-independent
    prediction in three compiled kernels around the two FFTs (the Chapman-Kolmogorov
    prediction stays the numpy form's). ``density``: the filter's, for its grid rule."""

    compiled = True

    def __init__(self, part, kalman, density: GridDensity) -> None:
        super().__init__(part, kalman)
        self._rule = (density.span, density.unit[0], density.unit[1])  # a GridRule
        self._plans: dict[tuple[int, int], FFTPlan] = {}  # per filter: threads have their own

    def shift(self, density: GridDensity, inc) -> None:
        D = inc.D
        sp0, sp1 = density.spacing.tolist()
        n0, n1 = density.values.shape
        p0 = max(int(math.ceil(7.0 * math.sqrt(max(D.item(0), 0.0)) / sp0)) + 1, SPLINE_PAD)
        p1 = max(int(math.ceil(7.0 * math.sqrt(max(D.item(3), 0.0)) / sp1)) + 1, SPLINE_PAD)
        shape = (fast_len(n0 + min(p0, n0)), fast_len(n1 + min(p1, n1)))
        plan = self._plans.get(shape)
        if plan is None:
            if len(self._plans) > 8:
                self._plans.clear()
            plan = self._plans[shape] = FFTPlan(shape)
        ax = density.axes
        new0, new1, c0, c1, mean, cov = grid_shift(
            (density.values, ax[0], ax[1]), density.mean, density.cov, inc.d, D, self._rule,
            plan.buf)
        X = plan.forward()
        gauss_prefilter(X, D, sp0, sp1, plan.prefilter)
        out = plan.inverse()
        density.set_axes([new0, new1])
        density.values, mass = finish(out, c0, c1, n0, n1, density.cell)
        if not (math.isfinite(mass) and mass > 0):
            raise FilterDivergence(f"{density.kind}: grid density lost its mass ({mass})")
        density.mean, density.cov = mean, cov
