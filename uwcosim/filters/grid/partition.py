"""Model analysis shared by the projection (``pfm_psi``) and point-mass filters.

Both filters represent the density of a few *gridded* states ``p`` on a grid or spectral basis
and handle the remaining states ``k`` with a Kalman filter, conditionally on the mean of ``p``.
This module

- splits a :class:`~uwcosim.models.casadi_model.CasadiModel` state into ``p`` and ``k``
  (:class:`Partition`) from the CasADi structure of the dynamics and measurements: the ``k``
  block must have affine dynamics independent of ``p`` and be measured only by affine rows that
  do not involve ``p``; every other measurement row must involve ``p`` only. For the TAN model
  (seed 000, eqs. 54-55) this gives ``p = (x, y)``, ``k = (vx, vy)``: the velocities obey
  ``v' = v + a [cos psi, sin psi] dt`` and the DVL measures them directly, the terrain depth
  depends on position only;
- builds the Fokker-Planck coefficient fields of the gridded block from the CasADi drift ``f``:
  ``f_p``, ``div f_p`` and the diffusion ``B = g Q g'`` with its derivatives (CasADi
  differentiates; :meth:`Partition.fields` evaluates them on a grid with ``Function.map``);
- runs the conditional Kalman filter of the ``k`` block (:class:`ConditionalKalman`) and returns
  the increment of ``p`` over a step with its covariance: the velocity uncertainty becomes extra
  diffusion of the position, inflated to the *long-run* covariance of the velocity error
  (see :meth:`ConditionalKalman.increment`);
- the log-likelihood of the ``p`` rows on a tensor grid is in
  :mod:`uwcosim.filters.grid.likelihood`.

The continuous drift is ``model.ode(x, u, 0)`` when the model exposes its ODE as ``ode``;
otherwise it is the mean rate of the model's own one-step map, ``(f(x, u, dt) - x) / dt``, and
``B = Q_d / dt`` with ``Q_d = G diag(psd / dt) G'`` (identical for the TAN model, whose RK4 step is
exact).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import casadi as ca
import numpy as np
from scipy.linalg import lapack

from uwcosim.errors import FilterDivergence
from uwcosim.filters.base import select
from uwcosim.filters.grid import projection_kernels as pk
from uwcosim.filters.numerics import cholesky, kalman_gain, nis, symmetrize

_gesv = lapack.dgesv


class FastFunction:
    """Low-overhead numeric calls of a CasADi function (``Function.buffer``, ~1 us per call).

    Outputs are densified and returned as numpy arrays of their CasADi shapes.
    """

    def __init__(self, fn: ca.Function) -> None:
        sx_in = fn.sx_in()
        outs = [ca.densify(o) for o in fn.call(sx_in)]
        self.fn = ca.Function(fn.name() + "_dense", sx_in, outs)
        self._buf, self._eval = self.fn.buffer()
        self._in = [np.zeros(self.fn.nnz_in(i)) for i in range(self.fn.n_in())]
        self._out = [np.zeros(self.fn.nnz_out(i)) for i in range(self.fn.n_out())]
        self._shapes = [self.fn.size_out(i) for i in range(self.fn.n_out())]
        for i, a in enumerate(self._in):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._out):
            self._buf.set_res(i, memoryview(r))
        self._views = [r.reshape(s, order="F") for r, s in zip(self._out, self._shapes,
                                                                 strict=True)]

    def __call__(self, *args) -> list[np.ndarray]:
        for a, v in zip(self._in, args, strict=False):
            a[:] = v if getattr(v, "ndim", 1) <= 1 else np.ravel(v)
        self._eval()
        pairs = zip(self._out, self._shapes, strict=True)
        return [r.reshape(s, order="F").copy() for r, s in pairs]

    def views(self, *args) -> list[np.ndarray]:
        """As a call, but the outputs are views of the internal buffers (Fortran order), valid
        until the next call: for a caller that consumes them at once."""
        for a, v in zip(self._in, args, strict=False):
            a[:] = v if getattr(v, "ndim", 1) <= 1 else np.ravel(v)
        self._eval()
        return self._views


def symbolic(model):
    """The CasADi form of a model, whose expressions :class:`Partition` analyses: a model with
    a closed-form implementation (the TAN model) carries it as ``model.symbolic``."""
    return getattr(model, "symbolic", model)


def _resolve_states(spec, names: tuple[str, ...]) -> list[int]:
    out = []
    for s in spec:
        if isinstance(s, str):
            if s not in names:
                raise ValueError(f"unknown state {s!r} (valid: {', '.join(names)})")
            out.append(names.index(s))
        else:
            i = int(s)
            if not 0 <= i < len(names):
                raise ValueError(f"state index {i} out of range 0..{len(names) - 1}")
            out.append(i)
    if len(set(out)) != len(out) or not out:
        raise ValueError(f"states must be a non-empty list of distinct states, got {spec}")
    return sorted(out)


def _depends(expr, sym) -> bool:
    """Whether ``expr`` depends on ``sym`` (structurally, after the zero pattern)."""
    return bool(expr.numel() and ca.depends_on(expr, sym))


class Partition:
    """Split of the state into gridded states ``p`` and conditionally linear states ``k``.

    ``states``: names or indices of the gridded states (default: chosen from the structure, see
    the module docstring); ``measurements``: names of the measurement rows to use (default all).
    """

    def __init__(self, model, states=None, measurements=None, max_dim: int = 3) -> None:
        for attr in ("_f", "_FG", "_h", "q_psd"):
            if not hasattr(model, attr):
                raise ValueError(
                    "the projection and point-mass filters need the CasadiModel (its CasADi "
                    "functions), not a numpy fast path"
                )
        self.model = model
        nx, nu = model.nx, model.nu
        names = tuple(model.measurement_names)
        if measurements is None:
            self.use = np.ones(model.nz, dtype=bool)
        else:
            unknown = [m for m in measurements if m not in names]
            if unknown:
                raise ValueError(f"unknown measurements {unknown} (valid: {', '.join(names)})")
            self.use = np.array([n in measurements for n in names])

        x = ca.SX.sym("x", nx)
        u = ca.SX.sym("u", nu)
        dt = ca.SX.sym("dt")
        ode = getattr(model, "ode", None)
        if ode is not None:
            w = ca.SX.sym("w", model.nw)
            xdot = ode(x, u, w)
            f = ca.substitute(xdot, w, ca.DM.zeros(model.nw))
            G = ca.substitute(ca.jacobian(xdot, w), w, ca.DM.zeros(model.nw))
            B = G @ ca.diag(ca.DM(model.q_psd)) @ G.T
        else:
            F_d, G = model._FG(x, u, dt)
            f = (model._f(x, u, dt) - x) / dt
            B = G @ ca.diag(ca.DM(model.q_psd)) @ G.T / dt**2  # B dt = Q_d
        self.continuous = ode is not None
        Jf = ca.jacobian(f, x)
        f_dep = np.array(ca.DM(Jf.sparsity(), 1)).astype(bool)
        f_lin = [not _depends(Jf[i, :], x) for i in range(nx)]
        B_dep = [_depends(B[i, :], x) for i in range(nx)]
        xm = ca.MX.sym("x", nx)
        Jh = ca.jacobian(model._h(xm), xm)
        h_dep = np.array(ca.DM(Jh.sparsity(), 1)).astype(bool)
        h_lin = [not _depends(Jh[r, :], xm) for r in range(model.nz)]

        if states is None:
            rows = [r for r in range(model.nz) if self.use[r]]
            k = {j for r in rows if h_lin[r] for j in np.flatnonzero(h_dep[r])}

            def bad_row(r, k):
                return not h_lin[r] or any(h_dep[r, i] and i not in k for i in range(nx))

            changed = True
            while changed:
                changed = False
                for j in sorted(k):
                    bad = (
                        not f_lin[j]
                        or B_dep[j]
                        or any(f_dep[j, i] and i not in k for i in range(nx))
                        or any(h_dep[r, j] and bad_row(r, k) for r in rows)
                    )
                    if bad:
                        k.discard(j)
                        changed = True
            p = [i for i in range(nx) if i not in k] or list(range(nx))
        else:
            p = _resolve_states(states, model.state_names)
        kk = [i for i in range(nx) if i not in p]
        self.p, self.k = p, kk
        if len(p) > max_dim:
            raise ValueError(
                f"{len(p)} gridded states {[model.state_names[i] for i in p]}; at most {max_dim} "
                "are supported (set 'states' to the nonlinear ones)"
            )
        self._validate(f, Jf, B, h_dep, h_lin, x)
        self._splits: dict[bytes, tuple[list[int], list[int]]] = {}
        self.rows_grid = [r for r in range(model.nz) if self.use[r] and h_dep[r, p].any()]
        self.rows_kalman = [r for r in range(model.nz) if self.use[r] and r not in self.rows_grid]
        # one-step map, its Jacobian and the discrete noise covariance, in one fast call
        xs, us, dts = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("dt")
        Fd, Gd = model._FG(xs, us, dts)
        Qd = Gd @ ca.diag(ca.DM(model.q_psd) / dts) @ Gd.T
        step = ca.Function("step", [xs, us, dts], [model._f(xs, us, dts), Fd, Qd])
        self.step = FastFunction(step)
        # the Kalman rows are affine in x: h_rows(x) = H_rows x + c_rows
        x_ref = np.zeros(nx)
        if self.rows_kalman:
            self.H_kalman = model.H(x_ref)[self.rows_kalman]
            self.c_kalman = model.h(x_ref)[self.rows_kalman]

        xp = x[p]
        fp = f[p]
        Bp = B[p, p]
        divf = sum(ca.jacobian(fp[i], x)[p[i]] for i in range(len(p)))
        dB = ca.vertcat(*[sum(ca.jacobian(Bp[r, s], x)[p[r]] for r in range(len(p)))
                          for s in range(len(p))])
        ddB = sum(ca.jacobian(ca.jacobian(Bp[r, s], x)[p[r]], x)[p[s]]
                  for r in range(len(p)) for s in range(len(p)))
        xps = ca.SX.sym("xp", len(p))
        xks = ca.SX.sym("xk", len(kk))
        subs = ca.vertcat(*[xps[p.index(i)] if i in p else xks[kk.index(i)] for i in range(nx)])
        outs = [ca.substitute(e, x, subs) for e in (fp, divf, ca.vec(Bp), dB, ddB)]
        self._fields = ca.Function("fpe_fields", [xps, xks, u, dt], outs)
        self._field_maps: dict[int, ca.Function] = {}
        self.drift_constant = not _depends(ca.vertcat(fp, ca.vec(Bp)), xp)
        self.diffusion_constant = not _depends(ca.vec(Bp), xp)

    def split_rows(self, z, mask, nz: int):
        """``(z, kalman rows, grid rows)`` of the measurement components available now."""
        if pk.ENABLED and z is not None:
            z = np.asarray(z, dtype=float)
            bits = pk.available_bits(z, self.use if mask is None else np.asarray(mask, bool),
                                     self.use)
            if bits == 0:
                return z, [], []
            split = self._splits.get(bits)
            if split is None:
                rows = [r for r in range(nz) if bits >> r & 1]
                split = ([r for r in rows if r in self.rows_kalman],
                         [r for r in rows if r in self.rows_grid])
                self._splits[bits] = split
            return z, list(split[0]), list(split[1])
        if z is not None:
            mask = self.use if mask is None else (np.asarray(mask, bool) & self.use)
        idx = select(z, mask, nz)
        z = None if z is None else np.asarray(z, dtype=float)
        if idx is None:
            return z, [], []
        key = idx.tobytes()
        split = self._splits.get(key)
        if split is None:
            rows = [int(r) for r in idx]
            split = ([r for r in rows if r in self.rows_kalman],
                     [r for r in rows if r in self.rows_grid])
            self._splits[key] = split
        return z, list(split[0]), list(split[1])

    def _validate(self, f, Jf, B, h_dep, h_lin, x) -> None:
        p, k, names = self.p, self.k, self.model.state_names
        for j in k:
            if _depends(f[j], x[p]) or _depends(Jf[j, :], x):
                raise ValueError(
                    f"state {names[j]!r} cannot be handled by the conditional Kalman filter: its "
                    "dynamics must be affine and independent of the gridded states"
                )
        if k and _depends(ca.jacobian(f[p], x[k]), x[k]):
            raise ValueError("the gridded states' drift must be affine in the Kalman states")
        for r in range(self.model.nz):
            if not self.use[r]:
                continue
            on_p, on_k = h_dep[r, p].any(), h_dep[r, k].any() if k else False
            if on_p and on_k:
                raise ValueError(
                    f"measurement {self.model.measurement_names[r]!r} depends on both gridded and "
                    "Kalman states; grid the states it depends on"
                )
            if on_k and not h_lin[r]:
                name = self.model.measurement_names[r]
                raise ValueError(f"measurement {name!r} is nonlinear in Kalman states")

    @property
    def names(self) -> list[str]:
        return [self.model.state_names[i] for i in self.p]

    def fields(self, points: np.ndarray, xk, u, dt: float):
        """FPE coefficient fields at ``points`` (rows are gridded-state points).

        Returns ``(f (N, n), div f (N,), B (N, n, n), dB (N, n), ddB (N,))`` with
        ``dB_s = sum_r dB_rs/dx_r`` and ``ddB = sum_rs d2B_rs/dx_r dx_s``.
        """
        N, n = points.shape
        fm = self._field_maps.get(N)
        if fm is None:
            fm = self._field_maps[N] = self._fields.map(N)
        xk = np.asarray(xk, float).reshape(-1)
        f, divf, B, dB, ddB = (np.asarray(o) for o in fm(points.T, xk, u, dt))
        return f.T, divf.ravel(), B.T.reshape(N, n, n), dB.T, ddB.ravel()

    def fpe_coefficients(
        self, axes: list[np.ndarray], xk, u, dt: float, extra_B=None, taper: float = 0.1
    ):
        """Operator coefficients ``(c0, c1, c2)`` of ``L* p`` on the tensor grid ``axes``.

        The drift is multiplied by a C-infinity window ``W`` that falls from 1 to 0 over the outer
        ``taper`` fraction of each side of the box: on the periodic box a drift that does not
        vanish at the edges jumps at the seam, which gives the Galerkin matrix spurious growing
        modes; the density is negligible where ``W < 1``. ``div(W f) = W div f + f . grad W``.
        """
        n = len(axes)
        mesh = np.meshgrid(*axes, indexing="ij")
        shape = mesh[0].shape
        pts = np.stack([g.ravel() for g in mesh], axis=1)
        f, divf, B, dB, ddB = self.fields(pts, xk, u, dt)
        if extra_B is not None:
            B = B + np.asarray(extra_B)[None]
        W = np.ones(shape)
        gradW = []
        if taper > 0:
            ws = [_window(a, taper) for a in axes]
            for d in range(n):
                W = W * _along(ws[d][0], d, n)
            for d in range(n):
                g = np.ones(shape)
                for e in range(n):
                    g = g * _along(ws[e][1] if e == d else ws[e][0], e, n)
                gradW.append(g)
        c0 = 0.5 * ddB.reshape(shape) - W * divf.reshape(shape)
        for d in range(len(gradW)):
            c0 = c0 - gradW[d] * f[:, d].reshape(shape)
        c1 = [(dB[:, s].reshape(shape) - W * f[:, s].reshape(shape)) for s in range(n)]
        c2 = [[0.5 * B[:, r, s].reshape(shape) for s in range(n)] for r in range(n)]
        return c0, c1, c2


def _along(v: np.ndarray, d: int, n: int) -> np.ndarray:
    shape = [1] * n
    shape[d] = v.size
    return v.reshape(shape)


def _window(a: np.ndarray, taper: float) -> tuple[np.ndarray, np.ndarray]:
    """C-infinity edge window on the periodic grid ``a`` (and its derivative)."""
    L = (a[1] - a[0]) * a.size
    s = (a - a[0]) / L
    left = s < 0.5
    t = np.where(left, s, 1.0 - s) / taper
    dtdx = np.where(left, 1.0, -1.0) / (taper * L)
    t = np.clip(t, 0.0, 1.0)

    def psi(v):
        with np.errstate(divide="ignore", over="ignore"):
            return np.where(v > 0, np.exp(-1.0 / np.where(v > 0, v, 1.0)), 0.0)

    def dpsi(v):
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            vv = np.where(v > 0, v, 1.0)
            return np.where(v > 0, np.exp(-1.0 / vv) / vv**2, 0.0)

    p, q = psi(t), psi(1.0 - t)
    w = p / (p + q)
    dw = (dpsi(t) * q + p * dpsi(1.0 - t)) / (p + q) ** 2
    return w, dw * dtdx * ((t > 0) & (t < 1))


def block_index(rows: list[int], cols: list[int] | None = None):
    """Index of ``rows`` (and ``cols``): basic slices when contiguous (cheaper than fancy
    indexing on the small matrices of every step), else integer arrays / ``np.ix_``."""

    def one(idx):
        if idx and list(idx) == list(range(idx[0], idx[0] + len(idx))):
            return slice(idx[0], idx[0] + len(idx))
        return np.asarray(idx, dtype=np.intp)

    if cols is None:
        return one(rows)
    r, c = one(rows), one(cols)
    if isinstance(r, slice) and isinstance(c, slice):
        return r, c
    return np.ix_(rows, cols)


class Increment(NamedTuple):
    """Increment of the gridded block over a step, at the mean of the other states."""

    d: np.ndarray  # mean increment f(x)_p - x_p
    D: np.ndarray  # its covariance Q_pp + F_pk S F_pk'
    Dk: np.ndarray  # the part due to the Kalman states, F_pk S F_pk'
    F: np.ndarray  # Jacobian of the one-step map at the mean


class ConditionalKalman:
    """Kalman filter of the ``k`` block, conditionally on the mean of the gridded block.

    The joint density is approximated by ``p(x_p) N(x_k; mean, cov)`` (cross-covariance
    neglected). Over a step the gridded block moves by ``d = f(x)_p - x_p`` at the mean, with
    covariance ``Q_pp + F_pk S F_pk'``. ``S`` is the long-run covariance of the Kalman error
    ``e_k`` (``sum over lags of Cov(e_k, e_{k+l})``): the error of a filtered velocity is
    correlated from step to step (``e_{k+1} = Phi e_k + noise``, ``Phi = (I - K H) F``), so the
    position error it integrates grows like ``S`` per step, not like the one-step ``P``:
    ``S = (I - Phi)^-1 P + P (I - Phi')^-1 - P``. With ``long_run=False``, ``S = P``.
    """

    def __init__(self, model, part: Partition, x0, P0, long_run: bool = True) -> None:
        self.model = model
        self.p, self.k = part.p, part.k
        self.rows = part.rows_kalman
        self.mean = np.asarray(x0, float)[self.k].copy()
        self.cov = np.asarray(P0, float)[np.ix_(self.k, self.k)].copy()
        self.long_run = bool(long_run)
        self._F = np.eye(len(self.k))
        self._eye = np.eye(len(self.k))
        self._phi = None
        self.step = part.step
        ip, ik = block_index(self.p), block_index(self.k)
        self._ip, self._ik = ip, ik
        self._pp = block_index(self.p, self.p)
        self._pk = block_index(self.p, self.k)
        self._kk = block_index(self.k, self.k)
        self._p_arr = np.asarray(self.p, dtype=np.int64)
        self._k_arr = np.asarray(self.k, dtype=np.int64)
        #: compiled kernels (projection_kernels) when Numba is there; False: numpy code
        self.fast = pk.ENABLED
        self._rows_idx = np.asarray(self.rows, dtype=np.intp)
        if self.rows:
            self.H = part.H_kalman[:, self.k]
            self.c = part.c_kalman
            self._R = model.R[np.ix_(self.rows, self.rows)]

    def long_run_cov(self) -> np.ndarray:
        P = self.cov
        if not self.long_run or self._phi is None or not len(self.k):
            return P
        _, _, X, info = _gesv(self._eye - self._phi, P)
        if info != 0:
            return P
        S = X + X.T - P
        S = 0.5 * (S + S.T)
        if not math.isfinite(float(S.sum())) or np.trace(S) > 1e6 * max(np.trace(P), 1e-300):
            return P  # (nearly) unit eigenvalue: no DVL information, random-walk error
        if cholesky(S) is None:
            return P
        return S

    def increment(self, x_full, u, dt: float) -> Increment:
        """Predict the ``k`` block; return the gridded block's increment over the step."""
        fx, F, Q = self.step(x_full, u, dt)
        fx = fx.reshape(-1)
        if self.fast:
            use_phi = self.long_run and self._phi is not None and bool(self.k)
            phi = self._phi if use_phi else self._eye
            d, D, Dk, self.mean, self.cov = pk.kalman_increment(
                np.asarray(x_full, float), fx, F, Q, self._p_arr, self._k_arr, self.cov, phi,
                use_phi)
            if self.k:
                self._F = F[self._kk]
            return Increment(d, D, Dk, F)
        k = self.k
        d = fx[self._ip] - x_full[self._ip]
        D = Q[self._pp]
        if k:
            Fpk = F[self._pk]
            Dk = Fpk @ self.long_run_cov() @ Fpk.T
            Dk = 0.5 * (Dk + Dk.T)
            Fkk = F[self._kk]
            self.mean = fx[self._ik]
            C = Fkk @ self.cov @ Fkk.T + Q[self._kk]
            self.cov = 0.5 * (C + C.T)
            self._F = Fkk
            D = D + Dk
        else:
            Dk = np.zeros_like(D)
        return Increment(d, 0.5 * (D + D.T), Dk, F)

    def update(self, x_full, z, rows, diagnostics: dict) -> None:
        """Kalman update of the ``k`` block with the measurement rows ``rows``."""
        if not rows or not self.k:
            return
        if rows == self.rows:
            H, R, c = self.H, self._R, self.c
            if self.fast:
                mean, cov, phi, nis_, ok = pk.kalman_update(self.mean, self.cov, H, R, c,
                                                            z.take(self._rows_idx), self._F)
                if ok:
                    self.mean, self.cov, self._phi = mean, cov, phi
                    diagnostics["nis"] = nis_
                    diagnostics["nis_dof"] = float(len(rows))
                    return
        else:
            sel = [self.rows.index(r) for r in rows]
            H, R, c = self.H[sel], self.model.R[np.ix_(rows, rows)], self.c[sel]
        y = z[rows] - (H @ self.mean + c)  # rows affine in x_k, independent of x_p
        PHt = self.cov @ H.T
        S = symmetrize(H @ PHt + R)
        K, cho = kalman_gain(PHt, S, diagnostics)  # K = P H' S^-1 (LAPACK Cholesky)
        diagnostics["nis"] = nis(y, cho)
        self.mean = self.mean + K @ y
        IKH = self._eye - K @ H
        C = IKH @ self.cov @ IKH.T + K @ R @ K.T  # Joseph form
        self.cov = 0.5 * (C + C.T)
        self._phi = IKH @ self._F
        diagnostics["nis_dof"] = float(len(rows))


def assemble_estimate(est) -> tuple[np.ndarray, np.ndarray]:
    """``(x, P)`` of a partitioned filter (grid or projection) from its gridded block
    (``_mean``, ``_cov``) and its conditional Kalman block; FilterDivergence if non-finite."""
    kal = est.kalman
    if kal.fast:
        x, P, finite = pk.assemble(est.x.size, kal._p_arr, kal._k_arr, est._mean, est._cov,
                                   kal.mean, kal.cov)
        if not finite:
            est.diverged = True
            raise FilterDivergence(f"{est.kind}: non-finite estimate")
        return x, P
    x = est.x.copy()
    P = np.zeros_like(est.P)
    x[est._ip] = est._mean
    P[est._pp] = est._cov
    if est.part.k:
        x[est._ik] = est.kalman.mean
        P[est._kk] = est.kalman.cov
    if not np.isfinite(x.sum() + P.sum()):
        raise FilterDivergence(f"{est.kind}: non-finite estimate")
    return x, symmetrize(P)
