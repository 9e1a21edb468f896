"""Compiled steps of the Kalman filters (EKF, KF, dead reckoning) on a model's compiled form.

A model that offers :class:`~uwcosim.models.protocol.CompiledForm` (the TAN model does) gives
its transition as a compiled function writing ``F``, ``b`` and ``Q`` of the step (``x' = F x +
b + w``) and its measurements as rows linear in the state plus at most one table-surface row
(the terrain depth, :mod:`uwcosim.core.bicubic`). A filter's step then costs two compiled calls
(the model's transition, the filter's equations) instead of some forty numpy calls, and a whole
step one (:func:`ekf_step`: prediction and update, the transition inlined when the model names
one of :mod:`uwcosim.core.kinematics`; :meth:`uwcosim.filters.base.Estimator.step`).

The filter's constant data and its per-step scratch travel in one named bundle, a
:class:`Workspace`: a one-element structured array whose fields (``ws[0].F``, ``ws[0].Q``,
``ws[0].H0`` ...) the kernels read by name. It is the one argument bundle Numba's dispatcher
types cheaply: a NamedTuple of arrays costs 0.3-0.5 us per field at every call, a structref 3 us
and uncached, a structured array about 0.1 us, provided its dtype is the very object the
dispatcher first met (an equal dtype object costs numpy's comparison of the fields, about 2 us
per call): a layout has one dtype object (:func:`workspace_dtype`). The steps skip the
dispatcher altogether: :meth:`Workspace.call` calls a kernel's compiled entry point for the
types of its arguments, 0.3 us per call against 0.6 us through the dispatcher
(``benchmarks/kalman_call.py``; ``benchmarks/bench_filters.py`` times the step).
The mean ``x`` and covariance ``P`` are the filter's own arrays, updated in place; a whole step
(:func:`ekf_step`) keeps them in the bundle too (``ws[0].x``, ``ws[0].P``: the filter's ``x``
and ``P`` are then views of them), two arguments fewer per call.

The equations are those of the numpy steps (:mod:`uwcosim.filters.kalman`), written as loops in
index order: Cholesky by columns, solves by substitution, products by rows. Where the numpy
steps call BLAS/LAPACK (``np.dot``, ``dpotrf``, ``dpotrs``) the sums are grouped differently,
so the two agree to round-off (about 1e-15 relative per step), not bit for bit; the filters'
``compiled`` setting is therefore off by default and the default logs are the numpy steps'
(``tests/test_kalman_compiled.py`` checks the agreement and the bits of the parts that are the
same arithmetic). PD repair, the counted jitter of :func:`uwcosim.filters.numerics.repair_pd`,
is repeated here; a step reports what went wrong as a status code that
:func:`raise_for_status` turns into the numpy steps' :class:`FilterDivergence`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from uwcosim.core import bicubic, jit, kinematics
from uwcosim.core.errors import FilterDivergence
from uwcosim.filters.numerics import JITTER_START, JITTER_STEPS
from uwcosim.filters.small_linalg import cholesky, mm_into, mv_into

OK = 0
NO_DATA = -1  # no usable measurement component: the update does nothing
NOT_FINITE = 1  # NaN or inf in the state or covariance after the step
COV_NOT_FINITE = 2  # a covariance to factorize holds NaN or inf
NOT_PD = 3  # a covariance stays indefinite after the jitter of repair_pd
IN_PREDICTION = 16  # added to a status of a whole step's prediction half


class Workspace(NamedTuple):
    """What a compiled filter keeps for its steps: the bundle ``ws`` and the model's parts."""

    ws: np.ndarray  #: the one-element structured array the kernels take
    F: np.ndarray  #: view of ``ws[0].F``: the model's transition writes ``F``, ``b``, ``Q``
    b: np.ndarray  #: view of ``ws[0].b``
    Q: np.ndarray  #: view of ``ws[0].Q``
    x: np.ndarray  #: view of ``ws[0].x``, the mean of a whole step
    P: np.ndarray  #: view of ``ws[0].P``, the covariance of a whole step
    table: np.ndarray  #: the surface row's polynomial table (a dummy without one)
    transition: Callable[..., None]  #: ``transition(u, dt, F, b, Q)``, the model's
    given: bool  #: the model's transition is not compiled in: call it before a whole step
    everything: np.ndarray  #: the mask of every measurement component (``mask=None``)
    nothing: np.ndarray  #: no measurement: ``z`` of NaN, for a step with ``z=None``
    entries: dict  #: the kernels' compiled entry points for these types, by kernel (:meth:`call`)

    def call(self, kernel, *args):
        """``kernel(ws, *args)`` through its compiled entry point for the types of this call,
        resolved at the first (:func:`uwcosim.core.jit.entry_point`): the dispatcher is skipped.
        The caller checks first that ``args`` keep those types (:func:`exact`; ``ws`` and
        ``table`` are this workspace's), or calls ``kernel`` itself."""
        entry = self.entries.get(kernel)
        if entry is None:
            entry = self.entries[kernel] = jit.entry_point(kernel, (self.ws, *args))
        return entry(self.ws, *args)


