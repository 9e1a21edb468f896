"""A user's filter model from a few lines of CasADi: :func:`from_casadi`, :class:`SymbolicModel`.

The user writes the dynamics and the measurements as CasADi expressions in their own symbols;
:func:`from_casadi` turns them into a :class:`~uwcosim.models.protocol.StateSpaceModel` that
every general filter takes (KF when linear, EKF, UKF, CKF, CUKF, PF, RPF, RBPF, VB-AKF,
QIVBF)::

    import casadi as ca
    from uwcosim.models import from_casadi

    x, y, vx, vy = (ca.SX.sym(n) for n in ("x", "y", "vx", "vy"))
    model = from_casadi(states=[x, y, vx, vy], f=[vx, vy, 0, 0],     # dx/dt
                        h=[ca.sqrt((x - 500)**2 + y**2)],               # range to a beacon
                        Q=[0.01, 0.01, 1e-4, 1e-4], R=[4.0],
                        measurements=["ranger.range_m"])

**Dynamics** (``time``):

- ``"continuous"`` (default): ``f`` is ``dx/dt = f(x, u, w)``; a step of length ``dt`` is
  ``substeps`` RK4 steps with ``u`` and the noise ``w`` held over it (as the master feeds the
  truth FMUs). ``Q`` is the power spectral density of ``w`` (a vector: diagonal, or a
  matrix; constant), so a step's noise covariance is ``Q / dt`` and the model's
  ``Q(x, u, dt) = G (Q / dt) G'`` with ``G = d step / d w`` at ``w = 0``.
- ``"discrete"``: ``f`` is ``x_{k+1} = f(x, u, w, dt)`` (``dt``: the symbol of the step, if
  ``f`` or ``Q`` use it); ``Q`` is the covariance of ``w`` per step (a vector, a matrix, or a
  CasADi expression of ``dt``, the states and the controls), ``Q(x, u, dt) = G Q G'``.

``noise``: the symbols of the process noise in ``f``; without them the noise is additive on
every state (``f + w``, ``Q`` then one entry per state). ``control_psd``: PSDs of noise on the
controls that the truth follows and the filters know, added as ``J_u diag(q_c / dt) J_u'``
(first order, as the TAN model does).

**Measurements**: ``h`` is ``z = h(x) + v``, ``v ~ N(0, R)`` (``R`` a vector of variances or a
matrix), one name per row (``measurements``: in a scenario the outputs of
``[model] sensors``, in order). ``h`` may call the map's terrain function
(:attr:`uwcosim.models.builder.ModelContext.terrain`, a CasADi B-spline): write the states as
``ca.MX.sym`` symbols then (a B-spline has no SX form).

**What the filters get**: ``f``, ``F = df/dx`` and ``Q`` from one CasADi call (``FQ``), ``h``
and its exact Jacobian ``H``, batch forms ``f_batch``/``h_batch`` (``Function.map``) for the
particle and sigma-point filters; ``linear`` (``F`` and ``H`` independent of the state: the
``kf`` then accepts it) and ``Q_depends_on_x`` are read from the expressions. Functions are
SX-expanded when they can be (pure arithmetic: several times faster), else kept as MX (the
terrain B-spline). A continuous model with constant noise also carries its
:class:`~uwcosim.models.casadi_model.CasadiModel` form as ``symbolic`` (what the grid filters
analyse); a discrete model has none.

Every bad input (a free symbol, a shape, a ``Q`` or ``R`` that is not a covariance) is one
``ValueError`` line naming the argument.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import casadi as ca
import numpy as np

from uwcosim.core.integrators import rk4
from uwcosim.models.casadi_model import CasadiModel, PointwiseMap

Expr = ca.SX | ca.MX


# ---- argument normalization -------------------------------------------------------------------

def _symbol_vector(arg, names, what: str) -> tuple[Expr | None, tuple[str, ...]]:
    """A column of symbols and its names from a vector symbol or a list of scalar symbols."""
    if arg is None or (isinstance(arg, Sequence) and not isinstance(arg, str) and not arg):
        if names:
            raise ValueError(f"{what}_names given without {what}s")
        return None, ()
    if isinstance(arg, Sequence) and not isinstance(arg, str):
        items = list(arg)
        bad = [i for i, s in enumerate(items)
               if not isinstance(s, ca.SX | ca.MX) or s.numel() != 1 or not s.is_valid_input()]
        if bad:
            raise ValueError(f"{what}s: entry {bad[0]} is not a scalar CasADi symbol "
                             f"(ca.SX.sym or ca.MX.sym)")
        vec = ca.vertcat(*items)
        default = tuple(s.name() for s in items)
    elif isinstance(arg, ca.SX | ca.MX) and arg.is_valid_input():
        vec = ca.reshape(arg, arg.numel(), 1)
        n = vec.numel()
        default = (arg.name(),) if n == 1 and isinstance(arg, ca.MX) else tuple(
            vec[i].name() if isinstance(vec, ca.SX) else f"{what}{i}" for i in range(n))
    else:
        raise ValueError(f"{what}s: expected CasADi symbols (a vector symbol or a list of "
                         f"scalar symbols), got {type(arg).__name__}")
    out = tuple(names) if names is not None else default
    if len(out) != vec.numel():
        raise ValueError(f"{what}_names: {len(out)} names for {vec.numel()} {what}s")
    if len(set(out)) != len(out):
        raise ValueError(f"{what}_names: names must be distinct, got {list(out)}")
    return vec, out


def _column(expr, what: str) -> Expr:
    """An expression as a column (a list of scalar expressions or numbers is stacked)."""
    if isinstance(expr, Sequence) and not isinstance(expr, str):
        parts = [e if isinstance(e, ca.SX | ca.MX | ca.DM) else ca.DM(float(e)) for e in expr]
        if not parts:
            raise ValueError(f"{what}: no rows")
        if any(isinstance(p, ca.MX) for p in parts):
            parts = [ca.MX(p) if not isinstance(p, ca.MX) else p for p in parts]
        expr = ca.vertcat(*parts)
    if isinstance(expr, int | float | np.ndarray | ca.DM):
        expr = ca.DM(expr)
    if not isinstance(expr, ca.SX | ca.MX | ca.DM):
        raise ValueError(f"{what}: expected a CasADi expression or a list of them, got "
                         f"{type(expr).__name__}")
    return ca.reshape(expr, expr.numel(), 1)


def _empty_like(ref: Expr, name: str) -> Expr:
    return (ca.MX if isinstance(ref, ca.MX) else ca.SX).sym(name, 0)


def _function(name: str, inputs: list, outputs: list, what: str) -> ca.Function:
    """A CasADi function of the user's symbols; a free symbol is one line naming it."""
    try:
        return ca.Function(name, inputs, outputs)
    except RuntimeError as exc:
        known = {str(s) for i in inputs for s in ca.symvar(i)}
        free = sorted({str(s) for o in outputs if isinstance(o, ca.SX | ca.MX)
                       for s in ca.symvar(o)} - known)
        if free:
            raise ValueError(f"{what} uses {', '.join(free)}: not among its symbols ({what} "
                             f"takes {', '.join(sorted(known)) or 'none'})") from None
        raise ValueError(f"{what}: {str(exc).strip().splitlines()[-1]}") from None


