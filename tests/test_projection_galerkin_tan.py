"""The projection filter's general (Galerkin + matrix exponential) prediction on a TAN-like model.

In Table 1 the position drift (the rotated velocity) does not depend on the gridded position,
so PFM-PSI only uses its exact translation-and-blur prediction. Here an along-track terrain
navigation model grids position *and* speed, ``(x, v)``: ``x' = v + w_x``, ``v' = a + w_v``,
measured by a DVL (``v``) and a depth sounder over a terrain profile ``h(x)``; the drift ``v`` of
``x`` depends on a gridded state, so the prediction goes through the Galerkin matrix with the
drift term ``c1`` (issue 14). After two Bayes updates (a non-Gaussian posterior), one PFM-PSI
prediction is compared with the exact transport of the *same* density on a fine grid (301 x 301
points): shear ``(x, v) -> (x + dt v + dt^2 a / 2, v + dt a)`` (cubic interpolation), then the
Fokker-Planck diffusion over ``dt`` (white noise: ``Q = [[q_x dt + q_v dt^3/3, q_v dt^2/2],
[q_v dt^2/2, q_v dt]]``, FFT convolution).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy import ndimage

from tests.grid_reference import gaussian_convolve
from uwcosim.evaluation.distance import hellinger
from uwcosim.filters.grid.partition import Partition
from uwcosim.filters.projection.filter import ProjectionFilter
from uwcosim.models.auv_equations import STATE_NAMES
from uwcosim.models.casadi_model import CasadiModel

QX, QV, A, DT = 0.05, 0.02, 0.1, 2.0


def along_track_model():
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    w = ca.SX.sym("w", 2)
    ode = ca.Function("ode", [x, u, w], [ca.vertcat(x[1] + w[0], u[0] + w[1])])
    xm = ca.MX.sym("x", 2)
    h = ca.Function("h", [xm], [ca.vertcat(xm[1], 10.0 * ca.sin(xm[0] / 6.0))])
    model = CasadiModel(ode, h, [QX, QV], [0.5**2, 1.0], ("x", "v"), ("dvl.v_m", "depth"))
    model.ode = ode
    return model


def exact_prediction(p0, axes0, axes1, shear: bool = True):
    """Transport of the grid density ``p0`` over one step onto ``axes1`` (see module)."""
    X1, V1 = np.meshgrid(*axes1, indexing="ij")
    V0 = V1 - A * DT
    X0 = X1 - DT * (V0 if shear else np.mean(V0)) - 0.5 * A * DT**2
    sp0 = [a[1] - a[0] for a in axes0]
    coords = [(X0 - axes0[0][0]) / sp0[0], (V0 - axes0[1][0]) / sp0[1]]
    moved = ndimage.map_coordinates(p0, coords, order=3, mode="constant", cval=0.0)
    Q = np.array([[QX * DT + QV * DT**3 / 3, QV * DT**2 / 2], [QV * DT**2 / 2, QV * DT]])
    sp1 = [a[1] - a[0] for a in axes1]
    return np.maximum(gaussian_convolve(moved, sp1, Q), 0.0)


def predicted_distance(K: int):
    """Hellinger distances of PFM-PSI's prediction and of a shear-free prediction to the exact
    transport, and the filter."""
    model = along_track_model()
    pf = ProjectionFilter(model, [0.0, 1.0], np.diag([4.0**2, 1.0**2]), K=K,
                          states=["x", "v"], resolution_inflation=0.0)
    assert not pf.part.drift_constant and pf.part.k == []
    for z in ([1.3, 6.0], [1.5, -2.0]):  # a skewed, two-lobed posterior
        pf.predict(np.array([A]), DT)
        pf.update(np.array(z))
    lo, hi = pf.basis.lo, pf.basis.lo + pf.basis.length
    axes0 = [np.linspace(lo[d], hi[d], 301) for d in range(2)]
    p0 = pf.density_grid(axes0, clip=False)[1]
    mean = pf.x.copy()
    pf.predict(np.array([A]), DT)  # Galerkin matrix with the drift term, expm
    shift = np.array([DT * mean[1] + 0.5 * A * DT**2, A * DT])
    axes1 = [a + s for a, s in zip(axes0, shift, strict=True)]
    ref = exact_prediction(p0, axes0, axes1)
    got = pf.density_grid(axes1, clip=False)[1]
    wrong = exact_prediction(p0, axes0, axes1, shear=False)
    return hellinger(got, ref), hellinger(wrong, ref), pf, mean + shift


def test_galerkin_prediction_converges_to_exact_transport():
    d8, _, _, _ = predicted_distance(8)
    d12, wrong, pf, mean = predicted_distance(12)
    assert d12 < 0.5 * d8 and d12 < 0.08, (d8, d12)  # measured 0.15, 0.057 (K = 16: 0.020)
    assert wrong > 5 * d12, (d12, wrong)  # the drift coupling matters at this scale (0.65)
    # the predicted mean follows the linear map: E[x'] = E[x] + dt E[v] + dt^2 a / 2
    np.testing.assert_allclose((pf.x - mean) / np.sqrt(np.diag(pf.P)), 0.0, atol=0.05)


def test_noisy_controls_keep_the_tan_position_drift_constant():
    """Noisy heading and acceleration (seed 000 Fig. 6: "control vector with noise") make the
    position diffusion depend on the velocity, not on the position: with the gridded position
    (x, y) PFM-PSI stays on its constant-drift path. The automatic split makes the same choice:
    only the velocity block's own noise B[k, k] (state-independent) must not depend on the state,
    the velocity-dependent position diffusion does not stop (vx, vy) from being Kalman states."""
    x = ca.SX.sym("x", 4)
    u = ca.SX.sym("u", 2)
    w = ca.SX.sym("w", 6)  # w_x, w_y, w_vx, w_vy, w_psi, w_a
    psi, a = u[0] + w[4], u[1] + w[5]
    c, s = ca.cos(psi), ca.sin(psi)
    xdot = ca.vertcat(x[2] * c - x[3] * s + w[0], x[3] * c + x[2] * s + w[1],
                      a * c + w[2], a * s + w[3])
    ode = ca.Function("ode", [x, u, w], [xdot])
    xm = ca.MX.sym("x", 4)
    h = ca.Function("h", [xm], [ca.vertcat(xm[2], xm[3], ca.sin(xm[0] / 100) * xm[1] / 100)])
    model = CasadiModel(ode, h, [0.05, 0.05, 1e-5, 1e-5, 1e-4, 1e-6], [0.05**2] * 2 + [1.0],
                        STATE_NAMES, ("vx", "vy", "depth"))
    model.ode = ode
    part = Partition(model, states=["x", "y"])
    assert part.drift_constant and part.diffusion_constant  # B depends on (vx, vy) only
    auto = Partition(model)
    assert (auto.p, auto.k) == ([0, 1], [2, 3]) and auto.drift_constant
