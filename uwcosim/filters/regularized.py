"""Regularized particle filter (``rpf``): kernel jitter after resampling.

Musso, Oudjane & Le Gland, "Improving regularised particle filters", in *Sequential Monte Carlo
Methods in Practice* (Doucet, de Freitas, Gordon eds.), Springer 2001, ch. 12. The bootstrap
filter of :mod:`uwcosim.filters.particle`, except that after each resampling every particle is
moved by a draw of the Gaussian kernel scaled to the particle cloud::

    X_i <- X_i + h D e_i,   e_i ~ N(0, I),   D D' = S = sum_j w_j (X_j - x)(X_j - x)'

with ``S`` the weighted empirical covariance *before* resampling and the bandwidth of the
optimal Gaussian kernel (the one minimizing the mean integrated squared error when the density
is Gaussian with covariance ``S``)::

    h_opt = A N^(-1/(n+4)),   A = (4 / (n + 2))^(1/(n+4))       (n: state dimension)

times ``bandwidth_scale`` (1 = ``h_opt``; Musso et al. advise smaller values for multimodal
densities). The jitter restores the diversity that resampling removes (copies of one particle
split again) at the price of inflating the covariance by ``1 + h^2`` at each resampling: with
frequent resampling and weak measurements (flat terrain) the cloud then grows geometrically.
``shrink = true`` uses the kernel shrinkage of Liu & West (2001) instead, which keeps the mean
and the covariance of the cloud: ``X_i <- a X_i + (1 - a) x + h D e_i`` with
``a = sqrt(1 - h^2)`` (requires ``h < 1``).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, StrictBool, StrictFloat

from uwcosim.filters.base import register
from uwcosim.filters.numerics import psd_factor
from uwcosim.filters.particle import ParticleCloud, ParticleFilter
from uwcosim.filters.settings import Measurements, measurements_field


def optimal_bandwidth(n_particles: int, dim: int) -> float:
    """``h_opt = (4 / (n + 2))^(1/(n+4)) N^(-1/(n+4))`` of the Gaussian kernel."""
    e = 1.0 / (dim + 4.0)
    return (4.0 / (dim + 2.0)) ** e * float(n_particles) ** (-e)


@register("rpf")
class RegularizedPF(ParticleFilter):
    """Post-regularized particle filter (Gaussian kernel, optimal bandwidth).

    ``bandwidth_scale = 1`` is the optimal bandwidth ``h_opt``; ``shrink`` false is plain
    jitter, true Liu-West shrinkage. ``diagnostics['bandwidth']`` is ``h`` at a resampling
    step.
    """

    class Settings(ParticleCloud.Settings):
        bandwidth_scale: StrictFloat = Field(1.0, ge=0, description="times the optimal "
                                             "Gaussian kernel bandwidth")
        shrink: StrictBool = Field(False, description="Liu-West shrinkage (keeps the cloud's "
                                   "mean and covariance)")
        measurements: Measurements = measurements_field()

    def __init__(self, model, x0, P0, **kw) -> None:
        super().__init__(model, x0, P0, **kw)
        self.bandwidth = self.settings.bandwidth_scale * optimal_bandwidth(self.n,
                                                                           self.model.nx)
        self.shrink = self.settings.shrink
        if self.shrink and not self.bandwidth < 1.0:
            raise ValueError(f"shrink needs a bandwidth below 1, got {self.bandwidth:.3g}")
        self._plain_resample = self.resample
        self.resample = self._resample_and_measure
        self._kernel: np.ndarray | None = None

    def _resample_and_measure(self, w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The resampling scheme, after taking the kernel factor ``D`` from the weighted
        particles it is about to resample (they are still ``self.particles``)."""
        X = self.particles
        m = X @ w
        Dev = X - m[:, None]
        S = (Dev * w) @ Dev.T
        self._kernel = psd_factor(0.5 * (S + S.T))
        self._kernel_mean = m
        return self._plain_resample(w, rng)

    def update(self, z, mask=None) -> None:
        self._kernel = None
        super().update(z, mask)
        if self._kernel is not None and self.bandwidth > 0.0:
            jitter = self._kernel @ self.rng.standard_normal(self.particles.shape)
            jitter *= self.bandwidth
            if self.shrink:  # a X_i + (1 - a) x + h D e_i: mean and covariance kept
                a = math.sqrt(1.0 - self.bandwidth**2)
                jitter += (1.0 - a) * self._kernel_mean[:, None]
                jitter += a * self.particles
                self.particles = jitter
            else:
                self.particles = self.particles + jitter
            self._moved()
            self.diagnostics["bandwidth"] = self.bandwidth
