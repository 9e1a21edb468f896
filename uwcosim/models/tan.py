"""The terrain-aided navigation model of seed 000 Example 2 for the filters.

State ``[x, y, vx, vy]``, control ``[psi, a]``, process noise on all four states (eq. 54);
measurements ``[vx, vy]`` from the DVL and, with a map, the terrain depth ``h_d(x, y)``
(eq. 55). :func:`tan_model` builds it from the same CasADi expressions as the FMUs
(:mod:`uwcosim.models.auv_equations`) and returns the closed-form numpy implementation
:class:`TANModel`, whose ``symbolic`` attribute is the CasADi form (the grid filters analyse its
expressions). ``tests/test_filters_tan.py`` checks the two against each other.

Why a closed form: CasADi's ``map`` costs about 1 ms per 1000 points and a single CasADi call
30-60 us, which is the whole budget of a 1000-particle step. For the kinematics of eq. (54)
with inputs and noise held over a step the exact solution is (RK4 reproduces it, the position
being quadratic in time)::

    p' = p + dt (Rot v + w_p) + dt^2/2 Rot (a e + w_v),   v' = v + dt (a e + w_v)

with ``Rot`` the rotation by ``psi`` and ``e = [cos psi, sin psi]``: a linear map
``x' = F x + b + G w`` with ``F = [[I, dt Rot], [0, I]]`` and ``G = [[dt I, dt^2/2 Rot],
[0, dt I]]``.

Control noise (``control_psd``, the scenario's ``model.control_noise``): when the truth follows
``psi + w_psi`` and ``a + w_a`` (white noise held over the step, PSDs ``q_c``) while the filters
know the commanded controls, the step is linearized in the controls and
``Q = G diag(q/dt) G' + J diag(q_c/dt) J'`` with ``J = d x'/d(psi, a)`` at the current state and
control (:func:`control_jacobian`). The heading column depends on the velocity
(``dt Rot'(psi) v``), so ``Q`` then depends on the state (``Q_depends_on_x``); filters evaluate it
at their estimate. The acceleration column is exact (the step is linear in ``a``).

:class:`FastTerrain` evaluates the same cubic B-spline as :meth:`Bathymetry.depth` from a table
of per-cell bicubic polynomial coefficients (16 per cell, 128 bytes: 32 MB for the default
25 km x 25 km map at 50 m, built once per map in ~0.1 s and shared), one gather and two Horner
schemes per point. Maps above 512 MB of table fall back to :meth:`Bathymetry.depth`. When
Numba is already imported (by the grid filters) the lookups of ``h_batch`` and of one point run
compiled (:mod:`uwcosim.models.terrain_kernels`, the same bits); Numba is never imported for
them alone. ``h(x)`` then ``H(x)`` at the same point (the EKF) cost one lookup.
"""

from __future__ import annotations

import math
import sys
import weakref

import casadi as ca
import numpy as np

from uwcosim.core import bspline, jit, kinematics
from uwcosim.core.bicubic import Surface
from uwcosim.models import terrain_kernels  # compiled (importing loads no Numba)
from uwcosim.models.auv_equations import STATE_NAMES, vehicle_ode
from uwcosim.models.casadi_model import CasadiModel
from uwcosim.models.protocol import CompiledForm
from uwcosim.models.terrain import PAD, Bathymetry

DVL_NAMES = ("dvl.vx_m", "dvl.vy_m")
DEPTH_NAME = "sounder.depth_m"

TABLE_MAX_BYTES = 512 * 2**20
# cubic B-spline basis in the monomial basis: w_a(f) = sum_i _M[a, i] f^i (uwcosim.core.bspline)
_M = bspline.MONOMIAL.T
_TABLES: dict[int, np.ndarray] = {}
_KERNELS: list = []  # [module of the compiled lookups] once Numba is loaded, [None] if disabled