F8 = np.dtype(np.float64)
BOOL = np.dtype(np.bool_)


def exact(a, dtype: np.dtype, ndim: int) -> bool:
    """Whether ``a`` is of the one Numba type that :meth:`Workspace.call` resolves for an array
    argument: an ndarray of ``dtype`` (native order) and ``ndim`` dimensions, C-contiguous,
    writeable and aligned."""
    if type(a) is not np.ndarray or a.dtype is not dtype or a.ndim != ndim:
        return False
    flags = a.flags
    return flags.c_contiguous and flags.writeable and flags.aligned


def workspace_fields(n: int, nz: int, npar: int) -> list[tuple]:
    """The fields every compiled Kalman step reads (the dtype of :func:`workspace`)."""
    return [("x", "f8", n), ("P", "f8", (n, n)),
            ("F", "f8", (n, n)), ("b", "f8", n), ("Q", "f8", (n, n)),
            ("motion", "i8"), ("params", "f8", max(npar, 1)),  # core.kinematics' code
            ("H0", "f8", (nz, n)), ("R", "f8", (nz, nz)), ("use", "u1", nz),
            ("srow", "i8"), ("si", "i8"), ("sj", "i8"),  # the surface row and its states
            ("sx0", "f8"), ("sy0", "f8"), ("sidx", "f8"), ("sidy", "f8"),
            ("snx", "i8"), ("sny", "i8"),
            # the EKF's work arrays (a step with m available rows uses their first m rows)
            ("rows", "i8", nz), ("hx", "f8", nz), ("H", "f8", (nz, n)), ("y", "f8", nz),
            ("Rm", "f8", (nz, nz)), ("PHt", "f8", (n, nz)), ("S", "f8", (nz, nz)),
            ("L", "f8", (nz, nz)), ("B", "f8", (nz, n + 1)), ("K", "f8", (n, nz)),
            ("KR", "f8", (n, nz)), ("v", "f8", n), ("T", "f8", (n, n)), ("A", "f8", (n, n)),
            ("A2", "f8", (n, n)), ("IKH", "f8", (n, n))]


@functools.cache
def workspace_dtype(fields: tuple) -> np.dtype:
    """The one dtype object of a workspace layout: Numba's dispatcher keys its type of a
    structured array by the dtype object, and another object of an equal dtype costs numpy's
    comparison of every field at every call, about 2 us (``benchmarks/kalman_call.py``)."""
    return np.dtype(list(fields), align=True)


