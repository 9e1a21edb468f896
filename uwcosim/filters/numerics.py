"""Covariance numerics shared by the filters.

Symmetrization, Cholesky factorizations and solves (never an explicit inverse), the Joseph-form
update, positive-definite repair by escalating jitter (counted, so diagnostics can report it),
square roots of semi-definite noise covariances, finiteness checks and the transition
linearization ``(F, Q)`` of a model.

The small factorizations call LAPACK (``dpotrf``/``dpotrs``) directly: for the 2x2 to 6x6
matrices of navigation filters the checking wrappers of numpy/scipy cost 5-15 us per call,
LAPACK itself about 1 us.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from uwcosim.core.errors import FilterDivergence

JITTER_START = 1e-12
JITTER_STEPS = 8  # 1e-12 ... 1e-5 relative to the mean diagonal

_potrf = lapack.dpotrf
_potrs = lapack.dpotrs


def symmetrize(P: np.ndarray) -> np.ndarray:
    """``(P + P') / 2``."""
    return 0.5 * (P + P.T)


def symmetrize_(P: np.ndarray) -> np.ndarray:
    """``(P + P') / 2`` in place (``P`` square, owned by the caller), the same bits as
    :func:`symmetrize` with one temporary fewer; returns ``P``."""
    P += P.T  # numpy buffers the overlapping operand: elementwise from the old P
    P *= 0.5
    return P


def cholesky(P: np.ndarray) -> np.ndarray | None:
    """Lower Cholesky factor of a finite symmetric ``P``, or ``None`` if not positive definite."""
    L, info = _potrf(P, lower=1)
    return L if info == 0 else None


def check_finite(what: str, *arrays: np.ndarray) -> None:
    """Raise :class:`FilterDivergence` if any array holds NaN or inf."""
    for a in arrays:
        # the sum is one cheap pass and non-finite whenever an element is NaN or inf
        if not math.isfinite(float(a.sum())) and not np.isfinite(a).all():
            raise FilterDivergence(f"{what} contains NaN or inf")


def repair_pd(
    P: np.ndarray, counter: dict[str, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(P, L)`` with ``L`` the lower Cholesky factor of a PD version of ``P``.

    Adds escalating jitter ``eps * mean(diag(P)) * I`` until the factorization succeeds and
    counts the repairs in ``counter['pd_repairs']``. Raises :class:`FilterDivergence` for NaN
    or when ``P`` stays indefinite.
    """
    P = symmetrize(np.asarray(P, dtype=float))
    check_finite("covariance", P)
    L = cholesky(P)
    if L is not None:
        return P, L
    scale = max(float(np.mean(np.abs(np.diag(P)))), 1e-300)
    eye = np.eye(P.shape[0])
    eps = JITTER_START
    for _ in range(JITTER_STEPS):
        Pj = P + eps * scale * eye
        L = cholesky(Pj)
        if L is None:
            eps *= 10.0
            continue
        if counter is not None:
            counter["pd_repairs"] = counter.get("pd_repairs", 0.0) + 1.0
        return Pj, L
    raise FilterDivergence("covariance not positive definite beyond repair")


def factor(P: np.ndarray, counter: dict[str, float] | None = None):
    """``(P, L)`` for a symmetric ``P`` already checked finite: plain Cholesky, and
    :func:`repair_pd` (counted) only when that fails."""
    L = cholesky(P)
    if L is not None:
        return P, L
    return repair_pd(P, counter)


def cho_solve(cho, B: np.ndarray) -> np.ndarray:
    """``A^-1 B`` from ``cho = (L, True)``, the lower Cholesky factor of ``A``."""
    vec = B.ndim == 1
    X, info = _potrs(cho[0], B[:, None] if vec else B, lower=1)
    if info != 0:  # pragma: no cover - only for malformed input
        raise FilterDivergence(f"Cholesky solve failed (info={info})")
    return X[:, 0] if vec else X


def kalman_gain(PHt: np.ndarray, S: np.ndarray, counter=None) -> tuple[np.ndarray, tuple]:
    """``K = P H' S^-1`` by a Cholesky solve; returns ``(K, cho)`` for reuse (NIS).

    ``S`` is used as given when its Cholesky factorization succeeds (only its lower triangle is
    read), else repaired (counted); NaN in ``S`` propagates to ``K`` (callers check the state).
    """
    S, L = factor(S, counter)
    cho = (L, True)
    K = cho_solve(cho, PHt.T).T  # K' = S^-1 (P H')'
    return K, cho


def gain_and_nis(PHt: np.ndarray, S: np.ndarray, innov: np.ndarray,
                 counter=None) -> tuple[np.ndarray, float]:
    """``(K, nis)``: ``K = P H' S^-1`` and ``y' S^-1 y`` from one factorization of ``S`` and
    one LAPACK solve with the right-hand sides ``[(P H')', y]`` (as :func:`kalman_gain` and
    :func:`nis`, with fewer calls)."""
    S, L = factor(S, counter)
    m, n = S.shape[0], PHt.shape[0]
    B = np.empty((m, n + 1), order="F")
    B[:, :n] = PHt.T
    B[:, n] = innov
    X, info = _potrs(L, B, lower=1)
    if info != 0:  # pragma: no cover - only for malformed input
        raise FilterDivergence(f"Cholesky solve failed (info={info})")
    return X[:, :n].T, float(np.dot(innov, X[:, n]))


def nis(innov: np.ndarray, cho) -> float:
    """Normalized innovation squared ``y' S^-1 y``."""
    return float(innov @ cho_solve(cho, innov))


def joseph_update(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray,
                  eye: np.ndarray | None = None) -> np.ndarray:
    """``P = (I - K H) P (I - K H)' + K R K'`` (Joseph form, symmetrized); ``eye``: the
    identity of ``P``'s size, if the caller keeps one."""
    IKH = (np.eye(P.shape[0]) if eye is None else eye) - np.dot(K, H)
    A = np.dot(np.dot(IKH, P), IKH.T)
    A += np.dot(np.dot(K, R), K.T)
    return symmetrize_(A)


def psd_factor(Q: np.ndarray) -> np.ndarray:
    """A factor ``L`` with ``L L' = Q`` for a symmetric positive semi-definite ``Q``.

    Cholesky when ``Q`` is definite; otherwise the eigen-decomposition with the (round-off)
    negative eigenvalues clipped to zero, so singular noise covariances (noise on some states
    only) are sampled exactly instead of being jittered.
    """
    Q = symmetrize(np.asarray(Q, dtype=float))
    check_finite("process noise covariance", Q)
    L = cholesky(Q)
    if L is not None:
        return L
    w, V = np.linalg.eigh(Q)
    if w.min() < -1e-9 * max(w.max(), 1e-300):
        raise FilterDivergence("process noise covariance is not positive semi-definite")
    return V * np.sqrt(np.clip(w, 0.0, None))


def linearize(model, x: np.ndarray, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(F, Q)`` of the transition at ``x``: one call where the model offers it.

    Uses ``model.FQ`` if present, else ``model.FG`` with ``Q = G diag(q_psd/dt) G'`` (the
    CasADi models without control noise), else ``model.F`` and ``model.Q``.
    """
    fq = getattr(model, "FQ", None)
    if fq is not None:
        return fq(x, u, dt)
    if hasattr(model, "FG") and hasattr(model, "q_psd") \
            and getattr(model, "control_psd", None) is None:
        F, G = model.FG(x, u, dt)
        return F, (G * (model.q_psd / dt)) @ G.T  # Q = G diag(psd/dt) G'
    return model.F(x, u, dt), model.Q(x, u, dt)
