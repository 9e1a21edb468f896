"""Point-mass (grid) Bayes filter: the reference posterior of terrain navigation.

The density of the gridded states ``p`` (all states of a low-dimensional model; the position of
the TAN model, whose velocities are handled by the conditional Kalman filter of
:mod:`uwcosim.filters.grid.partition`, exactly as in ``pfm_psi``) lives on a regular grid of
``n_points`` per dimension spanning ``mean -+ span * sigma`` (Bergman 1999). Following the
Lagrangian grid-based filters of Matousek, Dunik and Straka, the grid is chosen anew at every
prediction from the predicted mean and covariance (re-centred and re-scaled to the support):

- *drift independent of the gridded states* (TAN: the position moves by the rotated velocity):
  the new grid is pulled back by the mean increment ``d`` and the posterior is interpolated there
  (cubic B-spline, zero outside the old grid), then convolved with the increment's Gaussian
  ``N(0, D)`` by FFT (zero-padded, exact characteristic function ``exp(-w' D w / 2)``);
- *general drift*: Chapman-Kolmogorov sum ``p'(x'_j) = sum_i N(x'_j; f(x_i), Q) p(x_i)`` with the
  model's one-step map ``f`` and covariance ``Q`` at the mean, each source point's kernel
  normalized to conserve mass; separable per dimension when ``Q`` is diagonal, dense otherwise.
  The kernel variance is floored at a quarter of the squared grid spacing.

The update multiplies by the likelihood on the grid (:class:`GridLikelihood`). Settings:
``n_points`` (per dimension, default 101), ``span`` (half-width in standard deviations, 8),
``states``, ``measurements``, ``long_run`` (as for ``pfm_psi``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import scipy.fft as sfft
from pydantic import Field, StrictBool, StrictFloat, StrictInt, StrictStr
from scipy import ndimage, sparse

from uwcosim.core import bspline
from uwcosim.core.errors import FilterDivergence
from uwcosim.filters.base import Estimator, register
from uwcosim.filters.grid import projection_kernels as pk  # imports point_mass_kernels
from uwcosim.filters.grid.conditional import (
    ConditionalKalman,
    assemble_estimate,
    begin_update,
    block_index,
)
from uwcosim.filters.grid.likelihood import GridLikelihood
from uwcosim.filters.grid.partition import Partition, symbolic
from uwcosim.filters.grid.point_mass_fft import (
    _fast_len,
    _FFTPlan,
    _inverse_bspline_factors,
    _unit_frequencies,
)
from uwcosim.filters.grid.spectral import axes_moments
from uwcosim.filters.numerics import symmetrize
from uwcosim.filters.settings import MEASUREMENTS, STATES, FilterSettings, Measurements

# isort: split
from uwcosim.filters.grid import point_mass_kernels as pmk  # after projection_kernels

_TAPS = np.arange(-1, 3)
_POWERS = np.arange(4.0)
_SPLINE_MATRICES: dict[tuple[int, int], sparse.csr_matrix] = {}
SPLINE_PAD = 7  # zero padding for the spline prefilter (its impulse response: 0.27^|k|)


@lru_cache(maxsize=32)
def _inverse_bspline_symbol(shape: tuple[int, ...]) -> np.ndarray:
    """``1 / prod_d (4 + 2 cos w_d) / 6``: the cubic B-spline prefilter on a real FFT grid."""
    out = 1.0
    for o in _unit_frequencies(shape):
        out = out * (6.0 / (4.0 + 2.0 * np.cos(o)))
    return out


def _spline_matrix(coords: np.ndarray, n: int, size: int) -> sparse.csr_matrix:
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
    a, b = (o / spacing[d] for d, o in enumerate(_unit_frequencies(shape)))
    kern = np.exp((-D[0, 1] * a) * b)
    col, row = _inverse_bspline_factors(shape)
    kern *= np.exp((-0.5 * D[0, 0]) * a * a) * col
    kern *= np.exp((-0.5 * D[1, 1]) * b * b) * row
    return kern


def shift_blur(values: np.ndarray, spacing, coords: list[np.ndarray], D: np.ndarray,
               fast: bool = False):
    """Prediction of a drift independent of the grid: ``(p * N(0, D))`` at shifted points.

    One zero-padded real FFT: the Gaussian ``exp(-w' D w / 2)`` and the cubic B-spline
    prefilter are applied together, then the spline is evaluated at the fractional grid
    coordinates ``coords`` (one array per axis, in units of the old spacing; zero outside the
    old grid) by one sparse banded matrix per axis. ``fast`` (two dimensions): the spline by the
    compiled kernel :func:`projection_kernels.spline_shift_2d`, which also clips at 0.
    """
    n = values.ndim
    D = np.asarray(D, dtype=float)
    if fast and n == 2:
        return _shift_blur_2d(values, spacing, coords, D)
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
        out = _spline_matrix(coords[0], values.shape[0], shape[0]) @ out
        B = _spline_matrix(coords[1], values.shape[1], shape[1])
        return (B @ out.T).T
    oms = [o / spacing[d] for d, o in enumerate(_unit_frequencies(shape))]
    quad = 0.0
    for r in range(n):
        quad = quad + (0.5 * D[r, r]) * oms[r] * oms[r]
        for s in range(r + 1, n):
            quad = quad + D[r, s] * oms[r] * oms[s]
    X *= np.exp(-quad) * _inverse_bspline_symbol(shape)
    out = sfft.irfftn(X, s=shape)
    for d in range(n):
        B = _spline_matrix(coords[d], values.shape[d], shape[d])
        moved = np.moveaxis(out, d, 0)
        res = B @ moved.reshape(shape[d], -1)
        out = np.moveaxis(res.reshape((B.shape[0],) + moved.shape[1:]), 0, d)
    return out


#: largest grid memory (bytes) a point-mass filter may ask for
MAX_GRID_BYTES = 4 * 2**30


def _shift_blur_2d(values: np.ndarray, spacing, coords: list[np.ndarray], D: np.ndarray):
    """:func:`shift_blur` in two dimensions with fewer calls: the FFTs are ``rfft2``/``irfft2``
    on the zero-padded input, the spline is the compiled
    :func:`projection_kernels.spline_shift_2d` (clipped at 0)."""
    n0, n1 = values.shape
    p0 = max(int(math.ceil(7.0 * math.sqrt(max(D[0, 0], 0.0)) / spacing[0])) + 1, SPLINE_PAD)
    p1 = max(int(math.ceil(7.0 * math.sqrt(max(D[1, 1], 0.0)) / spacing[1])) + 1, SPLINE_PAD)
    shape = (sfft.next_fast_len(n0 + min(p0, n0), real=True),
             sfft.next_fast_len(n1 + min(p1, n1), real=True))
    buf = np.zeros(shape)
    buf[:n0, :n1] = values
    X = sfft.rfft2(buf)
    X *= _gauss_prefilter_2d(shape, spacing, D)
    out = sfft.irfft2(X, s=shape)
    return pk.spline_shift_2d(out, coords[0], coords[1], n0, n1)


@register("point_mass")
class PointMassFilter(Estimator):
    """Grid (point-mass) Bayes filter with a grid re-centred on the support every step."""

    class Settings(FilterSettings):
        n_points: StrictInt | list[StrictInt] = Field(101, description="grid points per gridded "
                                                      "state (>= 5; one value or one per state)")
        span: StrictFloat = Field(8.0, gt=0, description="half-width of the grid in standard "
                                  "deviations")
        states: list[StrictStr | StrictInt] | None = Field(None, description=STATES)
        measurements: Measurements = Field(None, description=MEASUREMENTS)
        long_run: StrictBool = Field(True, description="conditional Kalman filter of the other "
                                     "states in its long-run form")

    def __init__(self, model, x0, P0, **settings) -> None:
        model = symbolic(model)
        super().__init__(model, x0, P0, **settings)
        s = self.settings
        n_points, span, states, measurements = s.n_points, s.span, s.states, s.measurements
        long_run = s.long_run
        self.part = Partition(model, states, measurements)
        self.kalman = ConditionalKalman(model, self.part, self.x, self.P, long_run)
        self.likelihood = GridLikelihood(model, self.part)
        p = self.part.p
        n = len(p)
        self.n_points = [int(v) for v in np.broadcast_to(np.asarray(n_points), (n,))]
        if min(self.n_points) < 5 or not span > 0:
            raise ValueError("n_points must be >= 5 and span > 0")
        need = float(np.prod(np.asarray(self.n_points, dtype=float))) * 8.0 * (2 * n + 6)
        if need > MAX_GRID_BYTES:  # the grid, its mesh and work arrays
            raise ValueError(f"n_points {self.n_points} needs about {need / 2**30:.3g} GiB "
                             f"(limit {MAX_GRID_BYTES / 2**30:g} GiB): use fewer points")
        self.span = float(span)
        self._unit = [np.linspace(-1.0, 1.0, m) for m in self.n_points]
        self._ip, self._ik = block_index(p), block_index(self.part.k)
        self._pp, self._kk = block_index(p, p), block_index(self.part.k, self.part.k)
        self._keys = [(f"interval_lo_{m}", f"interval_hi_{m}") for m in self.part.names]
        mean, cov = self.x[p], self.P[np.ix_(p, p)]
        if np.any(np.diag(cov) <= 0):
            raise ValueError("P0 must have a positive variance for every gridded state")
        self.axes = self._grid(mean, cov)
        mesh = np.stack(np.meshgrid(*self.axes, indexing="ij"), axis=-1) - mean
        y = np.linalg.solve(np.linalg.cholesky(cov), mesh.reshape(-1, n).T)
        self.values = np.exp(-0.5 * np.sum(y * y, axis=0)).reshape(mesh.shape[:-1])
        self._normalize()
        self._mean, self._cov = mean, cov
        self._after_update = False
        #: compiled kernels (projection_kernels) for two gridded states when Numba is there;
        #: False runs the numpy code (same results to round-off)
        self.fast: bool = bool(pk.ENABLED and n == 2)
        self._plans: dict[tuple[int, int], _FFTPlan] = {}  # FFT work arrays per shape
        self.kalman.fast = self.fast
        self._var = [float(v) for v in np.diag(model.R)]
        self._set_estimate()

    # ------------------------------------------------------------------------------------------
    def _grid(self, mean, cov) -> list[np.ndarray]:
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        half = np.maximum(self.span * sig, 1e-9 * np.maximum(1.0, np.abs(mean)))
        out = []
        for d in range(len(mean)):
            a = self._unit[d] * half[d]  # linspace(mean - half, mean + half, n)
            a += mean[d]
            out.append(a)
        return out

    @property
    def axes(self) -> list[np.ndarray]:
        return self._axes

    @axes.setter
    def axes(self, axes: list[np.ndarray]) -> None:
        self._axes = axes
        spacing = [a.item(1) - a.item(0) for a in axes]
        self._spacing = np.array(spacing)
        self._cell = math.prod(spacing)

    @property
    def spacing(self) -> np.ndarray:
        return self._spacing.copy()

    @property
    def cell(self) -> float:
        return self._cell

    def _normalize(self, clip: bool = True) -> None:
        if clip:
            self.values = np.maximum(self.values, 0.0, out=self.values)
        mass = float(self.values.sum() * self._cell)
        if not np.isfinite(mass) or mass <= 0:
            raise FilterDivergence(f"{self.kind}: grid density lost its mass ({mass})")
        self.values /= mass

    def _set_estimate(self) -> None:
        self.x, self.P = assemble_estimate(self)

    # ------------------------------------------------------------------------------------------
    def predict(self, u, dt: float) -> None:
        self.diagnostics = {}
        self._after_update = False
        u = np.asarray(u, dtype=float).reshape(-1)
        inc = self.kalman.increment(self.x, u, dt)
        if self.part.drift_constant and self.fast:
            self._predict_shift_fast(inc)
        elif self.part.drift_constant:
            new = self._grid(self._mean + inc.d, self._cov + inc.D)
            old = self.spacing
            coords = [(new[d] - inc.d[d] - self.axes[d][0]) / old[d] for d in range(len(new))]
            vals = shift_blur(self.values, old, coords, inc.D, self.fast)
            self.values = vals if self.fast else np.maximum(vals, 0.0, out=vals)
            self.axes = new
            self._normalize(clip=False)
            # translation and Gaussian convolution: the moments propagate exactly
            self._mean, self._cov = self._mean + inc.d, symmetrize(self._cov + inc.D)
        else:
            self._chapman_kolmogorov(u, dt, inc)
            self._normalize()
            self._mean, self._cov = axes_moments(self.axes, self.values)
        self._set_estimate()

    def _predict_shift_fast(self, inc) -> None:
        """The drift-independent prediction (:func:`shift_blur` and the moments) in three
        compiled kernels around the two FFTs."""
        D = inc.D
        sp0, sp1 = self._spacing.tolist()
        n0, n1 = self.values.shape
        p0 = max(int(math.ceil(7.0 * math.sqrt(max(D.item(0), 0.0)) / sp0)) + 1, SPLINE_PAD)
        p1 = max(int(math.ceil(7.0 * math.sqrt(max(D.item(3), 0.0)) / sp1)) + 1, SPLINE_PAD)
        shape = (_fast_len(n0 + min(p0, n0)), _fast_len(n1 + min(p1, n1)))
        plan = self._plans.get(shape)  # per filter: filters in other threads have their own
        if plan is None:
            if len(self._plans) > 8:
                self._plans.clear()
            plan = self._plans[shape] = _FFTPlan(shape)
        new0, new1, c0, c1, mean, cov = pk.pm_grid_shift(
            self.values, self._axes[0], self._axes[1], self._mean, self._cov, inc.d, D,
            self.span, self._unit[0], self._unit[1], plan.buf)
        X = plan.forward()
        pk.pm_gauss_prefilter(X, shape[1], sp0, sp1, D, plan.col, plan.row)
        out = plan.inverse()
        self.axes = [new0, new1]
        self.values, mass = pk.pm_finish(out, c0, c1, n0, n1, self._cell)
        if not (math.isfinite(mass) and mass > 0):
            self.diverged = True
            raise FilterDivergence(f"{self.kind}: grid density lost its mass ({mass})")
        self._mean, self._cov = mean, cov

    def _chapman_kolmogorov(self, u, dt: float, inc) -> None:
        p = self.part.p
        n = len(p)
        mesh = np.meshgrid(*self.axes, indexing="ij")
        w = (self.values * self.cell).ravel()
        keep = w > 1e-16 * w.max()
        X = np.tile(self.x, (int(keep.sum()), 1))
        for d, i in enumerate(p):
            X[:, i] = mesh[d].ravel()[keep]
        fx = self.model.f_batch(X, u, dt)[:, p]
        w = w[keep]
        mean = w @ fx / w.sum()
        dev = fx - mean
        cov = (dev * w[:, None]).T @ dev / w.sum() + inc.D
        new = self._grid(mean, cov)
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
        self.axes = new
        self.values = out.reshape([a.size for a in new]) / self.cell

    def update(self, z, mask=None) -> None:
        z, rows_k, rows_g = begin_update(self, z, mask)
        if rows_g and self.fast and len(rows_g) == 1 and rows_g[0] in self.likelihood.terrain_rows:
            r = rows_g[0]
            tg = self.likelihood.terrain_rows[r]
            ax = self.axes
            E, llmax = pk.terrain_exponent(ax[0], ax[1], tg.t.coefficients, tg.tpar, tg.ipar,
                                           float(z[r]), self._var[r])
            np.exp(E, out=E)
            post, Z, self._mean, self._cov = pk.grid_product_moments(self.values, E, self._cell,
                                                                     ax[0], ax[1])
            if math.isfinite(Z) and Z > 0:
                self.values = post
                self.diagnostics["loglik"] = math.log(Z) + llmax
            else:
                self.diagnostics["update_skipped"] = 1.0
            self._finish_update()
            return
        if rows_g:
            post = self.likelihood.loglik(self.axes, z, rows_g, self.x)
            llmax = float(post.max())
            post -= llmax
            np.exp(post, out=post)
            post *= self.values
            Z = float(post.sum() * self._cell)
            if np.isfinite(Z) and Z > 0:
                post /= Z
                self.values = post
                self.diagnostics["loglik"] = float(np.log(Z) + llmax)
            else:
                self.diagnostics["update_skipped"] = 1.0
        if self.fast:
            self._mean, self._cov = pmk.pm_moments(self.values, self._axes[0], self._axes[1])
        else:
            self._mean, self._cov = axes_moments(self.axes, self.values)
        self._finish_update()

    def _finish_update(self) -> None:
        self._set_estimate()
        d = self.diagnostics
        d["n_points"] = float(self.values.size)
        for (klo, khi), a in zip(self._keys, self._axes, strict=True):
            d[klo] = a.item(0)
            d[khi] = a.item(-1)

    # ------------------------------------------------------------------------------------------
    @property
    def gridded_states(self) -> list[str]:
        return self.part.names

    def density_grid(self, axes=None, n: int | None = None):
        """Posterior density on a tensor grid: ``(axes, values)`` (default: the filter's grid).

        Other ``axes`` are served by cubic interpolation (zero outside the grid); ``n`` asks for
        ``n`` points per dimension across the grid.
        """
        if axes is None and n is None:
            return [a.copy() for a in self.axes], self.values.copy()
        if axes is None:
            axes = [np.linspace(a[0], a[-1], n) for a in self.axes]
        axes = [np.asarray(a, dtype=float) for a in axes]
        coords = [(a - self.axes[d][0]) / self.spacing[d] for d, a in enumerate(axes)]
        mesh = np.meshgrid(*coords, indexing="ij")
        vals = ndimage.map_coordinates(self.values, mesh, order=3, mode="constant", cval=0.0)
        return axes, np.maximum(vals, 0.0)