def workspace(model, use: np.ndarray, extra: list[tuple] | None = None) -> Workspace | None:
    """The :class:`Workspace` of ``model`` (None when it offers no compiled form) for a filter
    using the measurement components ``use``, with the ``extra`` fields of a filter (e.g. a
    sigma-point rule), to be filled by the caller."""
    form_of = getattr(model, "compiled_form", None)
    form = form_of() if form_of is not None else None
    if form is None:
        return None
    n, nz = model.nx, model.nz
    params = np.asarray(form.params, dtype=float)
    ws = np.zeros(1, dtype=workspace_dtype(tuple(workspace_fields(n, nz, params.size)
                                                 + (extra or []))))
    s = ws[0]
    s["motion"] = form.motion
    s["params"][: params.size] = params
    s["use"] = use
    s["H0"] = form.H0
    s["R"] = model.R
    s["srow"] = form.surface_row
    s["si"], s["sj"] = form.surface_states
    g = form.surface
    s["sx0"], s["sy0"], s["sidx"], s["sidy"], s["snx"], s["sny"] = g
    table = np.ascontiguousarray(form.table, dtype=float)
    return Workspace(ws, ws["F"][0], ws["b"][0], ws["Q"][0], ws["x"][0], ws["P"][0], table,
                     form.transition,
                     form.motion == kinematics.GIVEN, np.ones(nz, dtype=bool),
                     np.full(nz, np.nan), {})


def raise_for_status(status: int, what: str) -> None:
    """Raise the :class:`FilterDivergence` of the numpy steps for a step's ``status``
    (``what``: e.g. ``"ekf update"``; a whole step's prediction says ``prediction``)."""
    if status >= IN_PREDICTION:
        status -= IN_PREDICTION
        what = what.replace("update", "prediction")
    if status == NOT_FINITE:
        raise FilterDivergence(f"{what} contains NaN or inf")
    if status == COV_NOT_FINITE:
        raise FilterDivergence("covariance contains NaN or inf")
    if status == NOT_PD:
        raise FilterDivergence("covariance not positive definite beyond repair")


@jit.jit
def factor(P, L):
    """:func:`uwcosim.filters.numerics.factor`: ``L`` the Cholesky factor of ``P``, or of ``P``
    symmetrized plus escalating jitter ``eps mean|diag P| I`` (``P`` repaired in place);
    ``(repairs, status)``."""
    if cholesky(P, L):
        return 0.0, OK
    n = P.shape[0]
    total = 0.0
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (P[i, j] + P[j, i])  # P = (P + P') / 2
            P[i, j] = v
            P[j, i] = v
            total += v
    if not math.isfinite(total):
        return 0.0, COV_NOT_FINITE
    scale = 0.0
    for i in range(n):
        scale += abs(P[i, i])
    scale = max(scale / n, 1e-300)
    eps = JITTER_START
    Pj = np.empty_like(P)
    for _ in range(JITTER_STEPS):
        Pj[:, :] = P
        for i in range(n):
            Pj[i, i] = P[i, i] + eps * scale  # P + eps scale I
        if cholesky(Pj, L):
            P[:, :] = Pj
            return 1.0, OK
        eps *= 10.0
    return 0.0, NOT_PD


@jit.jit
def cho_solve(L, B):
    """``B = (L L')^-1 B`` in place (the columns of ``B``), by substitution."""
    m = L.shape[0]
    for c in range(B.shape[1]):
        for i in range(m):  # L w = b
            v = B[i, c]
            for k in range(i):
                v -= L[i, k] * B[k, c]
            B[i, c] = v / L[i, i]
        for i in range(m - 1, -1, -1):  # L' x = w
            v = B[i, c]
            for k in range(i + 1, m):
                v -= L[k, i] * B[k, c]
            B[i, c] = v / L[i, i]


@jit.jit
def gain_and_nis_into(PHt, S, y, L, B, K):
    """``(nis, repairs, status)``: ``K = P H' S^-1`` and ``y' S^-1 y`` from one factor ``L`` of
    ``S`` (``S`` repaired in place if needed; ``L``, ``B`` the work arrays of the solve)."""
    n, m = PHt.shape
    repairs, status = factor(S, L)
    if status != OK:
        return 0.0, repairs, status
    for i in range(m):
        for j in range(n):
            B[i, j] = PHt[j, i]
        B[i, n] = y[i]
    cho_solve(L, B)
    nis = 0.0
    for i in range(m):
        for j in range(n):
            K[j, i] = B[i, j]  # K = (S^-1 (P H')')'
        nis += y[i] * B[i, n]  # nis = y' S^-1 y
    return nis, repairs, OK


