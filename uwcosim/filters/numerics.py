"""Covariance numerics shared by the Gaussian filters.

Symmetrization, Cholesky solves (never an explicit inverse), the Joseph-form update and
positive-definite repair by escalating jitter (counted, so diagnostics can report it).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from uwcosim.errors import FilterDivergence

JITTER_START = 1e-12
JITTER_STEPS = 8  # 1e-12 ... 1e-5 relative to the mean diagonal


def symmetrize(P: np.ndarray) -> np.ndarray:
    """``(P + P') / 2``."""
    return 0.5 * (P + P.T)


def repair_pd(P: np.ndarray, counter: dict[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(P, L)`` with ``L`` the lower Cholesky factor of a PD version of ``P``.

    Adds escalating jitter ``eps * mean(diag(P)) * I`` until the factorization succeeds and
    counts the repairs in ``counter['pd_repairs']``. Raises :class:`FilterDivergence` for NaN
    or when ``P`` stays indefinite.
    """
    P = symmetrize(np.asarray(P, dtype=float))
    if not np.all(np.isfinite(P)):
        raise FilterDivergence("covariance contains NaN or inf")
    try:
        return P, np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        pass
    scale = max(float(np.mean(np.abs(np.diag(P)))), 1e-300)
    eye = np.eye(P.shape[0])
    eps = JITTER_START
    for _ in range(JITTER_STEPS):
        Pj = P + eps * scale * eye
        try:
            L = np.linalg.cholesky(Pj)
        except np.linalg.LinAlgError:
            eps *= 10.0
            continue
        if counter is not None:
            counter["pd_repairs"] = counter.get("pd_repairs", 0.0) + 1.0
        return Pj, L
    raise FilterDivergence("covariance not positive definite beyond repair")


def kalman_gain(PHt: np.ndarray, S: np.ndarray, counter=None) -> tuple[np.ndarray, tuple]:
    """``K = P H' S^-1`` by a Cholesky solve; returns ``(K, cho)`` for reuse (NIS)."""
    S, L = repair_pd(S, counter)
    cho = (L, True)
    K = cho_solve(cho, PHt.T).T
    return K, cho


def nis(innov: np.ndarray, cho) -> float:
    """Normalized innovation squared ``y' S^-1 y``."""
    return float(innov @ cho_solve(cho, innov))


def joseph_update(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``P = (I - K H) P (I - K H)' + K R K'`` (Joseph form, symmetrized)."""
    IKH = np.eye(P.shape[0]) - K @ H
    return symmetrize(IKH @ P @ IKH.T + K @ R @ K.T)


def chol_solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A^-1 B`` for symmetric PD ``A`` by Cholesky."""
    return cho_solve(cho_factor(A, lower=True), B)