def _covariance(value, n: int, what: str) -> np.ndarray:
    """A constant ``n x n`` covariance from a vector (diagonal) or a matrix."""
    try:
        M = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected numbers (a vector or a matrix)") from None
    if M.ndim == 0:
        M = np.full(n, float(M))
    M = np.diag(M) if M.ndim == 1 else M
    if M.shape != (n, n):
        raise ValueError(f"{what}: expected {n} values or a {n}x{n} matrix, got shape "
                         f"{np.shape(value)}")
    if not np.all(np.isfinite(M)):
        raise ValueError(f"{what}: NaN or infinite entries")
    if not np.allclose(M, M.T, rtol=1e-12, atol=0.0):
        raise ValueError(f"{what}: not symmetric")
    ev = np.linalg.eigvalsh(M) if n else np.zeros(0)
    if n and ev[0] < -1e-12 * max(ev[-1], 1e-300):
        raise ValueError(f"{what}: not positive semi-definite (eigenvalues {ev[0]:.3g} .. "
                         f"{ev[-1]:.3g})")
    return M


def _factor(M: np.ndarray) -> np.ndarray:
    """``L`` with ``L L' = M`` for a positive semi-definite ``M`` (its rank columns)."""
    w, V = np.linalg.eigh(M)
    keep = w > 1e-15 * max(float(w.max(initial=0.0)), 1e-300)
    return V[:, keep] * np.sqrt(w[keep])


