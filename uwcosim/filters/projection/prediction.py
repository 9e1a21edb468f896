"""PFM-PSI's prediction (seed 000 eqs. 15, 23, 41-43): the prior ``m- = exp(A dt) m``.

``A`` is the Galerkin matrix of the Fokker-Planck operator ``L* p = 1/2 sum d2(B p)/dx_r dx_s -
sum d(f p)/dx_r`` (eq. 15), built from the CasADi drift, its divergence and the diffusion
``B = g Q g'`` (and its derivatives) on the quadrature grid (Toeplitz in ``q - i``, one FFT per
field: eqs. 41-42, :func:`galerkin_matrix`); ``exp(A dt)`` by ``expm`` (``expm_multiply``
above :data:`DENSE_EXPM_MAX` basis functions; eq. 43). The drift is tapered to zero on the
outer 10 % of each side of the box (where the density is negligible): on the periodic box a
drift that does not vanish jumps at the seam and gives ``A`` spurious growing modes.

When neither ``f_p`` nor ``B`` depends on ``x_p`` (the TAN position block: its drift is the
rotated velocity), ``A`` is diagonal: a phase shift (applied by translating the box, which is
exact and cannot wrap around) and the decay ``exp(-w' D w / 2)`` (eq. 23 with a diagonal
``A``). ``D`` includes the velocity uncertainty
(:class:`~uwcosim.filters.grid.conditional.ConditionalKalman`). Either way the new box is the
projection symmetric interval of the predicted moments (eq. 33), the series re-projected onto
it and normalized (eq. 44); a signed series that lost its mass there is replaced by the
Gaussian of the predicted moments (:func:`gaussian_fallback`).

:class:`Prediction` is the numpy form; :class:`~uwcosim.filters.projection.prediction_kernels.
CompiledPrediction` runs the translation in one compiled call.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import scipy.fft as sfft
from scipy.linalg import expm
from scipy.sparse.linalg import expm_multiply

from uwcosim.filters.grid.conditional import ConditionalKalman
from uwcosim.filters.grid.partition import Partition
from uwcosim.filters.numerics import symmetrize
from uwcosim.filters.projection.series import (
    TWO_PI,
    SeriesDensity,
    SeriesOps,
    SpectralBasis,
    carried_moments,
    contract,
    diffusion_decay,
    gaussian_coefficients,
    mass,
    reproject,
    transfer_matrices,
)

DENSE_EXPM_MAX = 1200  # basis size up to which exp(A dt) is formed densely


# ---------------------------------------------------------------------------------------------
# Galerkin matrix of a second-order operator with variable coefficients (eqs. 15, 41-42)


@lru_cache(maxsize=16)
def _difference_index(K: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat multi-indices ``Q`` (N, n) and the index of ``q - i`` into a ``(4K+1)^n`` array."""
    grids = np.meshgrid(*([np.arange(-K, K + 1)] * n), indexing="ij")
    Q = np.stack([g.ravel() for g in grids], axis=1)
    D = Q[:, None, :] - Q[None, :, :] + 2 * K
    flat = np.ravel_multi_index(tuple(D[..., d] for d in range(n)), (4 * K + 1,) * n)
    return Q, flat


def field_coefficients(values: np.ndarray, basis: SpectralBasis) -> np.ndarray:
    """``c_k = (1 / prod L) integral c(x) exp(-j w_k (x - lo))`` for ``k = -2K..2K`` (FFT)."""
    K, M, n = basis.K, basis.M, basis.n
    C = sfft.fftn(values) / M**n
    idx = np.arange(-2 * K, 2 * K + 1) % M
    return C[np.ix_(*([idx] * n))]


def galerkin_matrix(basis: SpectralBasis, c0=None, c1=None, c2=None) -> np.ndarray:
    """Galerkin matrix ``A[q, i] = <L phi_i, phi_q>`` of the operator

        L u = sum_rs c2[r][s] d2u/dx_r dx_s + sum_s c1[s] du/dx_s + c0 u

    with coefficient fields sampled on the quadrature grid (``None`` = zero). For a field ``c``,
    ``<c d^a phi_i, phi_q> = c_{q-i} (j w_i)^a``: a Toeplitz structure in ``q - i`` built from
    one FFT per field (eqs. 41-42). Needs ``M >= 4K+1`` to resolve every difference ``q - i``.
    """
    K, n = basis.K, basis.n
    if basis.M < 4 * K + 1:
        raise ValueError(f"Galerkin matrix needs M >= 4K+1 = {4 * K + 1}, got {basis.M}")
    Q, flat = _difference_index(K, n)
    jw = [1j * TWO_PI * Q[:, d] / basis.length[d] for d in range(n)]  # j w of column i
    N = Q.shape[0]
    A = np.zeros((N, N), dtype=complex)
    if c0 is not None:
        A += field_coefficients(np.broadcast_to(c0, (basis.M,) * n), basis).ravel()[flat]
    if c1 is not None:
        for s in range(n):
            if c1[s] is None:
                continue
            ch = field_coefficients(np.broadcast_to(c1[s], (basis.M,) * n), basis).ravel()
            A += ch[flat] * jw[s][None, :]
    if c2 is not None:
        for r in range(n):
            for s in range(n):
                if c2[r][s] is None:
                    continue
                ch = field_coefficients(np.broadcast_to(c2[r][s], (basis.M,) * n), basis).ravel()
                A += ch[flat] * (jw[r] * jw[s])[None, :]
    return A