@jit.jit
def gain_and_nis(PHt, S, y):
    """``(K, nis, repairs, status)``: ``K = P H' S^-1`` and ``y' S^-1 y`` from one factor of
    ``S`` (repaired on a copy, as :func:`uwcosim.filters.numerics.gain_and_nis`)."""
    n, m = PHt.shape
    K = np.empty((n, m))
    nis, repairs, status = gain_and_nis_into(PHt, S.copy(), y, np.empty((m, m)),
                                             np.empty((m, n + 1)), K)
    return K, nis, repairs, status


@jit.jit
def symmetrize_into(A, P):
    """``P = (A + A') / 2``."""
    n = A.shape[0]
    for i in range(n):
        P[i, i] = A[i, i]
        for j in range(i + 1, n):
            v = 0.5 * (A[i, j] + A[j, i])
            P[i, j] = v
            P[j, i] = v


@jit.jit
def finite(x, P):
    """Whether ``x`` and ``P`` hold no NaN or inf."""
    t = 0.0
    for i in range(x.shape[0]):
        t += x[i]
        for j in range(P.shape[1]):
            t += P[i, j]
    return math.isfinite(t)


@jit.jit
def select_rows(use, z, mask, rows):
    """The available components ``rows[:m]``: finite, received (``mask``) and used by the
    filter (``use``, the workspace's); returns ``m``."""
    m = 0
    for r in range(z.shape[0]):
        if use[r] != 0 and mask[r] and math.isfinite(z[r]):
            rows[m] = r
            m += 1
    return m


@jit.jit
def measure(s, table, x, rows, m, hx, H):
    """``hx[k] = h_r(x)`` and ``H[k] = dh_r/dx`` for the rows ``r = rows[k]``, ``k < m``: the
    linear rows ``H0[r]``, the surface row from the table (looked up only if it is asked)."""
    n = x.shape[0]
    for k in range(m):
        r = rows[k]
        if r == s.srow:
            h, gx, gy = bicubic.value_gradient(table, s.sx0, s.sy0, s.sidx, s.sidy, s.snx,
                                               s.sny, x[s.si], x[s.sj])
            for j in range(n):
                H[k, j] = 0.0
            H[k, s.si] = gx
            H[k, s.sj] = gy
            hx[k] = h
        else:
            v = 0.0
            for j in range(n):
                H[k, j] = s.H0[r, j]
                v += s.H0[r, j] * x[j]
            hx[k] = v


@jit.jit
def measure_value(s, table, x, rows, m, hx):
    """``hx[k] = h_r(x)`` for the rows ``r = rows[k]``, ``k < m`` (no Jacobian)."""
    n = x.shape[0]
    for k in range(m):
        r = rows[k]
        if r == s.srow:
            hx[k] = bicubic.value(table, s.sx0, s.sy0, s.sidx, s.sidy, s.snx, s.sny,
                                  x[s.si], x[s.sj])
        else:
            v = 0.0
            for j in range(n):
                v += s.H0[r, j] * x[j]
            hx[k] = v


@jit.jit
def ekf_predict(ws, x, P):
    """EKF prediction with the step's ``F``, ``b``, ``Q`` (in ``ws``); ``x``, ``P`` in place.
    Returns the status."""
    s = ws[0]
    F, b, Q, v, T, A = s.F, s.b, s.Q, s.v, s.T, s.A
    mv_into(F, x, v)
    for i in range(x.shape[0]):
        x[i] = v[i] + b[i]  # x = f(x, u) = F x + b
    add_into(mm_into(mm_into(F, P, T), F.T, A), Q)  # P = F P F' + Q
    symmetrize_into(A, P)
    return OK if finite(x, P) else NOT_FINITE


@jit.jit
def add_into(A, B):
    """``A = A + B``; returns ``A``."""
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            A[i, j] = A[i, j] + B[i, j]
    return A


