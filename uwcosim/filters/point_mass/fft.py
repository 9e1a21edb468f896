"""FFT work of the point-mass filter's prediction: the frequency tables of a real FFT, the
cubic B-spline prefilter's symbol, and (two gridded states) the padded transforms through
scipy's pocketfft binding into arrays kept per shape.

:class:`FFTPlan` calls ``pypocketfft.r2c`` / ``c2r`` (the functions ``scipy.fft.rfft2`` and
``irfft2`` end in) with preallocated outputs: the same transforms and bits without the public
functions' argument normalization and output allocation (about 10 us per step); if the private
binding is missing it falls back to the public functions.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
import scipy.fft as sfft

try:  # scipy.fft's pocketfft binding: the transforms of rfft2/irfft2 without their dispatch
    from scipy.fft._pocketfft import pypocketfft as _pocketfft
except ImportError:  # pragma: no cover - another scipy layout: the public functions
    _pocketfft = None


@lru_cache(maxsize=32)
def unit_frequencies(shape: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """Angular frequencies of a real FFT of ``shape`` at unit spacing, broadcastable (cached)."""
    n = len(shape)
    out = []
    for d in range(n):
        f = sfft.rfftfreq(shape[d]) if d == n - 1 else sfft.fftfreq(shape[d])
        s = [1] * n
        s[d] = f.size
        out.append((2.0 * np.pi * f).reshape(s))
    return tuple(out)


@lru_cache(maxsize=32)
def inverse_bspline_symbol(shape: tuple[int, ...]) -> np.ndarray:
    """``1 / prod_d (4 + 2 cos w_d) / 6``: the cubic B-spline prefilter on a real FFT grid."""
    out = 1.0
    for o in unit_frequencies(shape):
        out = out * (6.0 / (4.0 + 2.0 * np.cos(o)))
    return out


@lru_cache(maxsize=32)
def inverse_bspline_factors(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The 2-D :func:`inverse_bspline_symbol` as its column and row factors."""
    o0, o1 = unit_frequencies(shape)
    return 6.0 / (4.0 + 2.0 * np.cos(o0)), 6.0 / (4.0 + 2.0 * np.cos(o1))


@lru_cache(maxsize=256)
def fast_len(n: int) -> int:
    """``sfft.next_fast_len(n, real=True)`` (cached: called twice per prediction)."""
    return sfft.next_fast_len(n, real=True)


class Prefilter(NamedTuple):
    """The cubic B-spline prefilter of a two-dimensional real-FFT spectrum as the compiled
    kernels take it: its column and row factors and the padded length of the last axis."""

    col: np.ndarray
    row: np.ndarray
    last: int


class FFTPlan:
    """Work arrays of the two-dimensional prediction for one padded shape (per filter): the
    zero-padded input, its spectrum, the inverse transform's output, the prefilter factors
    (also as :attr:`prefilter`, a :class:`Prefilter` as the plain tuple the kernels take)."""

    __slots__ = ("buf", "spec", "out", "col", "row", "last", "prefilter")

    def __init__(self, shape: tuple[int, int]) -> None:
        self.buf = np.zeros(shape)
        self.spec = np.empty((shape[0], shape[1] // 2 + 1), dtype=complex)
        self.out = np.empty(shape)
        self.col, self.row = inverse_bspline_factors(shape)
        self.last = shape[1]
        self.prefilter = (self.col, self.row, self.last)  # a Prefilter

    def forward(self) -> np.ndarray:
        """``spec = rfft2(buf)`` (same transform as :func:`scipy.fft.rfft2`, into ``spec``)."""
        if _pocketfft is None:
            self.spec[...] = sfft.rfft2(self.buf)
        else:
            _pocketfft.r2c(self.buf, (0, 1), True, 0, self.spec, 1)
        return self.spec

    def inverse(self) -> np.ndarray:
        """``out = irfft2(spec, s=shape)`` (as :func:`scipy.fft.irfft2`, into ``out``)."""
        if _pocketfft is None:
            self.out[...] = sfft.irfft2(self.spec, s=self.out.shape)
        else:
            _pocketfft.c2r(self.spec, (0, 1), self.last, False, 2, self.out, 1)
        return self.out
