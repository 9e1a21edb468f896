"""Compiled form of PFM-PSI's prediction for a drift independent of the gridded states (two
gridded states; the TAN model of seed 000): :class:`CompiledPrediction`.

One call per step, :func:`predict_step`: the conditional Kalman prediction of the velocities
with the increment ``(d, D)`` of the position (:func:`~uwcosim.filters.grid.
conditional_kernels.kalman_increment`), the translated, re-projected and decayed series on
the predicted box (eqs. 23, 33 and 44; :func:`predict_shift`) and the assembly of ``(x, P)``.
The same arithmetic as the numpy form
:meth:`Prediction.translate <uwcosim.filters.projection.prediction.Prediction.translate>` to
round-off (``tests/test_projection_kernels.py``). Bundles as NamedTuples or plain tuples of
their fields (:mod:`uwcosim.core.jit`): a :class:`~uwcosim.filters.grid.conditional_kernels.
ModelStep`, the :class:`~uwcosim.filters.grid.conditional_kernels.KalmanBlock`, a
:class:`~uwcosim.filters.projection.series_kernels.Series`.
"""

from __future__ import annotations

import math

from uwcosim.core.jit import jit
from uwcosim.filters.grid.conditional_kernels import assemble, kalman_increment
from uwcosim.filters.projection.prediction import Prediction, gaussian_fallback
from uwcosim.filters.projection.series import SeriesDensity
from uwcosim.filters.projection.series_kernels import box, shift_decay_mass
from uwcosim.filters.small_linalg import sym


@jit
def predict_shift(series, mean, cov, d, D, k_sigma, min_halfwidth):
    """The prediction of a series (a :class:`~uwcosim.filters.projection.series_kernels.Series`)
    for a drift independent of the gridded states.

    The moments move to ``(mean + d, cov + D)`` and the box to their symmetric interval; the
    series is translated by ``d`` and re-projected there, then decays by ``exp(-w' D w / 2)``.
    Returns ``(m, lo, length, mean, cov, mass)``; when the mass is finite and positive, ``m``
    is already made Hermitian and normalized
    (:func:`~uwcosim.filters.projection.series_kernels.shift_decay_mass`)."""
    m, lo, length = series
    mean2 = mean + d  # E- = E + d
    cov2 = cov + D  # C- = C + D
    lo2, len2 = box(mean2, cov2, k_sigma, min_halfwidth)  # eq. 33 at the predicted moments
    out, mass = shift_decay_mass((m, lo + d, length), (lo2, len2), D, True,
                                 math.sqrt(len2[0] * len2[1]), True)  # eqs. 23, 44
    return out, lo2, len2, mean2, sym(cov2), mass


@jit
def predict_step(step, kal, phi, use_phi, series, mean, cov, k_sigma, min_halfwidth):
    """One prediction after the model call ``step`` (a ``ModelStep``): the Kalman block
    ``kal`` predicted in place with the increment ``(d, D)``
    (:func:`~uwcosim.filters.grid.conditional_kernels.kalman_increment`), the series predicted
    (:func:`predict_shift`) and ``(x, P)`` assembled. Returns ``(m, lo, length, mass, x, P,
    finite)``; the predicted moments of the gridded block are written into ``mean``, ``cov``
    (fewer arrays to return: Numba boxes each one)."""
    d, D, _ = kalman_increment(step, kal, phi, use_phi)
    m2, lo2, len2, mean2, cov2, mass = predict_shift(series, mean, cov, d, D, k_sigma,
                                                     min_halfwidth)
    x2, P2, finite = assemble(kal, mean2, cov2)
    mean[:] = mean2
    cov[:, :] = cov2
    return m2, lo2, len2, mass, x2, P2, finite


class CompiledPrediction(Prediction):
    """:class:`~uwcosim.filters.projection.prediction.Prediction` with the translation in one
    compiled call (the Galerkin step stays the numpy form's)."""

    compiled = True

    def __init__(self, part, kalman, ops) -> None:
        super().__init__(part, kalman, ops)
        self._block = tuple(kalman.block)  # the kernels' argument (jit: plain tuples)

    def translate(self, density: SeriesDensity, x, u, dt: float, diag: dict):
        step = self.part.step
        _, F, Q = step.views(x, u, dt)  # consumed by the kernel at once
        phi, use_phi = self.kalman.long_run_phi()
        basis = density.basis
        # the predicted moments and the Kalman block are written in place
        m, lo, length, mass, xx, P, finite = predict_step(
            (x, step.flat[0], F, Q), self._block, phi, use_phi,
            (density.m, basis.lo, basis.length), density.mean, density.cov,
            self.ops.k_sigma, self.ops.min_halfwidth)
        density.m = m
        density.basis = basis.moved(lo, length, copy=False)  # fresh arrays from the kernel
        if math.isfinite(mass) and mass > 0:  # normalized by the kernel
            diag["prior_mass"] = mass
            return xx, P, finite
        gaussian_fallback(density, density.mean, density.cov, self.ops, diag)
        diag["prior_mass"] = self.ops.normalize(density.m, density.basis)
        return self.kalman.assemble(density.mean, density.cov)

