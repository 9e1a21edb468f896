"""Reference computations of the grid-filter tests (not part of the filters)."""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from uwcosim.filters.point_mass.fft import unit_frequencies


def gaussian_convolve(values: np.ndarray, spacing, D: np.ndarray) -> np.ndarray:
    """Linear convolution of grid values with ``N(0, D)`` by FFT (zero-padded, same shape)."""
    n = values.ndim
    D = np.asarray(D, dtype=float)
    sig = np.sqrt(np.maximum(np.diag(D), 0.0))
    shape = tuple(
        sfft.next_fast_len(values.shape[d] + int(min(np.ceil(7.0 * sig[d] / spacing[d]) + 1,
                                                     values.shape[d])), real=True)
        for d in range(n)
    )
    X = sfft.rfftn(values, s=shape)
    oms = [o / spacing[d] for d, o in enumerate(unit_frequencies(shape))]
    quad = 0.0
    for r in range(n):
        quad = quad + (0.5 * D[r, r]) * oms[r] * oms[r]
        for s in range(r + 1, n):
            quad = quad + D[r, s] * oms[r] * oms[s]
    X *= np.exp(-quad)
    out = sfft.irfftn(X, s=shape)
    return out[tuple(slice(0, values.shape[d]) for d in range(n))]