def _kernels():
    """:mod:`uwcosim.models.terrain_kernels` when Numba is already imported and enabled (Numba
    is never imported for this alone: about 0.5 s), else None."""
    if _KERNELS:
        return _KERNELS[0]
    if "numba" not in sys.modules:
        return None  # asked again at the next call: the grid filters may load it later
    if jit.ENABLED:
        _KERNELS.append(terrain_kernels)
    else:
        _KERNELS.append(None)
    return _KERNELS[0]


def _stencil_sum(w, views, out: np.ndarray, tmp: np.ndarray) -> np.ndarray:
    """``out = 0 + w[0] views[0] + w[1] views[1] + ...`` in that order, in place: the bits of
    ``sum(w[k] * views[k] for k ...)`` (whose ``0 +`` turns -0.0 into 0.0) without a fresh
    temporary per term (two whole-map arrays of 2 MB for each of the table's 80 terms at the
    default map's size)."""
    np.multiply(w[0], views[0], out=out)
    out += 0.0
    for k in range(1, len(views)):
        np.multiply(w[k], views[k], out=tmp)
        out += tmp
    return out


def _poly_table(bathy: Bathymetry) -> np.ndarray | None:
    """Per-cell polynomial coefficients ``[4*i + j, cell]`` of ``u^i v^j`` (cached per map).

    Coefficient-major: gathering the cells of a point cloud gives the ``(16, n)`` array the
    Horner schemes run on without a transposing copy.
    """
    key = id(bathy)
    table = _TABLES.get(key)
    if table is not None:
        return table
    ny, nx = bathy.shape
    if (ny - 1) * (nx - 1) * 128 > TABLE_MAX_BYTES:
        return None
    c = bathy.coefficients[PAD - 1 : PAD + ny + 1, PAD - 1 : PAD + nx + 1]  # nodes -1 .. n
    # contract the x stencil (a) then the y stencil (b): separable, 16 + 64 whole-grid passes
    tmp = np.empty((ny + 2, nx - 1))
    ci = [_stencil_sum(_M[:, i], [c[:, a : a + nx - 1] for a in range(4)],
                       np.empty((ny + 2, nx - 1)), tmp) for i in range(4)]
    table = np.empty((4, 4, ny - 1, nx - 1))
    for i in range(4):
        for j in range(4):
            _stencil_sum(_M[:, j], [ci[i][b : b + ny - 1, :] for b in range(4)], table[i, j],
                         tmp[: ny - 1])
    table = table.reshape(16, (ny - 1) * (nx - 1))
    _TABLES[key] = table
    weakref.finalize(bathy, _TABLES.pop, key, None)
    return table