# ---------------------------------------------------------------------------------------------
# the step


class Prediction:
    """PFM-PSI's prediction, numpy form (any number of gridded states): :meth:`translate` for
    a drift independent of the gridded states, else :meth:`galerkin` (the filter takes the one
    its model needs, once). Both predict the density (in place) and the Kalman block over
    ``dt`` with the control ``u`` held, from the filter's estimate ``x``, and return the prior's
    ``(x, P, finite)``."""

    #: the step runs compiled kernels
    compiled = False

    def __init__(self, part: Partition, kalman: ConditionalKalman, ops: SeriesOps) -> None:
        self.part = part
        self.kalman = kalman
        self.ops = ops

    def translate(self, density: SeriesDensity, x, u, dt: float, diag: dict):
        """``A`` diagonal: translation by the increment (moves the box) and diffusion decay."""
        inc = self.kalman.increment(x, u, dt)
        basis = density.basis
        new = basis.moved(*self.ops.box(density.mean + inc.d, density.cov + inc.D))
        mats = transfer_matrices(basis.K, basis.lo + inc.d, basis.length, new.lo, new.length)
        m = contract(density.m, list(mats))
        m *= diffusion_decay(new, inc.D)  # eq. 23: exp(A dt) = phase shift and decay
        # translation and Gaussian convolution: the moments are exact
        mean, cov = density.mean + inc.d, symmetrize(density.cov + inc.D)
        return self._finish(density, m, new, mean, cov, True, diag)

    def galerkin(self, density: SeriesDensity, x, u, dt: float, diag: dict):
        """A drift that depends on the gridded states: ``m- = exp(A dt) m`` (eqs. 23, 43) on a
        box that holds the old and the predicted intervals."""
        part, kal, ops = self.part, self.kalman, self.ops
        xk_before = kal.block.x.copy()
        inc = kal.increment(x, u, dt)
        basis = density.basis
        guess_mean = density.mean + inc.d
        Fpp = inc.F[np.ix_(part.p, part.p)]
        guess_cov = Fpp @ density.cov @ Fpp.T + inc.D
        lo1, len1 = ops.box(density.mean, density.cov)
        lo2, len2 = ops.box(guess_mean, guess_cov)
        lo = np.minimum(lo1, lo2)
        new = basis.moved(lo, np.maximum(lo1 + len1, lo2 + len2) - lo)
        m = reproject(density.m, basis, new)
        xk_mid = 0.5 * (xk_before + kal.block.x)
        c0, c1, c2 = part.fpe_coefficients(new.axes(), xk_mid, u, dt, inc.Dk / dt)
        A = galerkin_matrix(new, c0, c1, c2)  # eq. 15
        if A.shape[0] <= DENSE_EXPM_MAX:  # scaling and squaring: robust for stiff A
            mv = expm(A * dt) @ m.ravel()
        else:
            mv = expm_multiply(A * dt, m.ravel())
        m = mv.reshape(m.shape)  # eq. 43
        return self._finish(density, m, new, guess_mean, symmetrize(guess_cov), False, diag)

    def _finish(self, density: SeriesDensity, m, new: SpectralBasis, mean, cov, exact: bool,
                diag: dict):
        """The predicted series on its box, normalized (eq. 44), and its moments (``exact``:
        ``mean``, ``cov``; else the series'); the Gaussian of ``mean``, ``cov`` on its own box
        when the signed series lost its mass."""
        density.m, density.basis = m, new
        mass_ = mass(m, new)
        fallback = not (math.isfinite(mass_) and mass_ > 0)
        if fallback:
            gaussian_fallback(density, mean, cov, self.ops, diag)
        diag["prior_mass"] = self.ops.normalize(density.m, density.basis)
        if exact or fallback:
            density.mean, density.cov = mean, cov
        else:
            density.mean, density.cov = carried_moments(density.m, density.basis)
        return self.kalman.assemble(density.mean, density.cov)


def gaussian_fallback(density: SeriesDensity, mean, cov, ops: SeriesOps, diag: dict) -> None:
    """The signed series lost its mass on the new box: carry the Gaussian of the predicted
    moments on its own box instead (diagnostic ``gaussian_fallback``)."""
    density.basis = density.basis.moved(*ops.box(mean, cov))
    density.m = gaussian_coefficients(mean, cov, density.basis)
    diag["gaussian_fallback"] = 1.0
