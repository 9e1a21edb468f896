"""The series of PFM-PSI (seed 000, section 3.3): basis, box and quadrature (eqs. 33-41).

A density on the box ``[lo, lo + L]`` (one interval per dimension) is the truncated series

    p(x) = sum_q m_q phi_q(x),   phi_q(x) = prod_d exp(j 2 pi q_d (x_d - lo_d) / L_d) / sqrt(L_d)

over the *symmetric* frequency set ``q_d = -K..K`` (eq. 35 with ``q = -K..K`` instead of
``0..N-1``: a real density needs ``m_{-q} = conj(m_q)``, and a drift that depends on ``x`` couples
``q`` to ``q - k`` for both signs of ``k``). Coefficients are stored as a complex array of shape
``(2K+1,)*n`` indexed by ``q + K`` (C order), with the Hermitian symmetry kept up to round-off.

- the box, the *projection symmetric interval* ``E -+ k_sigma sigma`` (eq. 33, garbled in the
  extraction as ``-E - 10C``; :func:`symmetric_interval`), and its quadrature grid
  ``x_n = lo + n L / M`` (eq. 34 with ``M`` points per dimension; :class:`SpectralBasis`);
- inner products as quadratures on that periodic grid, i.e. FFTs (eqs. 37-38, 41, 45-46):
  ``<g, phi_q> = sqrt(L) / M * FFT(g)[q]`` (:func:`from_grid`), and the series on the grid
  (:func:`to_grid`) or at any points (:func:`evaluate`);
- the mass ``sqrt(prod L) m_0`` (eq. 39) and the normalization of eqs. 40, 44, 48 with the
  Hermitian part (:func:`normalize`); the exact moments of the truncated series (eqs. 50-51
  as integrals, :func:`series_moments`; :func:`carried_moments` falls back to the clipped grid
  values) and the quadrature moments of grid values (:func:`grid_moments`);
- the re-centring of step (1): the exact re-projection of a series onto another box (the old
  series taken as zero outside its box; :func:`reproject`), a Gaussian's coefficients
  (:func:`gaussian_coefficients`, eqs. 18-20) and the Gaussian convolution
  ``exp(-w' D w / 2)`` (:func:`diffusion_decay`).

:class:`SeriesDensity` is the filter's state (the series on its basis and the moments it
reports); :class:`SeriesOps` holds the three operations every step calls (box, normalization,
re-projection) in their numpy form; their compiled form is
:class:`~uwcosim.filters.projection.series_kernels.CompiledSeriesOps`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import scipy.fft as sfft

from uwcosim.core.errors import FilterDivergence
from uwcosim.filters.grid.moments import axes_moments
from uwcosim.filters.numerics import symmetrize

TWO_PI = 2.0 * np.pi


def fft_size(n: int) -> int:
    """Smallest even 5-smooth integer >= n (a fast FFT length)."""
    m = max(int(np.ceil(n)), 2)
    while True:
        m = sfft.next_fast_len(m, real=True)
        if m % 2 == 0:
            return m
        m += 1


@dataclass
class SpectralBasis:
    """Tensor-product complex-exponential basis on a box, with its quadrature grid.

    ``lo`` and ``length`` have one entry per dimension; ``K`` is the highest harmonic (``2K+1``
    basis functions per dimension) and ``M`` the number of quadrature points per dimension.
    """

    lo: np.ndarray
    length: np.ndarray
    K: int
    M: int
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.lo = np.asarray(self.lo, dtype=float).reshape(-1).copy()
        self.length = np.asarray(self.length, dtype=float).reshape(-1).copy()
        if self.M < 2 * self.K + 2:
            raise ValueError(f"quadrature grid M={self.M} too small for K={self.K}")

    @property
    def n(self) -> int:
        return self.lo.size

    @property
    def hi(self) -> np.ndarray:
        return self.lo + self.length

    @property
    def size(self) -> int:
        """Number of basis functions ``(2K+1)^n``."""
        return (2 * self.K + 1) ** self.n

    @property
    def shape(self) -> tuple[int, ...]:
        return (2 * self.K + 1,) * self.n

    @property
    def q(self) -> np.ndarray:
        return np.arange(-self.K, self.K + 1)

    def omega(self, d: int) -> np.ndarray:
        """Angular frequencies ``2 pi q / L_d`` of dimension ``d``."""
        return TWO_PI * self.q / self.length[d]

    def axes(self) -> list[np.ndarray]:
        """The quadrature grid ``x_n = lo + n L / M`` of every dimension (cached)."""
        ax = self._cache.get("axes")
        if ax is None:
            ar = _arange(self.M)
            ax = self._cache["axes"] = [
                self.lo[d] + self.length[d] * ar / self.M for d in range(self.n)
            ]
        return ax

    def cell(self) -> float:
        """Quadrature weight (cell volume) ``prod L_d / M`` (cached)."""
        c = self._cache.get("cell")
        if c is None:
            c = self._cache["cell"] = math.prod((self.length / self.M).tolist())
        return c

    def sqrt_volume(self) -> float:
        """``sqrt(prod L_d)`` (cached): the mass of the series is ``sqrt_volume * m_0``."""
        v = self._cache.get("sqrt_volume")
        if v is None:
            v = self._cache["sqrt_volume"] = math.sqrt(math.prod(self.length.tolist()))
        return v

    def moved(self, lo, length, copy: bool = True) -> SpectralBasis:
        """The same basis on another box (``copy=False``: ``lo`` and ``length`` are fresh 1-D
        float arrays the caller hands over)."""
        new = object.__new__(SpectralBasis)  # K and M are valid: skip __post_init__'s checks
        if copy:
            new.lo = np.array(lo, dtype=float).reshape(-1)
            new.length = np.array(length, dtype=float).reshape(-1)
        else:
            new.lo, new.length = lo, length
        new.K, new.M, new._cache = self.K, self.M, {}
        return new


@lru_cache(maxsize=16)
def _arange(M: int) -> np.ndarray:
    a = np.arange(M)
    a.setflags(write=False)
    return a


# ---------------------------------------------------------------------------------------------
# grid <-> coefficients


@lru_cache(maxsize=64)
def _half_index(K: int, M: int, n: int) -> tuple:
    """Index of the coefficients ``q_d = -K..K`` (last axis ``0..K``) in an rfftn array."""
    idx = np.arange(-K, K + 1) % M
    return np.ix_(*([idx] * (n - 1) + [np.arange(K + 1)]))


@lru_cache(maxsize=16)
def _dft_matrices(K: int, M: int) -> tuple[np.ndarray, ...]:
    """``E[n, q] = exp(j 2 pi n q / M)`` on the quadrature grid (independent of the box), its
    real and imaginary parts, their transposes and ``conj(E)``."""
    E = np.exp(2j * np.pi * np.outer(np.arange(M), np.arange(-K, K + 1)) / M)
    Ec, Es = E.real.copy(), E.imag.copy()
    for a in (E, Ec, Es):
        a.setflags(write=False)
    return Ec, Es, E, Ec.T.copy(), Es.T.copy(), E.conj()


def to_grid(m: np.ndarray, basis: SpectralBasis) -> np.ndarray:
    """Values of the (real) series on the quadrature grid, shape ``(M,)*n`` (indexing 'ij')."""
    K, M, n = basis.K, basis.M, basis.n
    if n == 2:  # two small matrix products beat the zero-padded FFT: Re(E m E')
        Ec, Es, E = _dft_matrices(K, M)[:3]
        A = m @ E.T
        out = Ec @ A.real
        out -= Es @ A.imag
        out *= 1.0 / math.sqrt(basis.length[0] * basis.length[1])
        return out
    half = np.zeros((M,) * (n - 1) + (M // 2 + 1,), dtype=complex)
    scale = M**n / np.sqrt(np.prod(basis.length))
    half[_half_index(K, M, n)] = m[..., K:]
    return sfft.irfftn(half, s=(M,) * n) * scale


def from_grid(values: np.ndarray, basis: SpectralBasis) -> np.ndarray:
    """Coefficients ``<g, phi_q>`` of a real grid function by FFT quadrature (eq. 45)."""
    K, M, n = basis.K, basis.M, basis.n
    scale = np.sqrt(np.prod(basis.length)) / M**n
    m = np.empty(basis.shape, dtype=complex)
    if n == 2:  # E^H g conj(E): two small matrix products (see to_grid)
        _, _, _, EcT, EsT, Econj = _dft_matrices(K, M)
        A = EcT @ values - 1j * (EsT @ values)
        out = A @ Econj
        out *= scale
        return out
    X = sfft.rfftn(values)
    m[..., K:] = X[_half_index(K, M, n)]
    # Hermitian completion: m_{-q} = conj(m_q)
    m[..., :K] = np.conj(np.flip(m[..., K + 1:], axis=tuple(range(n))))
    return m * scale


def axis_matrix(x: np.ndarray, lo: float, length: float, K: int) -> np.ndarray:
    """``E[n, q] = phi_q(x_n)`` in one dimension, zero outside ``[lo, lo + length]``."""
    s = np.asarray(x, dtype=float) - lo
    q = np.arange(-K, K + 1)
    E = np.exp(1j * TWO_PI * np.outer(s / length, q)) / np.sqrt(length)
    E[(s < 0) | (s > length)] = 0.0
    return E


def contract(m: np.ndarray, mats: list[np.ndarray]) -> np.ndarray:
    """Apply one matrix per axis: ``out[..a_d..] = sum_q prod_d mats[d][a_d, q_d] m[q]``."""
    if len(mats) == 1:
        return mats[0] @ m
    if len(mats) == 2:
        return mats[0] @ m @ mats[1].T
    out = m
    for d, T in enumerate(mats):
        out = np.moveaxis(np.tensordot(T, out, axes=(1, d)), 0, d)
    return out


def evaluate(m: np.ndarray, basis: SpectralBasis, axes: list[np.ndarray]) -> np.ndarray:
    """The series on the tensor grid ``axes`` (zero outside the box), real part."""
    mats = [axis_matrix(a, basis.lo[d], basis.length[d], basis.K) for d, a in enumerate(axes)]
    return contract(m, mats).real


def transfer_matrix(K: int, lo: float, length: float, lo2: float, length2: float) -> np.ndarray:
    """Exact re-projection in one dimension from ``[lo, lo+L]`` onto ``[lo2, lo2+L2]``.

    ``T[q', q] = integral over the overlap of phi_q conj(phi'_q')``: the L2 projection of the old
    series (taken as zero outside its interval) onto the new basis.
    """
    a = max(lo, lo2)
    w = min(lo + length, lo2 + length2) - a
    n = 2 * K + 1
    if w <= 0.0:
        return np.zeros((n, n), dtype=complex)
    q = np.arange(-K, K + 1)
    om = TWO_PI * q / length
    om2 = TWO_PI * q / length2
    # phase om_q (a - lo) - om2_q' (a - lo2) + delta w / 2 = om_q c1 - om2_q' c2 (separable)
    left = np.exp(-1j * om2 * (a - lo2 + 0.5 * w))
    right = np.exp(1j * om * (a - lo + 0.5 * w))
    # sin(a) / a with a = (om_q - om2_q') w / 2 (np.sinc(t) = sin(pi t) / (pi t))
    sinc = np.sinc(np.subtract.outer(om2, om) * (-0.5 * w / np.pi))
    # int over the overlap of exp(j delta s) = w sinc(delta w / 2) exp(j delta w / 2)
    sinc *= w / np.sqrt(length * length2)
    return np.multiply.outer(left, right) * sinc


def transfer_matrices(K: int, lo, length, lo2, length2) -> np.ndarray:
    """:func:`transfer_matrix` of every dimension at once, shape ``(n, 2K+1, 2K+1)``."""
    lo, length = np.asarray(lo, float), np.asarray(length, float)
    lo2, length2 = np.asarray(lo2, float), np.asarray(length2, float)
    a = np.maximum(lo, lo2)
    w = np.minimum(lo + length, lo2 + length2) - a
    q = _frequencies(K)
    om = TWO_PI * q / length[:, None]
    om2 = TWO_PI * q / length2[:, None]
    left = np.exp((-1j * (a - lo2 + 0.5 * w))[:, None] * om2)
    right = np.exp((1j * (a - lo + 0.5 * w))[:, None] * om)
    sinc = np.sinc((om2[:, :, None] - om[:, None, :]) * (-0.5 * w / np.pi)[:, None, None])
    sinc *= (np.maximum(w, 0.0) / np.sqrt(length * length2))[:, None, None]
    return left[:, :, None] * right[:, None, :] * sinc


@lru_cache(maxsize=16)
def _frequencies(K: int) -> np.ndarray:
    return np.arange(-K, K + 1, dtype=float)


def reproject(m: np.ndarray, basis: SpectralBasis, new: SpectralBasis) -> np.ndarray:
    """Coefficients on ``new`` of the series ``m`` on ``basis``."""
    mats = transfer_matrices(basis.K, basis.lo, basis.length, new.lo, new.length)
    return contract(m, list(mats))


# ---------------------------------------------------------------------------------------------
# Gaussian, mass and moments


def gaussian_coefficients(mean, cov, basis: SpectralBasis) -> np.ndarray:
    """Coefficients of ``N(mean, cov)`` (its characteristic function; tails outside ignored)."""
    mean = np.asarray(mean, float).reshape(-1)
    cov = np.atleast_2d(np.asarray(cov, float))
    oms = np.meshgrid(*[basis.omega(d) for d in range(basis.n)], indexing="ij")
    phase = sum(oms[d] * (mean[d] - basis.lo[d]) for d in range(basis.n))
    quad = sum(oms[r] * cov[r, s] * oms[s] for r in range(basis.n) for s in range(basis.n))
    return np.exp(-1j * phase - 0.5 * quad) / np.sqrt(np.prod(basis.length))


def mass(m: np.ndarray, basis: SpectralBasis) -> float:
    """``integral of p = sqrt(prod L) m_0`` (eqs. 39-40)."""
    return basis.sqrt_volume() * float(m[(basis.K,) * basis.n].real)


def _moment_vectors(basis: SpectralBasis, d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``int phi_q``, ``int y phi_q``, ``int y^2 phi_q`` over the interval (``y = x - centre``)."""
    L = basis.length[d]
    q = basis.q
    om = TWO_PI * q / L
    rl = np.sqrt(L)
    v0 = np.where(q == 0, rl, 0.0).astype(complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        v1 = np.where(q == 0, 0.0, -1j * rl / om)
        v2 = np.where(q == 0, L**3 / 12.0 / rl, 2.0 * rl / om**2).astype(complex)
    return v0, v1, v2


def series_moments(m: np.ndarray, basis: SpectralBasis) -> tuple[np.ndarray, np.ndarray,
                                                                 float]:
    """Mean, covariance and mass of the series by exact integration (eqs. 50-51)."""
    n = basis.n
    vecs = [_moment_vectors(basis, d) for d in range(n)]

    def integral(orders: list[int]) -> float:
        out = m
        for d in reversed(range(n)):
            out = out @ vecs[d][orders[d]]
        return float(np.real(out))

    mass_ = integral([0] * n)
    centre = basis.lo + 0.5 * basis.length
    mu = np.zeros(n)
    for d in range(n):
        o = [0] * n
        o[d] = 1
        mu[d] = integral(o) / mass_
    S = np.zeros((n, n))
    for r in range(n):
        for s in range(r, n):
            o = [0] * n
            if r == s:
                o[r] = 2
            else:
                o[r] = o[s] = 1
            S[r, s] = S[s, r] = integral(o) / mass_
    cov = S - np.outer(mu, mu)
    return centre + mu, cov, mass_


def grid_moments(values: np.ndarray, basis: SpectralBasis) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of nonnegative grid values (trapezoid quadrature, eqs. 50-51)."""
    return axes_moments(basis.axes(), values)



def diffusion_decay(basis: SpectralBasis, D: np.ndarray) -> np.ndarray:
    """``exp(-w' D w / 2)`` on the coefficients: a Gaussian convolution of covariance ``D``."""
    n = basis.n
    om = [basis.omega(d) for d in range(n)]
    if n == 2:
        a, b = om[0][:, None], om[1][None, :]
        quad = (0.5 * D[0, 0]) * (a * a) + (0.5 * D[1, 1]) * (b * b) + (D[0, 1] * a) * b
        return np.exp(-quad)
    quad = np.zeros(basis.shape)
    for r in range(n):
        for s in range(n):
            shape_r = [1] * n
            shape_r[r] = om[r].size
            shape_s = [1] * n
            shape_s[s] = om[s].size
            quad = quad + D[r, s] * om[r].reshape(shape_r) * om[s].reshape(shape_s)
    return np.exp(-0.5 * quad)


def symmetric_interval(mean, cov, k_sigma: float, min_halfwidth: float):
    """The box ``(lo, length)`` of ``mean -+ k_sigma sigma`` per dimension (eq. 33), with the
    half-width floored at ``min_halfwidth`` (and at ``1e-9 max(1, |mean|)``)."""
    sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
    floor = np.maximum(min_halfwidth, 1e-9 * np.maximum(1.0, np.abs(mean)))
    half = np.maximum(k_sigma * sig, floor)
    return mean - half, 2.0 * half


def normalize(m: np.ndarray, basis: SpectralBasis) -> float:
    """``m = (m + conj(m_-q)) / 2`` in place, then ``m /= mass`` when the mass is finite and
    positive (eqs. 40, 44, 48); returns the mass."""
    m += np.conj(m[(slice(None, None, -1),) * m.ndim])  # Hermitian part (times 2)
    m *= 0.5
    mass_ = mass(m, basis)
    if math.isfinite(mass_) and mass_ > 0:
        m /= mass_
    return mass_


def carried_moments(m: np.ndarray, basis: SpectralBasis) -> tuple[np.ndarray, np.ndarray]:
    """The moments of the series (:func:`series_moments`), or of its clipped grid values when
    those are not valid (a nonpositive or non-finite variance); the covariance symmetrized."""
    mean, cov, _ = series_moments(m, basis)
    if np.any(np.diag(cov) <= 0) or not np.all(np.isfinite(cov)):
        values = to_grid(m, basis)
        mean, cov = grid_moments(np.maximum(values, 0.0), basis)
    return mean, symmetrize(cov)


@dataclass
class SeriesDensity:
    """PFM-PSI's density of the gridded states: the series ``m`` on ``basis`` (its box and
    quadrature grid) and the gridded block's moments ``mean``, ``cov`` the filter reports."""

    m: np.ndarray
    basis: SpectralBasis
    mean: np.ndarray
    cov: np.ndarray


class SeriesOps:
    """The box (eq. 33), the normalization (eqs. 40, 44, 48) and the re-projection of a step,
    numpy form (any dimension). ``kind``: the filter's name, for its errors."""

    #: the operations run compiled kernels
    compiled = False

    def __init__(self, kind: str, k_sigma: float, min_halfwidth: float) -> None:
        self.kind = kind
        self.k_sigma = k_sigma
        self.min_halfwidth = min_halfwidth

    def box(self, mean, cov) -> tuple[np.ndarray, np.ndarray]:
        """:func:`symmetric_interval` with the filter's ``k_sigma`` and ``min_halfwidth``."""
        return symmetric_interval(mean, cov, self.k_sigma, self.min_halfwidth)

    def normalize(self, m: np.ndarray, basis: SpectralBasis) -> float:
        """:func:`normalize` in place; the mass, FilterDivergence when it is lost."""
        return self.checked(self._normalize(m, basis))

    def checked(self, mass: float) -> float:
        """``mass``, or FilterDivergence when it is not finite and positive."""
        if not (math.isfinite(mass) and mass > 0):
            raise FilterDivergence(f"{self.kind}: density lost its mass ({mass})")
        return mass

    def _normalize(self, m: np.ndarray, basis: SpectralBasis) -> float:
        return normalize(m, basis)

    def reproject(self, m: np.ndarray, basis: SpectralBasis, new: SpectralBasis) -> np.ndarray:
        """:func:`reproject`."""
        return reproject(m, basis, new)
