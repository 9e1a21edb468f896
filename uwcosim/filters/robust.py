"""A robust (Student-t) measurement likelihood for the particle, point-mass and projection
filters: :func:`student_t_loglik` and its setting.

With ``student_t_nu = nu`` each measurement component ``i`` (a diagonal ``R``) is taken as
Student-t with ``nu`` degrees of freedom and scale ``sqrt(R_ii)`` instead of Gaussian::

    log p(z_i | x) = -(nu + 1)/2 log(1 + e_i^2 / (nu R_ii)) + const,    e_i = z_i - h_i(x)

which tends to the Gaussian ``-e_i^2 / (2 R_ii)`` as ``nu -> inf`` (the constant does not
depend on ``x`` and cancels in the normalization). Its tails are polynomial: a 10-sigma
outlier of the sounder costs a particle ``(nu + 1)/2 log(1 + 100/nu)`` (7.2 for ``nu = 4``)
instead of 50, so it cannot wipe out the particles near the truth. Off by default: no
filter's results change.

The compiled steps of the grid filters (point mass, PFM-PSI) compute the Gaussian exponent
``W = -e^2 / (2 r)`` of their grid in their kernels, as without ``student_t_nu``, and turn it
into the Student-t one with :func:`student_t_exponent` (numpy's SIMD ``log1p`` over the whole
grid, several times faster than a compiled scalar loop, as for the ``exp`` that follows).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field, StrictFloat

NU = ("Student-t measurement likelihood with this many degrees of freedom (robust to "
      "outliers; e.g. 4; default: Gaussian)")


#: the type of the ``student_t_nu`` setting
StudentTNu = StrictFloat | None


def student_t_field() -> Any:
    """The ``student_t_nu`` setting of a filter that weights by a likelihood (default:
    Gaussian)."""
    return Field(None, gt=0, description=NU)


def student_t_loglik(e2: np.ndarray, r: np.ndarray | float, nu: float) -> np.ndarray:
    """``-(nu+1)/2 log(1 + e^2 / (nu r))`` elementwise (``e2`` the squared residuals, ``r``
    the variances, broadcast)."""
    return -0.5 * (nu + 1.0) * np.log1p(e2 / (nu * np.asarray(r, dtype=float)))


def student_t_exponent(W: np.ndarray, nu: float) -> float:
    """Gaussian exponents ``W = -e^2 / (2 r)`` made Student-t, in place and shifted by their
    maximum: ``W = -(nu+1)/2 log1p(-2 W / nu) - max`` (:func:`student_t_loglik` of the same
    squared standardized residuals ``e^2 / r = -2 W``); returns the maximum."""
    np.multiply(W, -2.0 / nu, out=W)  # e^2 / (nu r)
    np.log1p(W, out=W)
    W *= -0.5 * (nu + 1.0)  # -(nu + 1)/2 log(1 + e^2 / (nu r))
    top = float(W.max())
    W -= top
    return top
