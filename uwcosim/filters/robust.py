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