def _expanded(fn: ca.Function) -> ca.Function:
    """``fn`` SX-expanded when it is pure arithmetic (faster), else as it is (a B-spline)."""
    try:
        return fn.expand()
    except RuntimeError:
        return fn


def _depends(fn: ca.Function, out: int, inp: int) -> bool:
    """Whether output ``out`` of ``fn`` depends on input ``inp`` (the Jacobian's structural
    nonzeros: exact for an SX-expanded function)."""
    return bool(fn.numel_out(out) and fn.numel_in(inp) and fn.jac_sparsity(out, inp).nnz())


# ---- the model ---------------------------------------------------------------------------------

class SymbolicModel:
    """A filter model from CasADi functions: the :class:`StateSpaceModel` protocol, built by
    :func:`from_casadi` (see the module docstring).

    ``step(x, u, w, dt)``: the one-step map; ``noise_cov(x, u, dt)``: the covariance of ``w``
    over a step; ``h(x)``: the measurements. ``ode(x, u, w)`` and ``q_psd``: the continuous form
    with constant noise (``noise_cov = diag(q_psd) / dt``), from which :attr:`symbolic` is
    built.
    """

    def __init__(self, step: ca.Function, noise_cov: ca.Function, h: ca.Function, R,
                 state_names: tuple[str, ...], measurement_names: tuple[str, ...],
                 control_names: tuple[str, ...] = (), control_psd=None,
                 ode: ca.Function | None = None, q_psd=None, substeps: int = 1,
                 time: str = "continuous") -> None:
        self.time = time
        self.nx = int(step.size1_in(0))
        self.nu = int(step.size1_in(1))
        self.nw = int(step.size1_in(2))
        self.nz = int(h.size1_out(0))
        self.state_names = tuple(state_names)
        self.control_names = tuple(control_names)
        self.measurement_names = tuple(measurement_names)
        self.R = _covariance(R, self.nz, "R")
        if self.nz and np.linalg.eigvalsh(self.R)[0] <= 0:
            raise ValueError("R: not positive definite (a measurement needs some noise)")
        self.ode, self.substeps = ode, int(substeps)
        if q_psd is not None:  # the continuous form's noise PSDs (a discrete model has none)
            self.q_psd = np.asarray(q_psd, dtype=float)
        self.control_psd = None if control_psd is None else \
            np.asarray(control_psd, dtype=float).reshape(self.nu)
        x, u, w, dt = (ca.MX.sym(n, m) for n, m in
                       (("x", self.nx), ("u", self.nu), ("w", self.nw), ("dt", 1)))
        w0 = ca.DM.zeros(self.nw)
        xf = step(x, u, w, dt)
        F = ca.substitute(ca.jacobian(xf, x), w, w0)
        G = ca.substitute(ca.jacobian(xf, w), w, w0)
        Q = G @ noise_cov(x, u, dt) @ G.T
        if self.control_psd is not None:
            Ju = ca.substitute(ca.jacobian(xf, u), w, w0)
            Q = Q + Ju @ ca.diag(ca.DM(self.control_psd) / dt) @ Ju.T
        Q = 0.5 * (Q + Q.T)
        x_next = ca.substitute(xf, w, w0)
        self._f_fn = _expanded(ca.Function("f", [x, u, dt], [x_next]))
        self._fq_fn = _expanded(ca.Function("FQ", [x, u, dt], [F, Q]))
        self._fg_fn = _expanded(ca.Function("FG", [x, u, dt], [F, G]))
        self._h_fn = _expanded(h)
        xs = ca.MX.sym("x", self.nx)
        Hx = ca.jacobian(h(xs), xs)
        self._H_fn = _expanded(ca.Function("H", [xs], [Hx]))
        #: ``F`` and ``H`` do not depend on the state (the ``kf`` accepts the model)
        self.linear = not (_depends(self._fq_fn, 0, 0) or _depends(self._H_fn, 0, 0))
        #: ``Q`` depends on the state (the particle filters then factor it at each step)
        self.Q_depends_on_x = _depends(self._fq_fn, 1, 0)
        self._f_batch, self._h_batch = PointwiseMap(self._f_fn), PointwiseMap(self._h_fn)
        self._step, self._noise_cov, self._h_user = step, noise_cov, h

    # single-point evaluations -------------------------------------------------------------
    def f(self, x, u, dt: float) -> np.ndarray:
        return np.asarray(self._f_fn(x, u, dt)).reshape(self.nx)

    def FQ(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F, Q = self._fq_fn(x, u, dt)
        return np.asarray(F).reshape(self.nx, self.nx), np.asarray(Q).reshape(self.nx, self.nx)

    def FG(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F, G = self._fg_fn(x, u, dt)
        return np.asarray(F).reshape(self.nx, self.nx), np.asarray(G).reshape(self.nx, self.nw)

    def F(self, x, u, dt: float) -> np.ndarray:
        return self.FQ(x, u, dt)[0]

    def Q(self, x, u, dt: float) -> np.ndarray:
        return self.FQ(x, u, dt)[1]

    def h(self, x) -> np.ndarray:
        return np.asarray(self._h_fn(x)).reshape(self.nz)

    def H(self, x) -> np.ndarray:
        return np.asarray(self._H_fn(x)).reshape(self.nz, self.nx)

    # batch evaluations (rows are points) -----------------------------------------------------
    def f_batch(self, X: np.ndarray, u, dt: float) -> np.ndarray:
        return self._f_batch(X, u, dt).T

    def h_batch(self, X: np.ndarray) -> np.ndarray:
        return self._h_batch(X).reshape(self.nz, X.shape[0]).T

    # the CasADi form the grid filters analyse --------------------------------------------
    @cached_property
    def symbolic(self) -> CasadiModel | SymbolicModel:
        """The :class:`CasadiModel` of a continuous model with constant noise (the same ODE,
        noise PSDs, measurements and RK4 step; what the projection and point-mass filters
        analyse); the model itself otherwise (a discrete model, or an ODE that calls the
        terrain B-spline, has no such form)."""
        if self.ode is None or getattr(self, "q_psd", None) is None:
            return self
        try:
            return CasadiModel(self.ode, self._h_user, self.q_psd, self.R, self.state_names,
                               self.measurement_names, self.substeps, self.control_psd)
        except RuntimeError:
            return self


def from_casadi(*, states, f, h, Q, R, controls=None, noise=None, measurements=None,
                state_names: Sequence[str] | None = None,
                control_names: Sequence[str] | None = None, time: str = "continuous",
                dt=None, substeps: int = 1, control_psd=None) -> SymbolicModel:
    """A filter model from CasADi expressions (see the module docstring).

    ``states``, ``controls``, ``noise``: a vector symbol or a list of scalar symbols (the
    names default to the symbols' names; ``state_names``/``control_names`` override them);
    ``f``: ``dx/dt`` (``time="continuous"``) or ``x_{k+1}`` (``"discrete"``, with the step
    symbol ``dt``); ``h``: the measurements, named by ``measurements`` (default ``z0``, ...);
    ``Q``: the PSD (continuous) or per-step covariance (discrete) of the noise; ``R``: the
    measurement covariance; ``substeps``: RK4 steps per step (continuous);
    ``control_psd``: PSDs of the noise on the controls."""
    if time not in ("continuous", "discrete"):
        raise ValueError(f"time: expected 'continuous' or 'discrete', got {time!r}")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps: expected a positive integer, got {substeps!r}")
    xs, snames = _symbol_vector(states, state_names, "state")
    if xs is None:
        raise ValueError("states: at least one state")
    us, cnames = _symbol_vector(controls, control_names, "control")
    ws, _ = _symbol_vector(noise, None, "noise")
    us = us if us is not None else _empty_like(xs, "u")
    dts = dt
    if dts is not None and not (isinstance(dts, ca.SX | ca.MX) and dts.numel() == 1
                                and dts.is_valid_input()):
        raise ValueError("dt: expected a scalar CasADi symbol")
    if dts is not None and time == "continuous":
        raise ValueError("dt: the step symbol is for discrete dynamics (time='discrete'); "
                         "continuous dynamics f are dx/dt")
    dts = dts if dts is not None else (ca.MX if isinstance(xs, ca.MX) else ca.SX).sym("dt")
    fx = _column(f, "f")
    if fx.numel() != xs.numel():
        raise ValueError(f"f: {fx.numel()} rows for {xs.numel()} states")
    hx = _column(h, "h")
    nx = xs.numel()
    names = tuple(measurements) if measurements is not None else tuple(
        f"z{i}" for i in range(hx.numel()))
    if len(names) != hx.numel():
        raise ValueError(f"measurements: {len(names)} names for {hx.numel()} rows of h")
    h_fn = _function("h", [xs], [hx], "h")
    additive = ws is None
    ws = ws if ws is not None else _empty_like(xs, "w")
    user = _function("dynamics", [xs, us, ws, dts], [fx], "f")
    nw = nx if additive else ws.numel()
    X, U, W, DT = (ca.MX.sym(n, m) for n, m in (("x", nx), ("u", us.numel()),
                                                ("w", nw), ("dt", 1)))

    def rate(w, step=DT):
        """f(X, U, w, step), the noise ``w`` additive or the user's noise symbols (continuous
        dynamics do not use the step: 0)."""
        return user(X, U, ca.MX(0, 1), step) + w if additive else user(X, U, w, step)

    if time == "continuous":
        Qc = _covariance(Q, nw, "Q (the noise PSDs)")
        if np.count_nonzero(Qc - np.diag(np.diag(Qc))):  # whiten: w = L v, v of unit PSD
            L = _factor(Qc)
            V = ca.MX.sym("v", L.shape[1])
            ode = ca.Function("ode", [X, U, V], [rate(ca.DM(L) @ V, 0.0)])
            psd = np.ones(L.shape[1])
        else:
            ode = ca.Function("ode", [X, U, W], [rate(W, 0.0)])
            psd = np.diag(Qc).copy()
        ode = _expanded(ode)
        Ws = ca.MX.sym("w", ode.size1_in(2))
        xk = rk4(lambda _t, xx: ode(xx, U, Ws), X, 0.0, DT, substeps)
        step = ca.Function("step", [X, U, Ws, DT], [xk])
        cov = ca.Function("noise_cov", [X, U, DT], [ca.diag(ca.DM(psd)) / DT])
        return SymbolicModel(step, cov, h_fn, R, snames, names, cnames, control_psd, ode, psd,
                             substeps, time)
    step = ca.Function("step", [X, U, W, DT], [rate(W)])
    if isinstance(Q, ca.SX | ca.MX):
        Qe = ca.reshape(Q, Q.size1(), Q.size2()) if Q.size2() > 1 else ca.diag(Q)
        if Qe.shape != (nw, nw):
            raise ValueError(f"Q: expected {nw} values or a {nw}x{nw} matrix, got "
                             f"{Q.size1()}x{Q.size2()}")
        qf = _function("noise_cov", [xs, us, dts], [Qe], "Q")
        cov = ca.Function("noise_cov", [X, U, DT], [qf(X, U, DT)])
    else:
        cov = ca.Function("noise_cov", [X, U, DT], [ca.DM(_covariance(Q, nw, "Q"))])
    return SymbolicModel(step, cov, h_fn, R, snames, names, cnames, control_psd,
                         time=time)
