"""PFM-PSI: the projection filter on a projection symmetric interval (seed 000, section 3).

The density of the gridded states ``p`` (all states of a low-dimensional model; the position
``(x, y)`` of the TAN model) is the truncated complex-exponential series of
:mod:`~uwcosim.filters.projection.series` on the box ``E +- k_sigma * sigma`` (eq. 33). The
other states ``k`` (the DVL-measured velocities of the TAN model) are handled by a conditional
Kalman filter (:mod:`uwcosim.filters.grid.conditional`). One step:

1. *Re-centring* (eq. 33): the box is centred on the predicted mean with half-width ``k_sigma``
   predicted standard deviations; the coefficients are re-projected exactly from the old box
   (the old series taken as zero outside it) by per-axis transfer matrices
   (:mod:`~uwcosim.filters.projection.series`).
2. *Prediction* (eqs. 15, 23, 41-43): ``m- = exp(A dt) m`` with ``A`` the Galerkin matrix of the
   Fokker-Planck operator; a translation and a Gaussian decay when the drift does not depend on
   the gridded states (:mod:`~uwcosim.filters.projection.prediction`).
3. *Bayes update* (eqs. 45-48) with its moments (eqs. 50-51), the positivity repairs of the
   truncated series, the representation-error inflation, the refinement of the box and the gate
   (:mod:`~uwcosim.filters.projection.bayes`).

Each step has a numpy form (any number of gridded states, every setting) and a compiled form
(two gridded states, ``positivity`` ``"auto"`` or ``"none"``, no spectral filter; Numba,
:mod:`uwcosim.core.jit`), chosen once when the filter is built (:attr:`ProjectionFilter.fast`);
they give the same results to round-off (``tests/test_projection_kernels.py``). The frame of the
steps (partition, Kalman block, ``predict``, ``update``) is
:class:`~uwcosim.filters.grid.estimator.GridFilter`, shared with the point mass.

Deviations from the paper (docs/projection_filter.md):

- frequencies ``q = -K..K`` (``2K+1`` functions per dimension) instead of ``q = 0..N-1``: the
  positive set cannot represent a real density nor the coupling ``q <-> q -+ k`` that an
  ``x``-dependent drift creates;
- eq. 33 is garbled in the extraction (``-E - 10C``): implemented as
  ``[E - k_sigma sigma, E + k_sigma sigma]`` per dimension with the predicted ``E``, ``sigma``;
  the paper's 10 sigma is the setting ``k_sigma``, narrower by default: with ``K = 10`` a box of
  20 sigma resolves a Gaussian only to 1e-2 and the filter loses the track on rough terrain (see
  the docs for the numbers);
- re-projection uses exact integrals, inner products the FFT quadrature on ``M`` points
  (``grid_factor (2K+1)``) instead of ``K`` interval points.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, StrictBool, StrictFloat, StrictInt, StrictStr

from uwcosim.core.memory import memory_problem
from uwcosim.filters.base import register
from uwcosim.filters.grid.estimator import GridFilter
from uwcosim.filters.projection.bayes import BayesUpdate, Positivity
from uwcosim.filters.projection.bayes_kernels import CompiledBayesUpdate
from uwcosim.filters.projection.prediction import Prediction
from uwcosim.filters.projection.prediction_kernels import CompiledPrediction
from uwcosim.filters.projection.series import (
    SeriesDensity,
    SeriesOps,
    SpectralBasis,
    evaluate,
    fft_size,
    gaussian_coefficients,
    symmetric_interval,
)
from uwcosim.filters.projection.series_kernels import CompiledSeriesOps
from uwcosim.filters.robust import StudentTNu, student_t_field
from uwcosim.filters.settings import MEASUREMENTS, STATES, FilterSettings, Measurements


@register("pfm_psi")
class ProjectionFilter(GridFilter):
    """PFM-PSI projection filter (complex-exponential Galerkin projection of the FPE)."""

    class Settings(FilterSettings):
        K: StrictInt = Field(10, ge=1, description="highest harmonic per dimension")
        k_sigma: StrictFloat = Field(4.0, gt=0, description="half-width of the box (eq. 33) in "
                                     "predicted standard deviations")
        states: list[StrictStr | StrictInt] | None = Field(None, description=STATES)
        measurements: Measurements = Field(None, description=MEASUREMENTS)
        grid_factor: StrictFloat = Field(2.5, ge=2, description="quadrature points per basis "
                                         "function and dimension")
        positivity: Positivity = Field(
            "auto", description="treatment of negative lobes of the truncated series")
        spectral_filter: StrictFloat = Field(0.0, ge=0, description="even order of an "
                                             "exponential filter (0 = off)")
        long_run: StrictBool = Field(True, description="conditional Kalman filter of the other "
                                     "states in its long-run form")
        min_halfwidth: StrictFloat = Field(0.0, ge=0, description="floor of the box half-width")
        resolution_inflation: StrictFloat = Field(
            1.0, ge=0, description="inflate R by the variation of h within a resolution cell "
            "(1 = on)")
        refine: StrictFloat = Field(0.7, gt=0, description="redo the product on the "
                                    "posterior box below this width ratio (1 = off)")
        neg_limit: StrictFloat = Field(0.1, ge=0, description="negative mass above which 'auto' "
                                       "thresholds")
        moment_match: StrictBool = Field(True, description="give the series the grid "
                                         "posterior's mean and covariance after a threshold")
        gate: StrictFloat = Field(5.0, ge=0, description="implausible-measurement gate in "
                                  "standard deviations (0 = off)")
        student_t_nu: StudentTNu = student_t_field()  # filters.robust

    size_key = "n_basis"

    @classmethod
    def compiles(cls, settings) -> bool:
        return settings.positivity in ("auto", "none") and settings.spectral_filter == 0

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)  # the partition, Kalman block, likelihood
        s = self.settings
        p = self.part.p
        M = fft_size(s.grid_factor * (2 * s.K + 1))
        if not self.part.drift_constant:
            M = max(M, fft_size(4 * s.K + 2))
        # the quadrature grids (M^d points: three work grids, the posterior, the likelihood,
        # complex FFT buffers: about 12 float64 per point), estimated before they are made
        why = memory_problem(float(M) ** len(p) * 8.0 * 12,
                             f"K {s.K}, grid_factor {s.grid_factor:g} ({M}^{len(p)} grid "
                             f"points)", "use a smaller K or grid_factor")
        if why:
            raise ValueError(why)
        mean, cov = self.gridded_prior()
        basis = SpectralBasis(*symmetric_interval(mean, cov, s.k_sigma, s.min_halfwidth), s.K,
                              M)
        #: the density of the gridded states: the series on its box, and its moments
        self.density = SeriesDensity(gaussian_coefficients(mean, cov, basis), basis, mean, cov)
        self._n_basis = float(basis.size)
        if self.fast:
            ops = CompiledSeriesOps(self.kind, s.k_sigma, s.min_halfwidth)
            self.prediction = CompiledPrediction(self.part, self.kalman, ops)
            self.bayes = CompiledBayesUpdate(s, self.part, self.likelihood, self.kalman, ops,
                                             self.model.R, M)
        else:
            ops = SeriesOps(self.kind, s.k_sigma, s.min_halfwidth)
            self.prediction = Prediction(self.part, self.kalman, ops)
            self.bayes = BayesUpdate(s, self.part, self.likelihood, self.kalman, ops,
                                     self.model.R)
        self.begin(self.prediction.translate if self.part.drift_constant
                   else self.prediction.galerkin, mean, cov)

    # ------------------------------------------------------------------------------------------
    @property
    def m(self) -> np.ndarray:
        """The coefficients of the series."""
        return self.density.m

    @property
    def basis(self) -> SpectralBasis:
        """The series' basis: its box and quadrature grid."""
        return self.density.basis

    def representation(self) -> tuple[float, list[float], list[float]]:
        basis = self.density.basis
        lo, length = basis.lo.tolist(), basis.length.tolist()
        return self._n_basis, lo, [a + b for a, b in zip(lo, length, strict=True)]  # basis.hi

    # ------------------------------------------------------------------------------------------
    def density_grid(self, axes=None, n: int = 101, clip: bool = True):
        """Posterior density of the gridded states on a tensor grid.

        ``axes``: one array per gridded state (default: ``n`` points across the current box).
        Returns ``(axes, values)`` with ``values[i, j, ...]`` at ``(axes[0][i], axes[1][j], ...)``;
        zero outside the box; negative lobes clipped unless ``clip=False``.
        """
        basis = self.density.basis
        if axes is None:
            lo, hi = basis.lo, basis.hi
            axes = [np.linspace(lo[d], hi[d], n) for d in range(lo.size)]
        axes = [np.asarray(a, dtype=float) for a in axes]
        values = evaluate(self.density.m, basis, axes)
        return axes, (np.maximum(values, 0.0) if clip else values)
