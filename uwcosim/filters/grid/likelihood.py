"""Measurement likelihood of the gridded states on a tensor grid (projection and point-mass).

:class:`GridLikelihood` evaluates ``log p(z | x_p)`` of the measurement rows that depend on the
gridded states on a tensor grid, with the other states at their means. Rows equal to the
terrain depth of a TAN model (``model.terrain``, checked numerically against ``model.h``) use
:class:`TerrainGrid`, a separable evaluation of the same bathymetry B-spline; other rows use
``model.h_batch`` on the grid points. :func:`terrain_depth` is the compiled form of
:meth:`TerrainGrid.depth` that the filters' compiled Bayes steps call, on the map's bundle
:class:`TerrainMap`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from uwcosim.core import bspline
from uwcosim.core.jit import jit
from uwcosim.filters.grid.partition import Partition
from uwcosim.filters.robust import student_t_loglik

_TAPS = np.arange(4)


class TerrainMap(NamedTuple):
    """A bathymetry map as the compiled kernels take it: the spline coefficients ``C[y, x]``
    (with ``pad`` padding nodes on each side), the first node ``(x0, y0)``, the spacings and
    the numbers of nodes ``(nx, ny)``."""

    C: np.ndarray
    x0: float
    y0: float
    dx: float
    dy: float
    nx: int
    ny: int
    pad: int


class TerrainGrid:
    """The bathymetry spline ``h_d`` on a tensor grid, separably: ``W_x C W_y'``.

    Same cubic B-spline and edge clamping as :meth:`Bathymetry.depth`
    (:mod:`uwcosim.core.bspline`), at a cost linear in the grid size instead of 16 gathers per
    point.
    """

    def __init__(self, terrain) -> None:
        self.t = terrain
        self.pad = (terrain.coefficients.shape[0] - terrain.shape[0]) // 2
        ny, nx = terrain.shape
        #: the map for the compiled kernels (:func:`terrain_depth`)
        self.map = TerrainMap(terrain.coefficients, float(terrain.x0), float(terrain.y0),
                              float(terrain.dx), float(terrain.dy), int(nx), int(ny),
                              int(self.pad))

    @staticmethod
    def _weights(s: np.ndarray, n: int):
        """Cell index (column) and the 4 cubic B-spline weights (columns) at positions ``s``
        (:mod:`uwcosim.core.bspline`: its clamping, its weights as polynomials)."""
        i, f = bspline.cell(s, n)
        f2 = f * f
        return i[:, None], np.stack([np.ones_like(f), f, f2, f2 * f], axis=1) @ bspline.MONOMIAL

    def depth(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """``h_d(xs[i], ys[j])``, shape ``(len(xs), len(ys))``."""
        t = self.t
        ny, nx = t.shape
        iu, wu = self._weights((np.asarray(xs, float) - t.x0) / t.dx, nx)
        iv, wv = self._weights((np.asarray(ys, float) - t.y0) / t.dy, ny)
        pad = self.pad
        c0, c1 = int(iu.min()) - 1 + pad, int(iu.max()) + 3 + pad
        r0, r1 = int(iv.min()) - 1 + pad, int(iv.max()) + 3 + pad
        if (c1 - c0) * (r1 - r0) <= 16 * (xs.size + ys.size) ** 2:
            # small support: banded weight matrices and two dense products
            Wx = np.zeros((xs.size, c1 - c0))
            Wy = np.zeros((ys.size, r1 - r0))
            Wx[np.arange(xs.size)[:, None], iu + (pad - 1 - c0) + _TAPS] = wu
            Wy[np.arange(ys.size)[:, None], iv + (pad - 1 - r0) + _TAPS] = wv
            return Wx @ t.coefficients[r0:r1, c0:c1].T @ Wy.T
        C = t.coefficients[r0:r1]  # rows (y) in the support
        iu, iv = iu[:, 0], iv[:, 0]
        Gx = sum(wu[:, a][:, None] * C[:, iu + a - 1 + pad].T for a in range(4))
        return sum(wv[:, b][None, :] * Gx[:, iv + b - 1 + pad - r0] for b in range(4))


@jit
def terrain_depth(xs, ys, terrain):
    """``h[i, j] = h_d(xs[i], ys[j])`` on the map ``terrain`` (a :class:`TerrainMap`), as
    :meth:`TerrainGrid.depth` (compiled): first along ``y`` at the map's columns of the support
    (``Csub' Wy'``, one BLAS product with the banded weight matrix), then the 4 taps along
    ``x`` per grid row (a loop that vectorizes)."""
    C, x0, y0, dx, dy, nx, ny, pad = terrain
    iu, wu = bspline.cell_weights((xs - x0) / dx, nx)
    iv, wv = bspline.cell_weights((ys - y0) / dy, ny)
    c0 = iu.min() - 1 + pad
    c1 = iu.max() + 3 + pad
    r0 = iv.min() - 1 + pad
    r1 = iv.max() + 3 + pad
    WyT = np.zeros((r1 - r0, ys.size))
    for j in range(ys.size):
        for a in range(4):
            WyT[iv[j] + pad - 1 - r0 + a, j] = wv[j, a]
    CsubT = np.ascontiguousarray(C[r0:r1, c0:c1].T)  # (cols x, rows y)
    Hy = CsubT @ WyT  # (cols x, len ys)
    h = np.empty((xs.size, ys.size))
    for i in range(xs.size):
        k = iu[i] + pad - 1 - c0
        w0, w1, w2, w3 = wu[i, 0], wu[i, 1], wu[i, 2], wu[i, 3]
        for j in range(ys.size):
            h[i, j] = ((w0 * Hy[k, j] + w1 * Hy[k + 1, j]) + w2 * Hy[k + 2, j]) + w3 * Hy[k + 3, j]
    return h


def _diff2(v: np.ndarray, axis: int) -> np.ndarray:
    """``2 h`` times :func:`_diff` along ``axis`` (0 or 1) of a 2-D array, in fewer passes."""
    g = np.empty_like(v)
    if axis == 0:
        np.subtract(v[2:], v[:-2], out=g[1:-1])
        np.subtract(v[1], v[0], out=g[0])
        np.subtract(v[-1], v[-2], out=g[-1])
        g[0] *= 2.0
        g[-1] *= 2.0
    else:
        np.subtract(v[:, 2:], v[:, :-2], out=g[:, 1:-1])
        np.subtract(v[:, 1], v[:, 0], out=g[:, 0])
        np.subtract(v[:, -1], v[:, -2], out=g[:, -1])
        g[:, 0] *= 2.0
        g[:, -1] *= 2.0
    return g


def _diff(v: np.ndarray, a: np.ndarray, axis: int) -> np.ndarray:
    """Central differences along ``axis`` of a uniform grid (one-sided at the ends)."""
    h = a[1] - a[0]
    g = np.empty_like(v)

    def sl(index):
        idx = [slice(None)] * v.ndim
        idx[axis] = index
        return tuple(idx)

    g[sl(slice(1, -1))] = (v[sl(slice(2, None))] - v[sl(slice(None, -2))]) * (0.5 / h)
    g[sl(0)] = (v[sl(1)] - v[sl(0)]) / h
    g[sl(-1)] = (v[sl(-1)] - v[sl(-2)]) / h
    return g


class GridLikelihood:
    """Log-likelihood of the gridded measurement rows on a tensor grid of the gridded states."""

    def __init__(self, model, part: Partition, nu: float | None = None) -> None:
        self.model = model
        self.part = part
        #: Student-t degrees of freedom of every row (None: Gaussian; filters.robust)
        self.nu = nu
        if nu is not None:
            R = np.asarray(model.R)
            if np.count_nonzero(R - np.diag(np.diag(R))):
                raise ValueError("student_t_nu needs a diagonal measurement covariance R")
        self.terrain_rows: dict[int, TerrainGrid] = {}
        terrain = getattr(model, "terrain", None)
        if terrain is not None and len(part.p) == 2:
            rng = np.random.default_rng(0)
            xmin, xmax, ymin, ymax = terrain.extent
            pts = np.zeros((16, model.nx))
            pts[:, part.p[0]] = rng.uniform(xmin, xmax, 16)
            pts[:, part.p[1]] = rng.uniform(ymin, ymax, 16)
            hb = model.h_batch(pts)
            ref = terrain.depth(pts[:, part.p[0]], pts[:, part.p[1]])
            tg = TerrainGrid(terrain)
            for r in part.rows_grid:
                if np.allclose(hb[:, r], ref, rtol=0, atol=1e-6):
                    self.terrain_rows[r] = tg

    def _terrain_loglik(self, axes, z, r: int, resolution) -> np.ndarray:
        """:meth:`loglik` for one terrain row (the TAN depth), without the generic stacking."""
        h = self.terrain_rows[r].depth(axes[0], axes[1])
        var = float(self.model.R[r, r])
        e = h - float(z[r])
        if self.nu is not None:
            return self._student_t(e[..., None], np.array([var]), axes, h[..., None],
                                   resolution)
        if resolution is None:
            e *= e
            e *= -0.5 / var
            return e
        extra = None
        for d, a in enumerate(axes):
            if a.size < 3:
                continue
            g = _diff2(h, d)  # twice the central difference (one-sided ones doubled)
            g *= g
            g *= (float(resolution[d]) / (2.0 * (a[1] - a[0]))) ** 2 / 12.0
            if extra is None:
                extra = g
            else:
                extra += g
        if extra is None:
            e *= e
            e *= -0.5 / var
            return e - 0.5 * np.log(var)
        extra += var
        e *= e
        e /= extra
        e += np.log(extra)
        e *= -0.5
        return e

    def _student_t(self, e, r, axes, pred, resolution) -> np.ndarray:
        """The Student-t form of :meth:`loglik` (:func:`uwcosim.filters.robust.student_t_loglik`
        per row, variances ``r``, inflated by the representation error as the Gaussian's)."""
        var = np.broadcast_to(r, e.shape)
        if resolution is not None:
            extra = np.zeros(e.shape)
            for d, a in enumerate(axes):
                if a.size >= 3:
                    g = _diff(pred, a, d)
                    extra += g * g * (float(resolution[d]) ** 2 / 12.0)
            var = var + extra
            return np.sum(student_t_loglik(e * e, var, self.nu) - 0.5 * np.log(var), axis=-1)
        return np.sum(student_t_loglik(e * e, var, self.nu), axis=-1)

    def loglik(
        self, axes: list[np.ndarray], z: np.ndarray, rows: list[int], x_full, resolution=None
    ) -> np.ndarray:
        """``log p(z_rows | x_p)`` up to a constant, shape ``(len(a) for a in axes)``.

        ``resolution`` (one length per gridded state, optional): the scale below which the
        density representation cannot resolve position. The measurement variance is then
        inflated by the variation of ``h`` within such a cell, ``sum_d (dh/dx_d)^2 res_d^2 / 12``
        (gradient by central differences on the grid), so that a likelihood rougher than the
        representation is not sampled as if it were exact.
        """
        if len(rows) == 1 and rows[0] in self.terrain_rows:
            return self._terrain_loglik(axes, z, rows[0], resolution)
        shape = tuple(a.size for a in axes)
        pred = np.empty(shape + (len(rows),))
        generic = [r for r in rows if r not in self.terrain_rows]
        if generic:
            mesh = np.meshgrid(*axes, indexing="ij")
            X = np.tile(np.asarray(x_full, float), (mesh[0].size, 1))
            for d, i in enumerate(self.part.p):
                X[:, i] = mesh[d].ravel()
            hb = self.model.h_batch(X)
        for c, r in enumerate(rows):
            if r in self.terrain_rows:
                pred[..., c] = self.terrain_rows[r].depth(axes[0], axes[1])
            else:
                pred[..., c] = hb[:, r].reshape(shape)
        e = z[rows] - pred
        R = self.model.R[np.ix_(rows, rows)]
        if self.nu is not None:
            return self._student_t(e, np.diag(R), axes, pred, resolution)
        if resolution is None:
            if len(rows) == 1:
                return -0.5 * e[..., 0] ** 2 / R[0, 0]
            L = np.linalg.cholesky(R)
            y = np.linalg.solve(L, e.reshape(-1, len(rows)).T)
            return -0.5 * np.sum(y * y, axis=0).reshape(shape)
        extra = np.zeros(shape + (len(rows),))
        for d, a in enumerate(axes):
            if a.size < 3:
                continue
            g = _diff(pred, a, d)
            extra += g * g * (float(resolution[d]) ** 2 / 12.0)
        if len(rows) == 1:
            var = R[0, 0] + extra[..., 0]
            return -0.5 * (e[..., 0] ** 2 / var + np.log(var))
        S = R + extra[..., :, None] * np.eye(len(rows))
        L = np.linalg.cholesky(S)
        y = np.linalg.solve(L, e[..., None])[..., 0]
        logdet = 2.0 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
        return -0.5 * (np.sum(y * y, axis=-1) + logdet)
