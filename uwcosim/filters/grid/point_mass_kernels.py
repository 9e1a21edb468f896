"""Compiled kernels of the point-mass filter (two gridded states, the TAN case).

Part of :mod:`uwcosim.filters.projection_kernels` (same conventions, same lazy compilation; the
filter reaches these kernels through that module): the prediction around the two FFTs
(:func:`pm_grid_shift`, :func:`pm_gauss_prefilter`, :func:`pm_finish` with the spline shift
:func:`spline_shift_2d`) and the Bayes product with the terrain likelihood
(:func:`terrain_exponent`, :func:`grid_product_moments`), or the moments alone
(:func:`pm_moments`) when the update has no grid rows.
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core import bspline
from uwcosim.core.jit import jit, jit_fast
from uwcosim.core.reductions import max2, row_sum, sum2
from uwcosim.filters.grid.grid_moments import _marginals2, _moments2, _moments2_marginals
from uwcosim.filters.grid.projection_kernels import TWO_PI, _sym, terrain_depth

# ---------------------------------------------------------------------------------------------
# point mass


@jit
def _spline_rows(coords, n, size):
    """Rows of the cubic B-spline evaluation matrix of ``point_mass._spline_matrix``: indices
    (wrapped into ``size``) and weights (:func:`uwcosim.core.bspline.weights`; zero outside
    ``[0, n - 1]``)."""
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
def pm_grid_shift(values, ax0, ax1, mean, cov, d, D, span, unit0, unit1, buf):
    """First part of the point-mass prediction (drift independent of the grid).

    The new grid ``mean + d -+ span sigma`` (``sigma`` from ``cov + D``;
    ``PointMassFilter._grid``), the fractional coordinates on the old grid of its points
    pulled back by ``d``, and ``values`` copied into the top-left block of the zero-padded
    FFT buffer ``buf``. Returns
    ``(new0, new1, coords0, coords1, mean, cov)`` (the predicted moments: exact for a
    translation and a Gaussian convolution)."""
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
    return new0, new1, c0, c1, mean2, _sym(cov2)


@jit
def pm_gauss_prefilter(X, L1, sp0, sp1, D, col, row):
    """``X *= exp(-w' D w / 2) * prefilter`` on a real-FFT spectrum (two dimensions, grid
    spacings ``sp0``, ``sp1``, padded length ``L1`` of the last axis): the diagonal factors
    per index, the cross term ``exp(-D01 a_i b_j) = q_i^j`` (``b_j = j b_1`` on the last,
    real-FFT axis) by powers."""
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
def _scale2(a, s):
    """``a *= s`` (a 2-D array; the normalizations multiply by the reciprocal of the mass:
    a division per grid point costs about 4x a multiplication, and the results differ by at
    most 1 ulp)."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            a[i, j] *= s


@jit
def pm_finish(X, coords0, coords1, n0, n1, cell):
    """Spline at the shifted points (clipped at 0) and normalization: ``(values, mass)``;
    ``values`` are divided by the mass when it is finite and positive."""
    out = spline_shift_2d(X, coords0, coords1, n0, n1)
    mass = sum2(out, False) * cell
    if math.isfinite(mass) and mass > 0.0:
        _scale2(out, 1.0 / mass)
    return out, mass


@jit_fast
def terrain_exponent(xs, ys, C, tpar, ipar, z, var):
    """``ll - max(ll)`` of the terrain row, ``ll = -(h - z)^2 / (2 var)``, and ``max(ll)``
    (map as in :func:`bayes_terms`)."""
    h = terrain_depth(xs, ys, C, tpar[0], tpar[1], tpar[2], tpar[3], ipar[0], ipar[1],
                      ipar[2])
    c = -0.5 / var  # one division, not one per point (round-off: 1 ulp of the exponent)
    for i in range(h.shape[0]):
        for j in range(h.shape[1]):
            e = h[i, j] - z
            h[i, j] = (e * e) * c
    tmax = max2(h)
    h -= tmax
    return h, tmax


@jit
def pm_moments(values, xs, ys):
    """Mean and covariance of the grid density (as ``grid_moments.moments2``, which keeps one
    running sum per row: a chain of dependent additions): the row sums and the covariance
    term in the fixed order of ``row_sum`` / ``row_dot`` (the point-mass update without
    grid rows, e.g. no terrain measurement)."""
    m0, m1 = _marginals2(values)
    return _moments2_marginals(values, m0, m1, xs, ys)


@jit
def grid_product_moments(values, lik, cell, xs, ys):
    """``post = values * lik`` normalized, its mass ``Z`` and moments (point-mass update).

    When the mass is not finite and positive, ``post`` is ``values`` unchanged (the update is
    skipped, ``Z`` is returned for the caller to report)."""
    Mx, My = values.shape
    post = np.empty((Mx, My))
    m0 = np.zeros(Mx)
    m1 = np.zeros(My)
    for i in range(Mx):
        for j in range(My):
            p = values[i, j] * lik[i, j]
            post[i, j] = p
            m1[j] += p
        m0[i] = row_sum(post, i, False)
    Z = m0.sum() * cell
    if math.isfinite(Z) and Z > 0.0:
        _scale2(post, 1.0 / Z)
        m0 /= Z
        m1 /= Z
        mean, cov = _moments2_marginals(post, m0, m1, xs, ys)
    else:
        post = values
        mean, cov = _moments2(post, xs, ys, False)
    return post, Z, mean, cov