@jit.jit
def ekf_update(ws, table, x, P, z, mask):
    """EKF update (Joseph form) with the available components of ``z`` (finite, ``mask`` and
    used); ``x``, ``P`` in place, the workspace's work arrays for the rest (their first ``m``
    rows). Returns ``(status, nis, nis_dof, repairs)``."""
    s = ws[0]
    n = x.shape[0]
    m = select_rows(s.use, z, mask, s.rows)
    if m == 0:
        return NO_DATA, 0.0, 0.0, 0.0
    rows, hx, H, y, R = s.rows, s.hx[:m], s.H[:m], s.y[:m], s.Rm[:m, :m]
    measure(s, table, x, rows, m, hx, H)  # h(x) and H = dh/dx at the prior mean
    for k in range(m):
        y[k] = z[rows[k]] - hx[k]  # y = z - h(x)
    for a in range(m):
        for c in range(m):
            R[a, c] = s.R[rows[a], rows[c]]  # the available components' R
    PHt, S, K = s.PHt[:, :m], s.S[:m, :m], s.K[:, :m]
    mm_into(P, H.T, PHt)
    add_into(mm_into(H, PHt, S), R)  # S = H P H' + R
    nis, repairs, status = gain_and_nis_into(PHt, S, y, s.L[:m, :m], s.B[:m],
                                             K)  # K = P H' S^-1
    if status != OK:
        return status, 0.0, 0.0, repairs
    v, IKH, T, A, A2 = s.v, s.IKH, s.T, s.A, s.A2
    mv_into(K, y, v)
    for i in range(n):
        x[i] = x[i] + v[i]  # x = x + K y
    mm_into(K, H, IKH)
    for i in range(n):
        for j in range(n):
            IKH[i, j] = (1.0 if i == j else 0.0) - IKH[i, j]  # I - K H
    mm_into(mm_into(IKH, P, T), IKH.T, A)
    add_into(A, mm_into(mm_into(K, R, s.KR[:, :m]), K.T, A2))  # P = (I-KH) P (I-KH)' + K R K'
    symmetrize_into(A, P)
    return (OK if finite(x, P) else NOT_FINITE), nis, float(m), repairs


@jit.jit
def ekf_step(ws, table, u, dt, z, mask):
    """A whole EKF step on ``ws[0].x``, ``ws[0].P``: the model's transition (if compiled in),
    :func:`ekf_predict`, then :func:`ekf_update`. Returns ``(status, nis, nis_dof, repairs)``,
    a failed prediction's status plus :data:`IN_PREDICTION`."""
    s = ws[0]
    kinematics.write(s.motion, u, dt, s.params, s.F, s.b, s.Q)  # F, b, Q of the step
    status = ekf_predict(ws, s.x, s.P)  # x = F x + b, P = F P F' + Q
    if status != OK:
        return status + IN_PREDICTION, 0.0, 0.0, 0.0
    return ekf_update(ws, table, s.x, s.P, z, mask)  # x = x + K y, P = (I-KH) P (I-KH)' + K R K'


def compiled_workspace(est, model, use: np.ndarray,
                       extra: list[tuple] | None = None) -> Workspace | None:
    """The workspace of a filter whose ``compiled`` setting is on, using the measurement
    components ``use`` (None: the numpy steps, also when Numba is off,
    :data:`uwcosim.core.jit.ENABLED`); a one-line ValueError when the model offers no compiled
    form, or with the chi-square gate (``gate_probability``), which only the numpy step
    applies."""
    # a subclass's own Settings (a user's filter derived from ours) may not declare it
    if not getattr(est.settings, "compiled", False) or not jit.ENABLED:
        return None
    if getattr(est.settings, "gate_probability", None) is not None:  # filters.gating: numpy only
        raise ValueError(f"estimator {est.kind}: compiled = true has no chi-square gate "
                         "(gate_probability); set one of them")
    w = workspace(model, use, extra)
    if w is None:
        raise ValueError(
            f"estimator {est.kind}: compiled = true needs a model with a compiled form (a linear "
            "model, or the TAN model without control noise and its map within the table "
            "limit); set it false")
    return w
