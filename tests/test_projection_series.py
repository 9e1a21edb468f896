"""The series and the Galerkin matrix of PFM-PSI (:mod:`uwcosim.filters.projection.series`,
``prediction``) and Example 1 of seed 000 (eqs. 52-53)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.stats import multivariate_normal

from uwcosim.filters.projection import series as po
from uwcosim.filters.projection.prediction import galerkin_matrix
from uwcosim.verify.example1 import run_example1, solve

MEAN = np.array([0.5, 1.0])
COV = np.array([[2.0, 0.5], [0.5, 1.0]])


@pytest.fixture
def basis():
    return po.SpectralBasis([-10.0, -5.0], [20.0, 12.0], K=20, M=84)


def test_grid_roundtrip_and_gaussian(basis):
    m = po.gaussian_coefficients(MEAN, COV, basis)
    values = po.to_grid(m, basis)
    X, Y = np.meshgrid(*basis.axes(), indexing="ij")
    ref = multivariate_normal(MEAN, COV).pdf(np.stack([X, Y], axis=-1))
    assert np.max(np.abs(values - ref)) < 1e-8
    assert np.max(np.abs(po.from_grid(values, basis) - m)) < 1e-15
    assert po.mass(m, basis) == pytest.approx(1.0, abs=1e-12)
    sub = [basis.axes()[0][::5], basis.axes()[1][::7]]
    assert np.max(np.abs(po.evaluate(m, basis, sub) - ref[::5, ::7])) < 1e-8


def test_moments_exact_and_quadrature(basis):
    m = po.gaussian_coefficients(MEAN, COV, basis)
    mean, cov, mass = po.series_moments(m, basis)
    assert mass == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(mean, MEAN, atol=1e-6)
    np.testing.assert_allclose(cov, COV, atol=1e-6)
    mean, cov = po.grid_moments(po.to_grid(m, basis), basis)
    np.testing.assert_allclose(mean, MEAN, atol=1e-6)
    np.testing.assert_allclose(cov, COV, atol=1e-6)


def test_reprojection_is_exact(basis):
    m = po.gaussian_coefficients(MEAN, COV, basis)
    assert np.max(np.abs(po.reproject(m, basis, basis) - m)) < 1e-15
    new = basis.moved([-8.0, -6.0], [18.0, 14.0])
    moved = po.reproject(m, basis, new)
    assert np.max(np.abs(moved - po.gaussian_coefficients(MEAN, COV, new))) < 1e-9


def test_galerkin_constant_coefficients_is_diagonal_and_exact(basis):
    """Constant drift and diffusion: A is diagonal and exp(A t) is the exact FPE solution."""
    f = np.array([0.3, -0.2])
    B = np.array([[0.2, 0.05], [0.05, 0.1]])
    A = galerkin_matrix(
        basis,
        c1=[np.full(1, -f[0]), np.full(1, -f[1])],
        c2=[[np.full(1, B[r, s] / 2) for s in range(2)] for r in range(2)],
    )
    assert np.max(np.abs(A - np.diag(np.diag(A)))) < 1e-14
    m = po.gaussian_coefficients(MEAN, COV, basis)
    m1 = (expm(A) @ m.ravel()).reshape(m.shape)
    assert np.max(np.abs(m1 - po.gaussian_coefficients(MEAN + f, COV + B, basis))) < 1e-14
    assert np.max(np.abs(m * po.diffusion_decay(basis, B) - po.gaussian_coefficients(
        MEAN, COV + B, basis))) < 1e-15


def test_galerkin_ornstein_uhlenbeck_1d():
    """dx = -x dt + dW: the Galerkin solution keeps a Gaussian with the exact moments."""
    basis = po.SpectralBasis([-12.0], [24.0], K=40, M=256)
    x = basis.axes()[0]
    # L* p = 1/2 p'' + (x p)' = 1/2 p'' + x p' + p
    A = galerkin_matrix(basis, c0=np.ones_like(x), c1=[x], c2=[[np.full(1, 0.5)]])
    m = po.gaussian_coefficients([2.0], [[0.5]], basis)
    t = 0.7
    m = expm(A * t) @ m
    mean, cov, _ = po.series_moments(m, basis)
    assert mean[0] == pytest.approx(2.0 * np.exp(-t), abs=1e-8)
    assert cov[0, 0] == pytest.approx(0.5 * np.exp(-2 * t) + 0.5 * (1 - np.exp(-2 * t)), abs=1e-8)


def test_example1_spectral_accuracy():
    """Seed 000 Example 1: max error <= 1e-10 on [-5, 5], t = 1..10 s, with <= 65 functions."""
    for K in (16, 32):
        run = solve(K)
        assert run.n_basis <= 65
        err = np.abs(run.errors()[1:]).max()
        assert err <= 1e-10, (K, err)
    coarse = np.abs(solve(4).errors()[1:]).max()
    assert coarse > 1e-3  # the error does come from the truncation


def test_run_example1_table_and_figures(tmp_path, capsys):
    result = run_example1(tmp_path, Ks=(4, 8), echo=True)
    out = capsys.readouterr().out
    assert "K=4" in out and "K=8" in out
    assert result.max_error.shape == (10, 2)
    assert np.all(result.max_error[:, 1] < result.max_error[:, 0])
    assert len(result.figures) == 3 and all(p.is_file() for p in result.figures)


def test_transfer_matrices_equal_the_one_dimensional_form():
    """The batched re-projection equals :func:`transfer_matrix` of each dimension."""
    lo, length = np.array([-3.0, 10.0]), np.array([8.0, 5.0])
    lo2, length2 = np.array([-2.0, 9.0]), np.array([6.5, 7.0])
    batched = po.transfer_matrices(4, lo, length, lo2, length2)
    for d in range(2):
        one = po.transfer_matrix(4, lo[d], length[d], lo2[d], length2[d])
        np.testing.assert_allclose(batched[d], one, rtol=0, atol=1e-13)
