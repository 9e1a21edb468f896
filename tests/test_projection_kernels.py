"""Compiled kernels (Numba) of the projection and point-mass filters against the numpy forms.

The numpy forms are the reference (and the fallback without Numba): each kernel, and each
filter run with its compiled forms (``fast``) and with its numpy forms (``use_kernels`` off),
must agree to round-off.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from uwcosim.core import jit
from uwcosim.core.reductions import neg_sum2
from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.grid import partition
from uwcosim.filters.grid.likelihood import TerrainGrid, terrain_depth
from uwcosim.filters.point_mass import prediction as pm
from uwcosim.filters.point_mass import prediction_kernels as pmk
from uwcosim.filters.projection import bayes_kernels as bk
from uwcosim.filters.projection import prediction_kernels as prk
from uwcosim.filters.projection import series as po
from uwcosim.filters.projection import series_kernels as sk
from uwcosim.models.tan import tan_model
from uwcosim.models.terrain import synthetic_bathymetry

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="Numba not installed or disabled")

START = np.array([3000.0, 16000.0, 0.5, 0.0])


@pytest.fixture(scope="module")
def terrain():
    return synthetic_bathymetry(3)


def _basis(L=240.0, K=10, M=64):
    return po.SpectralBasis(np.array([3000.0, 16000.0]), np.array([L, 0.8 * L]), K, M)


def _series(basis):
    mean = basis.lo + np.array([0.45, 0.55]) * basis.length
    return po.gaussian_coefficients(mean, np.array([[300.0, 50.0], [50.0, 200.0]]), basis)


@pytest.mark.parametrize("K,M", [(10, 64), (4, 18), (7, 32)])
def test_grid_transforms_match_numpy(K, M):
    basis = _basis(K=K, M=M)
    m = _series(basis)
    tables = tuple(sk.folded_tables(K, M))
    sv = basis.sqrt_volume()
    values = po.to_grid(m, basis)
    fast = sk.to_grid2(m, tables, 1.0 / sv)
    assert np.max(np.abs(fast - values)) <= 1e-12 * np.max(np.abs(values))
    g = np.abs(values) * np.random.default_rng(0).random(values.shape)
    ref = po.from_grid(g, basis)
    out = sk.from_grid2(g, tables, sv / M**2)
    assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("L", [60.0, 240.0, 3000.0])
def test_terrain_depth_matches_grid_evaluation(terrain, L):
    tg = TerrainGrid(terrain)
    ax = _basis(L=L).axes()
    ref = tg.depth(ax[0], ax[1])
    out = terrain_depth(ax[0], ax[1], tuple(tg.map))
    assert np.max(np.abs(out - ref)) < 1e-9


@pytest.mark.parametrize("var,inflation", [(4.0, 1.0), (4.0, 0.0), (1e31, 1.0), (1e-31, 0.0)])
def test_bayes_terms_match_numpy(terrain, var, inflation):
    """Prior values, ``W``, ``S = 1 / sqrt(V)`` and ``vmin`` of :func:`bayes_terms` against
    the numpy forms; ``var = 1e31`` puts ``V`` outside the single-precision path's range (the
    rows in double precision), ``1e-31`` (no inflation) the uniform-variance branch."""
    basis = _basis(L=240.0)
    m = _series(basis)
    tables = tuple(sk.folded_tables(basis.K, basis.M))
    tg = TerrainGrid(terrain)
    terrain_map = tuple(tg.map)
    M = basis.M
    values, W, S = np.empty((M, M)), np.empty((M, M)), np.empty((M, M))
    ax = basis.axes()
    h = tg.depth(ax[0], ax[1])
    assert np.max(np.abs(h - terrain_depth(ax[0], ax[1], terrain_map))) < 1e-9
    h = terrain_depth(ax[0], ax[1], terrain_map)  # the same depths below
    z = float(h[20, 30]) + 1.0
    neg, tmax, vmin = bk.bayes_terms((m, basis.lo, basis.length), tables, terrain_map, z, var,
                                     inflation, (values, W, S), True)
    ref_values = po.to_grid(m, basis)
    assert np.allclose(values, ref_values, rtol=0, atol=1e-12 * np.abs(ref_values).max())
    cell = np.prod(basis.length / M)
    assert neg == pytest.approx(-np.minimum(ref_values, 0).sum() * cell, rel=1e-12, abs=1e-15)
    V = np.full((M, M), var)
    if inflation:
        for d in range(2):  # twice the central differences, one-sided ones doubled
            g = 2.0 * np.gradient(h, axis=d)
            res = inflation * basis.length[d] / (2 * basis.K + 1)
            V = V + g**2 * (res / (2.0 * basis.length[d] / M)) ** 2 / 12.0
    assert vmin == pytest.approx(V.min(), rel=1e-15)
    np.testing.assert_allclose(S, 1.0 / np.sqrt(V), rtol=1e-15, atol=0)
    ll = -0.5 * (h - z) ** 2 / V
    assert tmax == pytest.approx(ll.max(), rel=1e-14)
    assert W.max() == 0.0
    np.testing.assert_allclose(W + tmax, ll, rtol=1e-13, atol=1e-13 * np.abs(ll).max())


@pytest.mark.parametrize("M", [54, 64, 18])
def test_posterior_moments_and_negative_mass_match_numpy(M):
    """:func:`bayes_posterior`'s mass and moments (cross term summed by columns) and the
    column-wise negative mass (``neg_sum2``) against the numpy forms."""
    rng = np.random.default_rng(M)
    basis = _basis(K=4, M=M)
    values = po.to_grid(_series(basis), basis) + 1e-7 * rng.standard_normal((M, M))
    E = rng.random((M, M))
    S = 0.5 + rng.random((M, M))
    vmin = 0.7
    post, Z, mean, cov, status = bk.bayes_posterior((values, E, S), vmin, basis.lo,
                                                    basis.length)
    ref = values * E * np.sqrt(vmin) * S
    np.testing.assert_allclose(post, ref, rtol=1e-15, atol=0)
    cell = np.prod(basis.length / M)
    assert status == 0
    assert Z == pytest.approx(ref.sum() * cell, rel=1e-13)
    xs, ys = basis.axes()
    w = ref / ref.sum()
    mx, my = (w.sum(1) @ xs), (w.sum(0) @ ys)
    d0, d1 = xs - mx, ys - my
    ref_cov = np.array([[w.sum(1) @ d0**2, d0 @ w @ d1], [d0 @ w @ d1, w.sum(0) @ d1**2]])
    np.testing.assert_allclose(mean, [mx, my], rtol=1e-14, atol=0)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-11, atol=1e-12 * np.abs(ref_cov).max())
    assert neg_sum2(values) == pytest.approx(np.minimum(values, 0).sum(), rel=1e-13, abs=1e-300)


def test_shift_decay_matches_reprojection_and_decay():
    basis = _basis()
    m = _series(basis)
    new = basis.moved(basis.lo + [5.0, -3.0], basis.length * 0.9)
    D = np.array([[2.0, 0.3], [0.3, 1.5]])
    mats = po.transfer_matrices(basis.K, basis.lo, basis.length, new.lo, new.length)
    ref = po.contract(m, list(mats)) * po.diffusion_decay(new, D)
    out = sk.shift_decay((m, basis.lo, basis.length), (new.lo, new.length), D, True)
    assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))
    # disjoint boxes: nothing is carried over
    far = basis.moved(basis.lo + 10 * basis.length, basis.length)
    assert not np.any(sk.shift_decay((m, basis.lo, basis.length), (far.lo, far.length), D,
                                     False))


@pytest.mark.parametrize("K,shift,scale,D01", [
    (10, [5.0, -3.0], [1.3, 0.7], -0.4),  # one axis grows, the other shrinks
    (7, [230.0, -185.0], [1.0, 1.0], 0.9),  # boxes overlapping by a few metres
    (4, [0.0, 0.0], [0.02, 0.05], 0.0),  # much narrower boxes: many near-diagonal sinc terms
])
def test_shift_decay_any_series_and_boxes(K, shift, scale, D01):
    """The transfer split into real matrices and phases, for a random Hermitian series (the
    kernel computes the rows ``q0 >= 0`` and mirrors them) and boxes from nested to barely
    overlapping; ``D01 != 0`` runs the separated decay (a chain of products for the cross
    term)."""
    basis = _basis(K=K)
    rng = np.random.default_rng(K)
    m = rng.standard_normal(basis.shape) + 1j * rng.standard_normal(basis.shape)
    m = 0.5 * (m + np.conj(m[::-1, ::-1]))
    new = basis.moved(basis.lo + shift, basis.length * np.array(scale))
    D = np.array([[2.0, D01], [D01, 1.5]])
    mats = po.transfer_matrices(basis.K, basis.lo, basis.length, new.lo, new.length)
    ref = po.contract(m, list(mats)) * po.diffusion_decay(new, D)
    out = sk.shift_decay((m, basis.lo, basis.length), (new.lo, new.length), D, True)
    assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))


def test_shift_decay_large_exponents_use_the_direct_decay():
    """A singular diffusion ``D = d [[1, 1], [1, 1]]`` keeps the modes ``q0 = -q1``
    (``exp(-d (a + b)^2 / 2) = 1``) and kills the others; its separated factors would be
    ``exp(-d a^2 / 2) = 0`` times ``exp(-d a b) = inf`` (NaN). The kernel must see the large
    exponents and take ``exp(-quad)`` directly."""
    basis = _basis()
    square = basis.moved(basis.lo + 2.0, np.full(2, 200.0))  # a = -b exactly on q0 = -q1
    m = np.random.default_rng(0).standard_normal(basis.shape) + 0j  # all modes carry weight
    m = 0.5 * (m + m[::-1, ::-1])
    a_max = 2 * np.pi * basis.K / 200.0
    d = 2 * 700.0 / a_max**2  # exp(-d a^2 / 2) = exp(-700) at the highest mode, the cross
    D = d * np.ones((2, 2))  # exponent d a^2 = 1400: far beyond the separable limit (700)
    mats = po.transfer_matrices(basis.K, basis.lo, basis.length, square.lo, square.length)
    ref = po.contract(m, list(mats)) * po.diffusion_decay(square, D)
    out = sk.shift_decay((m, basis.lo, basis.length), (square.lo, square.length), D, True)
    assert np.all(np.isfinite(out))
    anti = np.fliplr(np.abs(ref)).diagonal()
    assert np.all(anti > 1e-3 * anti.max())  # the kept modes carry the series
    assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))


def test_predict_shift_normalizes_like_hermitian_normalize():
    """:func:`predict_shift`'s normalization folded into the re-projection equals the
    re-projection followed by ``hermitian_normalize`` (the centre row made Hermitian, divided
    by the mass)."""
    basis = _basis()
    m = _series(basis)
    mean = basis.lo + 0.5 * basis.length
    cov = np.array([[300.0, 50.0], [50.0, 200.0]])
    d, D = np.array([2.0, -1.5]), np.array([[2.0, 0.3], [0.3, 1.5]])
    out, lo2, len2, mean2, cov2, mass = prk.predict_shift((m, basis.lo, basis.length), mean,
                                                          cov, d, D, 4.0, 1.0)
    ref = sk.shift_decay((m, basis.lo + d, basis.length), (lo2, len2), D, True)
    ref_mass = sk.hermitian_normalize(ref, np.sqrt(np.prod(len2)))
    assert mass > 0 and abs(mass - ref_mass) <= 1e-13 * ref_mass
    assert np.max(np.abs(out - ref)) <= 1e-13 * np.max(np.abs(ref))
    assert np.array_equal(out, np.conj(out[::-1, ::-1]))  # exactly Hermitian


def test_spline_shift_matches_sparse_matrices():
    rng = np.random.default_rng(1)
    X = rng.random((56, 60))
    c0 = np.linspace(-2.0, 52.5, 50)  # some points outside the old 50 x 52 grid
    c1 = np.linspace(0.3, 51.0, 52)
    B0 = pm.spline_matrix(c0, 50, 56)
    ref = B0 @ X
    B1 = pm.spline_matrix(c1, 52, 60)
    ref = np.maximum((B1 @ ref.T).T, 0.0)
    out = pmk.spline_shift_2d(X, c0, c1, 50, 52)
    assert np.max(np.abs(out - ref)) < 1e-13


def test_available_bits():
    z = np.array([1.0, np.nan, 3.0, 4.0])
    for available in (partition.available_bits, partition.available_bits_numpy):
        assert available(z, np.ones(4, bool), np.array([1, 1, 1, 0], bool)) == 0b101
        assert available(z, np.array([0, 1, 1, 1], bool), np.ones(4, bool)) == 0b1100


def _trajectory(model, steps, seed=1):
    rng = np.random.default_rng(seed)
    x = START.copy()
    us, zs = [], []
    for k in range(steps):
        u = np.array([0.3 + 0.2 * np.sin(0.05 * k), 0.002])
        _, G = model.FG(x, u, 1.0)
        x = model.f(x, u, 1.0) + G @ (rng.standard_normal(4) * np.sqrt(model.q_psd))
        z = model.h(x) + rng.multivariate_normal(np.zeros(model.nz), model.R)
        if k % 7 == 3:
            z[2] = np.nan  # a lost depth measurement now and then
        us.append(u)
        zs.append(z)
    return us, zs


@pytest.mark.parametrize("name,settings,steps", [
    ("pfm_psi", {"K": 10}, 60),
    # thresholded every step: max(p - a, 0) amplifies round-off (~3x per step), so only the
    # first steps can agree to round-off
    ("pfm_psi", {"K": 6, "k_sigma": 10.0, "resolution_inflation": 0.0}, 10),
    ("point_mass", {"n_points": 61}, 60),
    # the Student-t likelihood (filters.robust): the compiled steps too
    ("pfm_psi", {"K": 10, "student_t_nu": 4.0}, 60),
    ("pfm_psi", {"K": 10, "student_t_nu": 4.0, "resolution_inflation": 0.0}, 60),
    ("point_mass", {"n_points": 61, "student_t_nu": 4.0}, 60),
])
def test_filters_same_with_and_without_kernels(terrain, name, settings, steps):
    model = tan_model([0.05, 0.05, 1e-4, 1e-4], 0.03, 2.0, terrain=terrain)
    us, zs = _trajectory(model, steps)
    P0 = np.diag([30.0**2, 30.0**2, 0.05**2, 0.05**2])
    x0 = START + np.array([20.0, -25.0, 0.02, -0.01])
    cls = ESTIMATORS.get(name)
    numpy_form = type(cls.__name__, (cls,), {"use_kernels": False})
    runs = []
    for fast in (True, False):
        est = (cls if fast else numpy_form).from_settings(model, x0, P0, settings)
        assert est.fast == fast  # the kernels apply to this model, unless turned off
        assert est.kalman.compiled == est.prediction.compiled == est.bayes.compiled == fast
        xs, Ps, diags = [], [], []
        for u, z in zip(us, zs, strict=True):
            est.predict(u, 1.0)
            est.update(z)
            xs.append(est.x.copy())
            Ps.append(est.P.copy())
            diags.append(dict(est.diagnostics))
        runs.append((np.array(xs), np.array(Ps), diags))
    (x1, P1, d1), (x2, P2, d2) = runs
    np.testing.assert_allclose(x1, x2, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(P1, P2, rtol=1e-7, atol=1e-12)
    for a, b in zip(d1, d2, strict=True):
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_allclose(a[key], b[key], rtol=1e-6, atol=1e-12, err_msg=key)


def test_environment_switch_disables_kernels():
    """``UWCOSIM_NUMBA=0``: no compiled kernels, and the grid filters run their numpy forms."""
    env = dict(os.environ, UWCOSIM_NUMBA="0")
    code = ("import numpy as np\n"
            "from uwcosim.core import jit\n"
            "from uwcosim.filters.base import ESTIMATORS\n"
            "from uwcosim.models.tan import tan_model\n"
            "from uwcosim.models.terrain import synthetic_bathymetry\n"
            "model = tan_model([0.05, 0.05, 1e-4, 1e-4], 0.03, 2.0, "
            "terrain=synthetic_bathymetry(3))\n"
            "x0, P0 = np.array([3000.0, 16000.0, 0.5, 0.0]), np.diag([900.0, 900.0, 1e-3, 1e-3])\n"
            "ests = [ESTIMATORS.get(k)(model, x0, P0) for k in ('pfm_psi', 'point_mass')]\n"
            "print(jit.ENABLED, *[e.fast for e in ests])")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False False False"


def test_interrupt_wrapped_by_a_kernel_is_recognized():
    def wrapped():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as inner:
            raise SystemError("returned a result with an exception set") from inner

    with pytest.raises(SystemError) as info:
        wrapped()
    assert jit.interrupted(info.value)
    assert not jit.interrupted(SystemError("other"))
    assert not jit.interrupted(ValueError("x"))


def test_bundles_as_named_tuples_or_plain_tuples(terrain):
    """A kernel takes a bundle as its NamedTuple or as the plain tuple of its fields (what the
    filters pass, :mod:`uwcosim.core.jit`): the same result."""
    tg = TerrainGrid(terrain)
    ax = _basis().axes()
    named = terrain_depth(ax[0], ax[1], tg.map)
    assert np.array_equal(named, terrain_depth(ax[0], ax[1], tuple(tg.map)))
    basis = _basis(K=4, M=18)
    m = _series(basis)
    tables = sk.folded_tables(basis.K, basis.M)
    assert np.array_equal(sk.to_grid2(m, tables, 0.5), sk.to_grid2(m, tuple(tables), 0.5))
