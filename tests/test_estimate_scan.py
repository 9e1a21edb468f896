"""The estimator bank's scan of its estimates (uwcosim.run.scan): compiled and plain
Python give the same bits, the NEES is e' S^-1 e, and every failed check leaves NaN."""

import numpy as np
import pytest

from uwcosim.run import scan as es


def _batch(rng, k=5, n=4):
    A = rng.standard_normal((k, n, n))
    Ps = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(n)
    Ps *= rng.uniform(0.01, 100.0, size=(k, 1, 1))
    X = rng.uniform(-5.0, 5.0, size=(k, n))
    E = rng.standard_normal((k, n)) * 3.0
    return X, Ps, E, np.full(k, np.nan)


BOUND = (-10.0, 10.0, -10.0, 10.0)


def _py(X, Ps, E, nis, monkeypatch):
    """The plain-Python path (Numba not loaded)."""
    import sys

    with monkeypatch.context() as m:
        m.delitem(sys.modules, "numba", raising=False)
        return es.scan_estimates(X, Ps, E, nis, (0, 1), BOUND)


def _compiled(X, Ps, E, nis):
    pytest.importorskip("numba")  # loaded: the compiled path
    from uwcosim.core import jit

    if not jit.ENABLED:
        pytest.skip("Numba disabled")
    return es.scan_estimates(X, Ps, E, nis, (0, 1), BOUND)


@pytest.mark.parametrize("n", [2, 4, 7], ids=lambda n: f"n{n}")
def test_nees_is_e_S_inverse_e_and_compiled_gives_the_same_bits(n, monkeypatch):
    rng = np.random.default_rng(n)
    for _ in range(20):
        X, Ps, E, nis = _batch(rng, n=n)
        ref = np.array([e @ np.linalg.solve(P, e) for e, P in zip(E, Ps, strict=True)])
        py = _py(X, Ps, E, nis, monkeypatch)
        np.testing.assert_allclose(py, ref, rtol=1e-10, atol=0)
        assert np.array_equal(_compiled(X, Ps, E, nis), py)


def test_each_failed_check_gives_nan_for_that_estimate_only(monkeypatch):
    rng = np.random.default_rng(1)
    X, Ps, E, nis = _batch(rng, k=7)
    X[0, 2] = np.nan  # non-finite estimate
    Ps[1, 0, 1] += 1e-3 * np.abs(Ps[1]).max()  # not symmetric
    Ps[2] = np.diag([1.0, -1.0, 1.0, 1.0])  # indefinite
    nis[3] = -1.0  # negative NIS
    X[4, 1] = 11.0  # outside the bound
    Ps[5] = 0.0  # zero covariance
    v = np.array([1.0, 1.0 - 1e-14, 0.0, 0.0])  # nearly singular: a pivot loses 14 digits
    Ps[6] = np.outer(v, v) * 1e6 + np.diag([0.0, 0.0, 1.0, 1.0]) + np.diag([1e-9, 0, 0, 0])
    for out in (_py(X, Ps, E, nis, monkeypatch), _compiled(X, Ps, E, nis)):
        assert np.isnan(out).all()
    X, Ps, E, nis = _batch(rng, k=3)
    for out in (_py(X, Ps, E, nis, monkeypatch), _compiled(X, Ps, E, nis)):
        assert np.isfinite(out).all() and (out >= 0).all()


def test_the_check_flags_the_estimates_the_numpy_checks_flag(monkeypatch):
    from uwcosim.run.divergence import DivergenceCheck

    rng = np.random.default_rng(3)
    check = DivergenceCheck((0, 1), BOUND)
    for _ in range(50):
        X, Ps, E, nis = _batch(rng, k=4)
        j = rng.integers(4)
        Ps[j] = rng.standard_normal((4, 4))  # most often not symmetric
        for out in (_py(X, Ps, E, nis, monkeypatch), _compiled(X, Ps, E, nis)):
            for i in range(4):
                assert np.isnan(out[i]) == bool(check(X[i], Ps[i], nis[i], 0.0))
