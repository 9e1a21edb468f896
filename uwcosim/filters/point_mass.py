"""Point-mass (grid) Bayes filter: the reference posterior of terrain navigation.

The density of the gridded states ``p`` (all states of a low-dimensional model; the position of
the TAN model, whose velocities are handled by the conditional Kalman filter of
:mod:`uwcosim.filters.projection_model`, exactly as in ``pfm_psi``) lives on a regular grid of
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

import numpy as np
import scipy.fft as sfft
from scipy import ndimage

from uwcosim.errors import FilterDivergence
from uwcosim.filters.base import Estimator, register
from uwcosim.filters.numerics import symmetrize
from uwcosim.filters.projection_likelihood import GridLikelihood
from uwcosim.filters.projection_model import ConditionalKalman, Partition


def hellinger(p: np.ndarray, q: np.ndarray) -> float:
    """Hellinger distance of two densities sampled on the same uniform grid.

    ``H^2 = 1 - sum sqrt(p q) / sqrt(sum p sum q)`` (negative values clipped), in [0, 1].
    """
    p = np.maximum(np.asarray(p, float), 0.0)
    q = np.maximum(np.asarray(q, float), 0.0)
    bc = np.sum(np.sqrt(p * q)) / np.sqrt(p.sum() * q.sum())
    return float(np.sqrt(max(0.0, 1.0 - bc)))


def gaussian_convolve(values: np.ndarray, spacing, D: np.ndarray) -> np.ndarray:
    """Linear convolution of grid values with ``N(0, D)`` by FFT (zero-padded, same shape)."""
    n = values.ndim
    sig = np.sqrt(np.maximum(np.diag(D), 0.0))
    pads = [int(min(np.ceil(7.0 * sig[d] / spacing[d]) + 1, values.shape[d])) for d in range(n)]
    shape = [sfft.next_fast_len(values.shape[d] + pads[d], real=True) for d in range(n)]
    X = sfft.rfftn(values, s=shape)
    oms = []
    for d in range(n):
        freq = sfft.rfftfreq if d == n - 1 else sfft.fftfreq
        f = freq(shape[d], spacing[d])
        o = 2.0 * np.pi * f
        s = [1] * n
        s[d] = o.size
        oms.append(o.reshape(s))
    quad = sum(oms[r] * D[r, s] * oms[s] for r in range(n) for s in range(n))
    out = sfft.irfftn(X * np.exp(-0.5 * quad), s=shape)
    return out[tuple(slice(0, values.shape[d]) for d in range(n))]


def _moments(axes, w):
    n = len(axes)
    w = w / w.sum()
    mean = np.empty(n)
    marg = []
    for d in range(n):
        m = w.sum(axis=tuple(i for i in range(n) if i != d))
        marg.append(m)
        mean[d] = m @ axes[d]
    cov = np.empty((n, n))
    for r in range(n):
        cov[r, r] = marg[r] @ (axes[r] - mean[r]) ** 2
        for s in range(r + 1, n):
            m2 = w.sum(axis=tuple(i for i in range(n) if i not in (r, s)))
            cov[r, s] = cov[s, r] = (axes[r] - mean[r]) @ m2 @ (axes[s] - mean[s])
    return mean, cov



@register("point_mass")
class PointMassFilter(Estimator):
    """Grid (point-mass) Bayes filter with a grid re-centred on the support every step."""

    def __init__(
        self,
        model,
        x0,
        P0,
        n_points: int | list[int] = 101,
        span: float = 8.0,
        states: list | None = None,
        measurements: list[str] | None = None,
        long_run: bool = True,
    ) -> None:
        super().__init__(model, x0, P0)
        self.part = Partition(model, states, measurements)
        self.kalman = ConditionalKalman(model, self.part, self.x, self.P, long_run)
        self.likelihood = GridLikelihood(model, self.part)
        p = self.part.p
        n = len(p)
        self.n_points = [int(v) for v in np.broadcast_to(np.asarray(n_points), (n,))]
        if min(self.n_points) < 5 or not span > 0:
            raise ValueError("n_points must be >= 5 and span > 0")
        self.span = float(span)
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
        self._set_estimate()

    # ------------------------------------------------------------------------------------------
    def _grid(self, mean, cov) -> list[np.ndarray]:
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        half = np.maximum(self.span * sig, 1e-9 * np.maximum(1.0, np.abs(mean)))
        return [np.linspace(mean[d] - half[d], mean[d] + half[d], self.n_points[d])
                for d in range(len(mean))]

    @property
    def spacing(self) -> np.ndarray:
        return np.array([a[1] - a[0] for a in self.axes])

    @property
    def cell(self) -> float:
        return float(np.prod(self.spacing))

    def _normalize(self) -> None:
        self.values = np.maximum(self.values, 0.0)
        mass = float(self.values.sum() * self.cell)
        if not np.isfinite(mass) or mass <= 0:
            self.diverged = True
            raise FilterDivergence(f"{self.kind}: grid density lost its mass ({mass})")
        self.values /= mass

    def _set_estimate(self) -> None:
        p, k = self.part.p, self.part.k
        x = self.x.copy()
        P = np.zeros_like(self.P)
        x[p] = self._mean
        P[np.ix_(p, p)] = self._cov
        if k:
            x[k] = self.kalman.mean
            P[np.ix_(k, k)] = self.kalman.cov
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            self.diverged = True
            raise FilterDivergence(f"{self.kind}: non-finite estimate")
        self.x, self.P = x, symmetrize(P)

    # ------------------------------------------------------------------------------------------
    def predict(self, u, dt: float) -> None:
        self.diagnostics = {}
        self._after_update = False
        u = np.asarray(u, dtype=float).reshape(-1)
        inc = self.kalman.increment(self.x, u, dt)
        if self.part.drift_constant:
            new = self._grid(self._mean + inc.d, self._cov + inc.D)
            coords = [(new[d] - inc.d[d] - self.axes[d][0]) / self.spacing[d]
                      for d in range(len(new))]
            mesh = np.meshgrid(*coords, indexing="ij")
            vals = ndimage.map_coordinates(self.values, mesh, order=3, mode="constant", cval=0.0)
            spacing = np.array([a[1] - a[0] for a in new])
            self.values = gaussian_convolve(np.maximum(vals, 0.0), spacing, inc.D)
            self.axes = new
        else:
            self._chapman_kolmogorov(u, dt, inc)
        self._normalize()
        self._mean, self._cov = _moments(self.axes, self.values)
        self._set_estimate()

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
        if self._after_update:
            self.diagnostics = {}
        self._after_update = True
        z, rows_k, rows_g = self.part.split_rows(z, mask, self.model.nz)
        self.kalman.update(self.x, z, rows_k, self.diagnostics)
        if rows_g:
            ll = self.likelihood.loglik(self.axes, z, rows_g, self.x)
            llmax = float(np.max(ll))
            post = self.values * np.exp(ll - llmax)
            Z = float(post.sum() * self.cell)
            if np.isfinite(Z) and Z > 0:
                self.values = post / Z
                self.diagnostics["loglik"] = float(np.log(Z) + llmax)
            else:
                self.diagnostics["update_skipped"] = 1.0
        self._mean, self._cov = _moments(self.axes, self.values)
        self._set_estimate()
        d = self.diagnostics
        d["n_points"] = float(self.values.size)
        for i, name in enumerate(self.part.names):
            d[f"interval_lo_{name}"] = float(self.axes[i][0])
            d[f"interval_hi_{name}"] = float(self.axes[i][-1])

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
