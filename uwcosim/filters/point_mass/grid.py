"""The point-mass filter's density: values on a regular tensor grid of the gridded states.

The grid spans ``mean -+ span sigma`` with ``n_points`` per dimension (Bergman 1999) and is
chosen anew at every prediction from the predicted moments (:meth:`GridDensity.grid`): the
Lagrangian grid of Matousek, Dunik and Straka, re-centred and re-scaled to the support.
:class:`GridDensity` holds the values, the axes with their spacing and cell volume, and the
gridded block's moments that the filter reports; :func:`scale_values` is the compiled
normalization of the compiled steps.
"""

from __future__ import annotations

import math

import numpy as np

from uwcosim.core.errors import FilterDivergence
from uwcosim.core.jit import jit


class GridDensity:
    """Density ``values`` on a tensor grid (``axes``, one regular axis per gridded state, with
    their ``spacing`` and ``cell`` volume: set together by :meth:`set_axes`), with the moments
    ``mean``, ``cov`` of the gridded block; ``span`` and ``n_points`` choose the grids
    (:meth:`grid`). It starts as the Gaussian ``N(mean, cov)`` on its grid; ``kind`` (the
    filter's name) names its errors."""

    def __init__(self, kind: str, span: float, n_points: list[int], mean: np.ndarray,
                 cov: np.ndarray) -> None:
        self.kind = kind
        self.span = span
        #: ``linspace(-1, 1, n)`` per axis: the grids' shape
        self.unit = [np.linspace(-1.0, 1.0, m) for m in n_points]
        self.set_axes(self.grid(mean, cov))
        n = len(n_points)
        mesh = np.stack(np.meshgrid(*self.axes, indexing="ij"), axis=-1) - mean
        y = np.linalg.solve(np.linalg.cholesky(cov), mesh.reshape(-1, n).T)
        self.values = np.exp(-0.5 * np.sum(y * y, axis=0)).reshape(mesh.shape[:-1])
        self.normalize()
        self.mean, self.cov = mean, cov

    def grid(self, mean, cov) -> list[np.ndarray]:
        """The axes of ``mean -+ span sigma`` (``sigma`` from ``cov``; floored)."""
        sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
        half = np.maximum(self.span * sig, 1e-9 * np.maximum(1.0, np.abs(mean)))
        out = []
        for d in range(len(mean)):
            a = self.unit[d] * half[d]  # linspace(mean - half, mean + half, n)
            a += mean[d]
            out.append(a)
        return out

    def set_axes(self, axes: list[np.ndarray]) -> None:
        """Move the density to the grid ``axes`` (its spacing and cell volume with it)."""
        self.axes = axes
        spacing = [a.item(1) - a.item(0) for a in axes]
        self.spacing = np.array(spacing)
        self.spacing.flags.writeable = False
        self.cell = math.prod(spacing)

    def normalize(self, clip: bool = True) -> None:
        """Divide the values by their mass (clipped at 0 first when ``clip``);
        FilterDivergence when the mass is lost."""
        if clip:
            self.values = np.maximum(self.values, 0.0, out=self.values)
        mass = float(self.values.sum() * self.cell)
        if not np.isfinite(mass) or mass <= 0:
            raise FilterDivergence(f"{self.kind}: grid density lost its mass ({mass})")
        self.values /= mass


@jit
def scale_values(a, s):
    """``a *= s`` (a 2-D array; the normalizations multiply by the reciprocal of the mass:
    a division per grid point costs about 4x a multiplication, and the results differ by at
    most 1 ulp)."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            a[i, j] *= s