class FastTerrain:
    """``h_d(x, y)`` of a :class:`Bathymetry`, vectorized over points, equal to its spline."""

    def __init__(self, bathy: Bathymetry) -> None:
        self.bathy = bathy
        ny, nx = bathy.shape
        self._nx, self._ny = nx, ny
        self._idx, self._idy = 1.0 / bathy.dx, 1.0 / bathy.dy
        self._origin = np.array([[bathy.x0], [bathy.y0]])
        self._x0, self._y0 = (float(v) for v in self._origin[:, 0])
        self._inv_spacing = np.array([[self._idx], [self._idy]])
        self._upper = np.array([[nx - 1.0], [ny - 1.0]])
        self._last_cell = np.array([[nx - 2], [ny - 2]], dtype=np.intp)
        self._table = _poly_table(bathy)
        self._last: tuple = (None, None)  # ((x, y), point(x, y)): an EKF asks h, then H

    def _cells(self, xy: np.ndarray):
        """Polynomial coefficients ``C[i, j, n]`` of the cells and the local ``(u, v)``."""
        uv = xy - self._origin  # (2, n): grid coordinates of the points
        uv *= self._inv_spacing
        np.maximum(uv, 0.0, out=uv)
        np.minimum(uv, self._upper, out=uv)
        ij = uv.astype(np.intp)
        np.minimum(ij, self._last_cell, out=ij)
        uv -= ij  # fractions within the cell
        cell = ij[1] * (self._nx - 1)
        cell += ij[0]
        C = self._table.take(cell, axis=1).reshape(4, 4, -1)
        return C, uv[0], uv[1]

    def depth_xy(self, xy: np.ndarray) -> np.ndarray:
        """Depth at points given as a ``(2, n)`` array of ``[x; y]`` rows."""
        if self._table is None:
            return self.bathy.depth(xy[0], xy[1])
        C, u, v = self._cells(xy)
        uu = np.empty_like(C[0])  # u on every row: same-shape products cost half a broadcast
        uu[:] = u
        q = C[3] * uu  # Horner in u: q_j = sum_i c_ij u^i
        q += C[2]
        q *= uu
        q += C[1]
        q *= uu
        q += C[0]
        h = q[3] * v  # Horner in v
        h += q[2]
        h *= v
        h += q[1]
        h *= v
        h += q[0]
        return h

    def depth_rows(self, X: np.ndarray, out: np.ndarray) -> None:
        """``out[n] = h_d(X[n, 0], X[n, 1])`` for the rows of a state array ``X`` (``(N, nx)``):
        the compiled lookup when Numba is loaded (the same bits), else :meth:`depth_xy`."""
        k = _kernels() if self._table is not None and X.dtype == np.float64 else None
        if k is None:
            out[:] = self.depth_xy(X.T[:2])
            return
        k.depth_rows(self._table, X, self._x0, self._y0, self._idx, self._idy, self._nx,
                     self._ny, out)

    def surface(self) -> tuple[Surface, np.ndarray] | None:
        """The map as a table surface of :mod:`uwcosim.core.bicubic` (its geometry and the
        polynomial table), None for a map too large for the table."""
        if self._table is None:
            return None
        return Surface(self._x0, self._y0, self._idx, self._idy, self._nx, self._ny), self._table

    def depth(self, x, y) -> np.ndarray:
        """Depth at the points (the value at the nearest edge outside the grid)."""
        h = self.depth_xy(np.array([np.atleast_1d(x), np.atleast_1d(y)], dtype=float))
        return h if np.ndim(x) else h[0]

    def point(self, x: float, y: float) -> tuple[float, float, float]:
        """``(h_d, dh_d/dx, dh_d/dy)`` at one point, in plain floats (no array overhead)."""
        x, y = float(x), float(y)
        key, out = self._last
        if key is not None and key[0] == x and key[1] == y:
            return out
        k = _kernels() if self._table is not None else None
        if k is None:
            out = self._point(x, y)
        else:  # the same operations compiled
            out = k.point(self._table, x, y, self._x0, self._y0, self._idx, self._idy,
                          self._nx, self._ny)
        self._last = ((x, y), out)
        return out

    def _point(self, x: float, y: float) -> tuple[float, float, float]:
        if self._table is None:
            h, gx, gy = self.bathy.gradient(np.array([x]), np.array([y]))
            return float(h[0]), float(gx[0]), float(gy[0])
        nx, ny = self._nx, self._ny
        u = (x - self.bathy.x0) * self._idx
        v = (y - self.bathy.y0) * self._idy
        flat_u, flat_v = not 0.0 <= u <= nx - 1.0, not 0.0 <= v <= ny - 1.0
        u = min(max(u, 0.0), nx - 1.0)
        v = min(max(v, 0.0), ny - 1.0)
        iu, iv = min(int(u), nx - 2), min(int(v), ny - 2)
        u -= iu
        v -= iv
        c = self._table[:, iv * (nx - 1) + iu].tolist()  # c[4 i + j]: u^i v^j
        q = [((c[12 + j] * u + c[8 + j]) * u + c[4 + j]) * u + c[j] for j in range(4)]
        dq = [(3.0 * c[12 + j] * u + 2.0 * c[8 + j]) * u + c[4 + j] for j in range(4)]
        h = ((q[3] * v + q[2]) * v + q[1]) * v + q[0]
        hu = 0.0 if flat_u else (((dq[3] * v + dq[2]) * v + dq[1]) * v + dq[0]) * self._idx
        hv = 0.0 if flat_v else ((3.0 * q[3] * v + 2.0 * q[2]) * v + q[1]) * self._idy
        return h, hu, hv

    def gradient(self, x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(h_d, dh_d/dx, dh_d/dy)`` at the points.

        Outside the grid the clamped depth is flat across the edge and its derivative there is
        zero (CasADi's ``bspline`` extrapolates instead; the truth FMU stops at the edge).
        """
        if self._table is None:
            return self.bathy.gradient(x, y)
        xy = np.array([np.atleast_1d(x), np.atleast_1d(y)], dtype=float)
        uv = (xy - self._origin) * self._inv_spacing
        flat = (uv < 0.0) | (uv > self._upper)
        C, u, v = self._cells(xy)
        q = ((C[3] * u + C[2]) * u + C[1]) * u + C[0]
        dq = (3.0 * C[3] * u + 2.0 * C[2]) * u + C[1]  # d q_j / du
        h = ((q[3] * v + q[2]) * v + q[1]) * v + q[0]
        hu = ((dq[3] * v + dq[2]) * v + dq[1]) * v + dq[0]
        hv = (3.0 * q[3] * v + 2.0 * q[2]) * v + q[1]
        out = (h, np.where(flat[0], 0.0, hu * self._idx), np.where(flat[1], 0.0, hv * self._idy))
        return out if np.ndim(x) else tuple(a[0] for a in out)


def control_jacobian(x, u, dt: float) -> np.ndarray:
    """``J = d x'/d(psi, a)`` (4 x 2) of the exact step at ``(x, u)``, noise-free.

    ``p' = p + dt Rot v + dt^2/2 a [cos 2psi, sin 2psi]``, ``v' = v + dt a [cos psi, sin psi]``.
    """
    psi, a, dt = float(u[0]), float(u[1]), float(dt)
    vx, vy = float(x[2]), float(x[3])
    c, s = math.cos(psi), math.sin(psi)
    c2, s2 = c * c - s * s, 2.0 * s * c
    h2 = 0.5 * dt * dt
    return np.array([[dt * (-s * vx - c * vy) - 2.0 * h2 * a * s2, h2 * c2],
                     [dt * (c * vx - s * vy) + 2.0 * h2 * a * c2, h2 * s2],
                     [-dt * a * s, dt * c],
                     [dt * a * c, dt * s]])


class TANModel:
    """The TAN model in closed form (numpy), built by :func:`tan_model`; same protocol as
    :class:`~uwcosim.models.casadi_model.CasadiModel`, which it carries as ``symbolic``."""

    linear = False
    Q_depends_on_x = False  # Q = G diag(psd/dt) G' depends on (u, dt) only (no control noise)

    def __init__(self, base: CasadiModel, dvl_only: bool = False) -> None:
        """``dvl_only``: measure the two DVL rows of ``base`` only (:meth:`without_terrain`)."""
        self.symbolic = base  # the same model as CasADi expressions (grid filters use them)
        self.nx, self.nu, self.nw, self.nz = base.nx, base.nu, base.nw, base.nz
        self.state_names = base.state_names
        self.measurement_names = base.measurement_names
        self.q_psd = base.q_psd
        #: PSDs of the noise on (psi, a) the filters know, or None (module docstring)
        self.control_psd = base.control_psd
        if self.control_psd is not None:
            self.Q_depends_on_x = True  # the heading noise enters through Rot'(psi) v
        self.R = base.R
        self.terrain = getattr(base, "terrain", None)
        if dvl_only:
            self.nz, self.measurement_names = 2, tuple(base.measurement_names[:2])
            self.R = np.asarray(base.R)[:2, :2].copy()
            self.terrain = None
        self._fast_terrain = FastTerrain(self.terrain) if self.terrain is not None else None
        self._H0 = np.zeros((self.nz, 4))  # the constant rows of H (DVL: the velocities)
        self._H0[0, 2] = self._H0[1, 3] = 1.0
        self._key: tuple | None = None
        self._sqrt_dt: float | None = None

    def without_terrain(self) -> TANModel:
        """The same model measuring the DVL velocities only (``nz = 2``, the depth row and the
        terrain dropped): for a filter that uses only them (dead reckoning), which then does no
        terrain lookup. The same numbers in its rows of ``h``, ``H`` and ``R``."""
        return TANModel(self.symbolic, dvl_only=True)

    def _mats(self, u, dt: float) -> list:
        """``[F, G, b, Q, Q_factor]`` for ``(u, dt)``; the last two are filled on demand."""
        psi, a, dt = float(u[0]), float(u[1]), float(dt)
        key = (psi, a, dt)
        if key != self._key:
            c, s = math.cos(psi), math.sin(psi)
            h2 = 0.5 * dt * dt
            F = np.array([[1.0, 0.0, dt * c, -dt * s], [0.0, 1.0, dt * s, dt * c],
                          [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
            G = np.array([[dt, 0.0, h2 * c, -h2 * s], [0.0, dt, h2 * s, h2 * c],
                          [0.0, 0.0, dt, 0.0], [0.0, 0.0, 0.0, dt]])
            # b = [dt^2/2 Rot a e, dt a e], Rot e = [cos 2psi, sin 2psi]
            b = np.array([h2 * a * (c * c - s * s), h2 * a * 2.0 * s * c, dt * a * c, dt * a * s])
            self._key, self._cache = key, [F, G, b, None, None]
        return self._cache

    def _Q(self, u, dt: float) -> np.ndarray:
        m = self._mats(u, dt)
        if m[3] is None:
            G = m[1]
            Q = (G * (self.q_psd / float(dt))) @ G.T  # Q = G diag(psd/dt) G'
            m[3] = 0.5 * (Q + Q.T)
        return m[3]

    def f(self, x, u, dt: float) -> np.ndarray:
        F, _, b, _, _ = self._mats(u, dt)
        return F @ np.asarray(x, dtype=float) + b

    def f_batch(self, X: np.ndarray, u, dt: float) -> np.ndarray:
        F, _, b, _, _ = self._mats(u, dt)
        out = F @ X.T
        out += b[:, None]
        return out.T  # column-major result: particle filters read states as columns

    def FG(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F, G, _, _, _ = self._mats(u, dt)
        return F.copy(), G.copy()

    def F(self, x, u, dt: float) -> np.ndarray:
        return self._mats(u, dt)[0].copy()

    def _control_factor(self, x, u, dt: float) -> np.ndarray:
        """``J diag(q_c/dt)^(1/2)``: the control noise's part of a factor of ``Q``."""
        return control_jacobian(x, u, dt) * np.sqrt(self.control_psd / float(dt))

    def Q(self, x, u, dt: float) -> np.ndarray:
        if self.control_psd is None:
            return self._Q(u, dt).copy()
        Lc = self._control_factor(x, u, dt)
        Q = self._Q(u, dt) + Lc @ Lc.T
        return 0.5 * (Q + Q.T)

    def Q_factor(self, x, u, dt: float) -> np.ndarray:
        """``L = G diag(psd/dt)^(1/2)`` with ``L L' = Q`` (read-only, cached per ``(u, dt)``):
        samples ``N(0, Q)`` without a Cholesky factorization. With control noise ``L`` is
        ``[G diag(psd/dt)^(1/2), J diag(q_c/dt)^(1/2)]`` (4 x 6), computed at ``x``."""
        if self.control_psd is not None:
            Lw = self.Q_factor_process(u, dt)
            return np.hstack([Lw, self._control_factor(x, u, dt)])
        return self.Q_factor_process(u, dt)

    def Q_factor_process(self, u, dt: float) -> np.ndarray:
        """The process noise's factor ``G diag(psd/dt)^(1/2)`` (cached per ``(u, dt)``)."""
        m = self._mats(u, dt)
        if m[4] is None:
            dt = float(dt)
            if dt != self._sqrt_dt:  # sqrt(psd/dt), for the usual constant step
                self._sqrt_dt, self._sqrt_psd = dt, np.sqrt(self.q_psd / dt)
            m[4] = m[1] * self._sqrt_psd
            m[4].flags.writeable = False
        return m[4]

    def FQ(self, x, u, dt: float) -> tuple[np.ndarray, np.ndarray]:
        return self._mats(u, dt)[0].copy(), self.Q(x, u, dt)

    def h(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if self._fast_terrain is None:
            return x[2:4].copy()
        x0, x1, x2, x3 = x.reshape(-1).tolist()
        return np.array([x2, x3, self._fast_terrain.point(x0, x1)[0]])

    def H(self, x) -> np.ndarray:
        H = self._H0.copy()
        if self._fast_terrain is not None:
            _, H[2, 0], H[2, 1] = self._fast_terrain.point(float(x[0]), float(x[1]))
        return H

    def h_rows(self, x, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(h(x)[idx], H(x)[idx])``, the terrain looked up only when its row is in ``idx``
        (dead reckoning uses the DVL rows only); the same numbers as ``h`` and ``H``."""
        if self._fast_terrain is not None and 2 in idx:
            return self.h(x)[idx], self.H(x)[idx]
        x = np.asarray(x, dtype=float)
        return x[2:4][idx], self._H0[idx]

    def compiled_form(self) -> CompiledForm | None:
        """The model for the compiled Kalman steps (:class:`~uwcosim.models.protocol.
        CompiledForm`): the compiled transition (:func:`uwcosim.core.kinematics.heading_step`,
        code ``HEADING``), the DVL rows and the terrain row as a table surface. None with control
        noise (``Q`` then depends on the state) or a map too large for the table."""
        if self.control_psd is not None:
            return None
        if self._fast_terrain is None:
            surface, table, row = Surface(0.0, 0.0, 1.0, 1.0, 2, 2), np.zeros((16, 1)), -1
        else:
            found = self._fast_terrain.surface()
            if found is None:
                return None
            (surface, table), row = found, 2
        H0 = self._H0.copy()
        psd = self.q_psd

        def transition(u, dt, F, b, Q):  # the compiled f and F of the step
            kinematics.heading_step(u, dt, psd, F, b, Q)

        return CompiledForm(transition, H0, row, (0, 1), surface, table, kinematics.HEADING,
                            tuple(float(v) for v in psd))

    def h_batch(self, X: np.ndarray) -> np.ndarray:
        out = np.empty((X.shape[0], self.nz), order="F")
        out[:, :2] = X[:, 2:4]
        if self._fast_terrain is not None:
            self._fast_terrain.depth_rows(X, out[:, 2])
        return out


def tan_model(
    q_psd,
    dvl_sigma,
    depth_sigma: float | None = None,
    terrain: Bathymetry | None = None,
    measurement_names: tuple[str, ...] | None = None,
    control_psd=None,
) -> TANModel:
    """TAN model; without ``terrain`` only the DVL is measured (dead-reckoning variant).
    ``control_psd``: PSDs of the noise on ``(psi, a)`` the filters know (None: none)."""
    x = ca.MX.sym("x", 4)
    rows = [x[2], x[3]]
    r = list(np.broadcast_to(np.asarray(dvl_sigma, dtype=float), (2,)) ** 2)
    names = list(DVL_NAMES)
    if terrain is not None:
        if depth_sigma is None:
            raise ValueError("depth_sigma is required with a terrain map")
        rows.append(terrain.casadi_function()(x[:2]))
        r.append(float(depth_sigma) ** 2)
        names.append(DEPTH_NAME)
    h = ca.Function("h", [x], [ca.vertcat(*rows)], ["x"], ["z"])
    symbolic = CasadiModel(
        vehicle_ode(), h, q_psd, np.array(r), STATE_NAMES,
        tuple(measurement_names) if measurement_names else tuple(names),
        control_psd=control_psd,
    )
    symbolic.terrain = terrain
    return TANModel(symbolic)
