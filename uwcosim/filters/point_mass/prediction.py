"""The point-mass filter's prediction: the density carried to the new grid.

The new grid is chosen from the predicted mean and covariance (:meth:`~uwcosim.filters.
point_mass.grid.GridDensity.grid`).

- *Drift independent of the gridded states* (TAN: the position moves by the rotated
  velocity): the new grid is pulled back by the mean increment ``d`` and the posterior is
  interpolated there (cubic B-spline of :mod:`uwcosim.core.bspline`, zero outside the old
  grid), then convolved with the increment's Gaussian ``N(0, D)`` by FFT (zero-padded, exact
  characteristic function ``exp(-w' D w / 2)``): :func:`shift_blur`. Translation and Gaussian
  convolution: the moments propagate exactly.
- *General drift*: the Chapman-Kolmogorov sum (:meth:`Prediction.transition`).

``D`` includes the velocity uncertainty of the conditional Kalman block
(:class:`~uwcosim.filters.grid.conditional.ConditionalKalman`). :class:`Prediction` is the
numpy form; :class:`~uwcosim.filters.point_mass.prediction_kernels.CompiledPrediction` runs the
drift-independent prediction in three compiled kernels around the two FFTs.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy import sparse

from uwcosim.core import bspline
from uwcosim.filters.grid.conditional import ConditionalKalman
from uwcosim.filters.grid.moments import axes_moments
from uwcosim.filters.grid.partition import Partition
from uwcosim.filters.numerics import symmetrize
from uwcosim.filters.point_mass.fft import (
    inverse_bspline_factors,
    inverse_bspline_symbol,
    unit_frequencies,
)
from uwcosim.filters.point_mass.grid import GridDensity

_TAPS = np.arange(-1, 3)
_POWERS = np.arange(4.0)
_SPLINE_MATRICES: dict[tuple[int, int], sparse.csr_matrix] = {}
SPLINE_PAD = 7  # zero padding for the spline prefilter (its impulse response: 0.27^|k|)


def spline_matrix(coords: np.ndarray, n: int, size: int) -> sparse.csr_matrix:
    """Cubic B-spline evaluation at fractional ``coords`` from ``size`` periodic coefficients.

    Rows are zero outside the sampled range ``[0, n - 1]``; the taps at ``-1`` and ``n`` wrap
    into the (zero-padded) end of the coefficient array. The matrix is a cached buffer refilled
    in place: valid until the next call with the same shape.
    """
    c = np.asarray(coords, dtype=float)
    if c[0] >= 0.0 and c[-1] <= n - 1.0 and c[-1] >= c[0]:  # increasing, all inside
        inside = None
        i = c.astype(np.intp)
    else:
        inside = (c >= 0.0) & (c <= n - 1.0)
        c = np.where(inside, c, 0.0)
        i = np.floor(c).astype(np.intp)
    f = c - i
    w = (f[:, None] ** _POWERS) @ bspline.MONOMIAL  # the 4 cubic B-spline weights per row
    if inside is not None:
        w *= inside[:, None]
    idx = i[:, None] + _TAPS
    idx %= size
    key = (c.size, size)
    B = _SPLINE_MATRICES.get(key)
    if B is None:  # the structure (4 entries per row) is fixed: build once, refill in place
        indptr = np.arange(0, 4 * c.size + 1, 4)
        B = sparse.csr_matrix((w.ravel(), idx.ravel(), indptr), shape=key)
        if len(_SPLINE_MATRICES) > 64:
            _SPLINE_MATRICES.clear()
        _SPLINE_MATRICES[key] = B
        return B
    B.data[:] = w.ravel()
    B.indices[:] = idx.ravel()
    return B


def _gauss_prefilter_2d(shape: tuple[int, int], spacing, D: np.ndarray) -> np.ndarray:
    """``exp(-w' D w / 2)`` times the cubic B-spline prefilter on a two-dimensional real-FFT
    spectrum of ``shape``: the diagonal factors as vectors, one full exp for the cross term."""
    a, b = (o / spacing[d] for d, o in enumerate(unit_frequencies(shape)))
    kern = np.exp((-D[0, 1] * a) * b)
    col, row = inverse_bspline_factors(shape)
    kern *= np.exp((-0.5 * D[0, 0]) * a * a) * col
    kern *= np.exp((-0.5 * D[1, 1]) * b * b) * row
    return kern


def shift_blur(values: np.ndarray, spacing, coords: list[np.ndarray], D: np.ndarray):
    """Prediction of a drift independent of the grid: ``(p * N(0, D))`` at shifted points.

    One zero-padded real FFT: the Gaussian ``exp(-w' D w / 2)`` and the cubic B-spline
    prefilter are applied together, then the spline is evaluated at the fractional grid
    coordinates ``coords`` (one array per axis, in units of the old spacing; zero outside the
    old grid) by one sparse banded matrix per axis.
    """
    n = values.ndim
    D = np.asarray(D, dtype=float)
    sig = np.sqrt(np.maximum(np.diag(D), 0.0))
    pads = [max(int(np.ceil(7.0 * sig[d] / spacing[d])) + 1, SPLINE_PAD) for d in range(n)]
    shape = tuple(
        sfft.next_fast_len(values.shape[d] + min(pads[d], values.shape[d]), real=True)
        for d in range(n)
    )
    X = sfft.rfftn(values, s=shape)
    if n == 2:
        X *= _gauss_prefilter_2d(shape, spacing, D)
        out = sfft.irfftn(X, s=shape)
        out = spline_matrix(coords[0], values.shape[0], shape[0]) @ out
        B = spline_matrix(coords[1], values.shape[1], shape[1])
        return (B @ out.T).T
    oms = [o / spacing[d] for d, o in enumerate(unit_frequencies(shape))]
    quad = 0.0
    for r in range(n):
        quad = quad + (0.5 * D[r, r]) * oms[r] * oms[r]
        for s in range(r + 1, n):
            quad = quad + D[r, s] * oms[r] * oms[s]
    X *= np.exp(-quad) * inverse_bspline_symbol(shape)
    out = sfft.irfftn(X, s=shape)
    for d in range(n):
        B = spline_matrix(coords[d], values.shape[d], shape[d])
        moved = np.moveaxis(out, d, 0)
        res = B @ moved.reshape(shape[d], -1)
        out = np.moveaxis(res.reshape((B.shape[0],) + moved.shape[1:]), 0, d)
    return out


class Prediction:
    """The point-mass prediction, numpy form (any number of gridded states): :meth:`translate`
    for a drift independent of the gridded states, else :meth:`chapman_kolmogorov` (the filter
    takes the one its model needs, once). Both predict the density (in place) and the Kalman
    block over ``dt`` with the control ``u`` held, from the filter's estimate ``x``, and return
    the prior's ``(x, P, finite)``."""

    #: the step runs compiled kernels
    compiled = False

    def __init__(self, part: Partition, kalman: ConditionalKalman) -> None:
        self.part = part
        self.kalman = kalman

    def translate(self, density: GridDensity, x, u, dt: float, diag: dict):
        """A drift independent of the gridded states: the density shifted and blurred
        (:meth:`shift`)."""
        inc = self.kalman.increment(x, u, dt)
        self.shift(density, inc)
        return self.kalman.assemble(density.mean, density.cov)

    def chapman_kolmogorov(self, density: GridDensity, x, u, dt: float, diag: dict):
        """A general drift: the Chapman-Kolmogorov sum (:meth:`transition`), normalized, and
        the moments of the new grid."""
        inc = self.kalman.increment(x, u, dt)
        self.transition(density, x, u, dt, inc)
        density.normalize()
        density.mean, density.cov = axes_moments(density.axes, density.values)
        return self.kalman.assemble(density.mean, density.cov)

    def shift(self, density: GridDensity, inc) -> None:
        """The drift-independent prediction (:func:`shift_blur`, clipped at 0, normalized)."""
        new = density.grid(density.mean + inc.d, density.cov + inc.D)
        old = density.spacing
        axes = density.axes
        coords = [(new[d] - inc.d[d] - axes[d][0]) / old[d] for d in range(len(new))]
        vals = shift_blur(density.values, old, coords, inc.D)
        density.values = np.maximum(vals, 0.0, out=vals)
        density.set_axes(new)
        density.normalize(clip=False)
        # translation and Gaussian convolution: the moments propagate exactly
        density.mean, density.cov = density.mean + inc.d, symmetrize(density.cov + inc.D)

    def transition(self, density: GridDensity, x, u, dt: float, inc) -> None:
        """General drift: ``p'(x'_j) = sum_i N(x'_j; f(x_i), Q) p(x_i)`` with the model's
        one-step map ``f`` and the covariance ``Q`` at the mean, each source point's kernel
        normalized to conserve mass; separable per dimension when ``Q`` is diagonal, dense
        otherwise. The kernel variance is floored at a quarter of the squared grid spacing."""
        p = self.part.p
        n = len(p)
        mesh = np.meshgrid(*density.axes, indexing="ij")
        w = (density.values * density.cell).ravel()
        keep = w > 1e-16 * w.max()
        X = np.tile(x, (int(keep.sum()), 1))
        for d, i in enumerate(p):
            X[:, i] = mesh[d].ravel()[keep]
        fx = self.part.model.f_batch(X, u, dt)[:, p]
        w = w[keep]
        mean = w @ fx / w.sum()
        dev = fx - mean
        cov = (dev * w[:, None]).T @ dev / w.sum() + inc.D
        new = density.grid(mean, cov)
        spacing = np.array([a[1] - a[0] for a in new])
        Q = inc.D + np.diag(np.maximum(0.25 * spacing**2 - np.diag(inc.D), 0.0))
        if np.allclose(Q, np.diag(np.diag(Q))):
            Ks = [np.exp(-0.5 * (new[d][:, None] - fx[None, :, d]) ** 2 / Q[d, d])
                  for d in range(n)]
            norm = np.prod([K.sum(axis=0) for K in Ks], axis=0)
            src = np.where(norm > 0, w / np.where(norm > 0, norm, 1.0), 0.0)
            if n == 1:
                out = Ks[0] @ src
            elif n == 2:
                out = (Ks[0] * src) @ Ks[1].T
            else:
                out = np.einsum("ai,bi,ci,i->abc", Ks[0], Ks[1], Ks[2], src)
        else:
            mesh_new = np.stack(np.meshgrid(*new, indexing="ij"), axis=-1).reshape(-1, n)
            Li = np.linalg.inv(np.linalg.cholesky(Q))
            out = np.zeros(mesh_new.shape[0])
            norm = np.zeros(fx.shape[0])
            blocks = []
            for c in range(0, fx.shape[0], 512):
                e = (mesh_new[:, None, :] - fx[None, c:c + 512, :]) @ Li.T
                Kc = np.exp(-0.5 * np.sum(e * e, axis=-1))
                norm[c:c + 512] = Kc.sum(axis=0)
                blocks.append(Kc)
            src = np.where(norm > 0, w / np.where(norm > 0, norm, 1.0), 0.0)
            for b, c in zip(blocks, range(0, fx.shape[0], 512), strict=True):
                out += b @ src[c:c + 512]
        density.set_axes(new)
        density.values = out.reshape([a.size for a in new]) / density.cell
