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
- splits the measurement components available at a step into Kalman and grid rows
  (:meth:`Partition.split_rows`; the availability bits by :func:`available_bits_numpy` or
  the compiled :func:`available_bits`, chosen once);
- the conditional Kalman filter of the ``k`` block, which gives the increment of ``p`` over a
  step with its covariance, is in :mod:`uwcosim.filters.grid.conditional`;
- the log-likelihood of the ``p`` rows on a tensor grid is in
  :mod:`uwcosim.filters.grid.likelihood`.

The continuous drift is ``model.ode(x, u, 0)`` when the model exposes its ODE as ``ode``;
otherwise it is the mean rate of the model's own one-step map, ``(f(x, u, dt) - x) / dt``, and
``B = Q_d / dt`` with ``Q_d = G diag(psd / dt) G'`` (identical for the TAN model, whose RK4 step is
exact).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from uwcosim.core.jit import ENABLED, bound, jit


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
        #: the outputs' buffers, flat (column-major), as :meth:`views` fills them
        self.flat = self._out

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
    the module docstring); ``measurements``: names of the measurement rows to use (default all);
    ``compiled``: :meth:`split_rows` by the compiled :func:`available_bits` (default: when
    Numba is enabled) instead of its numpy form :func:`available_bits_numpy` (the same rows).
    """

    def __init__(self, model, states=None, measurements=None, max_dim: int = 3,
                 compiled: bool | None = None) -> None:
        for attr in ("f_fn", "FG_fn", "h_fn", "q_psd"):
            if not hasattr(model, attr):
                raise ValueError(
                    "the projection and point-mass filters need the CasadiModel (its CasADi "
                    "functions), not a numpy fast path: a continuous-time model with constant "
                    "noise PSDs (a CasadiModel, from_casadi(time='continuous'), or a model whose "
                    "'symbolic' is one)"
                )
        self.model = model
        use_kernel = ENABLED if compiled is None else (compiled and ENABLED)
        self._available = bound(available_bits) if use_kernel else available_bits_numpy
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
        qc = getattr(model, "control_psd", None)
        if ode is not None:
            w = ca.SX.sym("w", model.nw)
            xdot = ode(x, u, w)
            f = ca.substitute(xdot, w, ca.DM.zeros(model.nw))
            G = ca.substitute(ca.jacobian(xdot, w), w, ca.DM.zeros(model.nw))
            B = G @ ca.diag(ca.DM(model.q_psd)) @ G.T
            if qc is not None:  # control noise: its diffusion through df/du
                Ju = ca.substitute(ca.jacobian(xdot, u), w, ca.DM.zeros(model.nw))
                B = B + Ju @ ca.diag(ca.DM(qc)) @ Ju.T
        else:
            F_d, G = model.FG_fn(x, u, dt)
            f = (model.f_fn(x, u, dt) - x) / dt
            B = G @ ca.diag(ca.DM(model.q_psd)) @ G.T / dt**2  # B dt = Q_d
            if qc is not None:
                Ju = model.Ju_fn(x, u, dt)
                B = B + Ju @ ca.diag(ca.DM(qc)) @ Ju.T / dt**2
        self.continuous = ode is not None
        Jf = ca.jacobian(f, x)
        f_dep = np.array(ca.DM(Jf.sparsity(), 1)).astype(bool)
        f_lin = [not _depends(Jf[i, :], x) for i in range(nx)]
        # B[j, i] depends on the state: with control noise the heading's diffusion of the
        # position depends on the velocity, which does not stop the velocity from being a
        # Kalman state as long as the velocity block's own noise B[k, k] does not
        B_dep = np.array([[_depends(B[j, i], x) for i in range(nx)] for j in range(nx)])
        xm = ca.MX.sym("x", nx)
        Jh = ca.jacobian(model.h_fn(xm), xm)
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
                        or any(B_dep[j, i] for i in k)
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
                "are supported (set 'states' to the nonlinear ones; a state is taken as a "
                "Kalman state only if its dynamics are affine and independent of the gridded "
                "states and a linear measurement row observes it)"
            )
        self._validate(f, Jf, B, h_dep, h_lin, x)
        self._splits: dict[int, tuple[list[int], list[int]]] = {}
        self.rows_grid = [r for r in range(model.nz) if self.use[r] and h_dep[r, p].any()]
        self.rows_kalman = [r for r in range(model.nz) if self.use[r] and r not in self.rows_grid]
        # one-step map, its Jacobian and the discrete noise covariance, in one fast call
        xs, us, dts = ca.SX.sym("x", nx), ca.SX.sym("u", nu), ca.SX.sym("dt")
        Fd, Gd = model.FG_fn(xs, us, dts)
        Qd = Gd @ ca.diag(ca.DM(model.q_psd) / dts) @ Gd.T
        if qc is not None:  # evaluated where the filters call it: at their estimate
            Jud = model.Ju_fn(xs, us, dts)
            Qd = Qd + Jud @ ca.diag(ca.DM(qc) / dts) @ Jud.T
        step = ca.Function("step", [xs, us, dts], [model.f_fn(xs, us, dts), Fd, Qd])
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

    def split_rows(self, z, mask):
        """``(z, kalman rows, grid rows)`` of the measurement components available now (finite,
        not masked, used)."""
        if z is None:
            return None, [], []
        z = np.asarray(z, dtype=float)
        bits = self._available(z, self.use if mask is None else np.asarray(mask, bool),
                               self.use)
        if bits == 0:
            return z, [], []
        split = self._splits.get(bits)
        if split is None:
            rows = [r for r in range(z.size) if bits >> r & 1]
            split = ([r for r in rows if r in self.rows_kalman],
                     [r for r in rows if r in self.rows_grid])
            self._splits[bits] = split
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


def available_bits_numpy(z: np.ndarray, mask: np.ndarray, use: np.ndarray) -> int:
    """Bit ``r`` set when ``z[r]`` is finite and ``mask[r]`` and ``use[r]`` (numpy form of
    :func:`available_bits`)."""
    bits = 0
    for r in np.flatnonzero(np.isfinite(z) & mask & use).tolist():
        bits |= 1 << r
    return bits


@jit
def available_bits(z, mask, use):
    """Bit ``r`` set when ``z[r]`` is finite and ``mask[r]`` and ``use[r]`` (compiled)."""
    bits = 0
    for r in range(z.size):
        if mask[r] and use[r] and math.isfinite(z[r]):
            bits |= 1 << r
    return bits
