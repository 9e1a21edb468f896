"""The chi-square gate (``gate_probability``, :mod:`uwcosim.filters.gating`) of ``vbakf`` and
``qivbf``: on ``S = H P H' + E[R]``, a rejected component is a lost one (for ``qivbf``:
extrapolated, and kept out of the extrapolation's history)."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.filters import variational  # noqa: F401  (register)
from uwcosim.filters.base import ESTIMATORS
from uwcosim.models.linear import seed001_model

X0 = np.array([0.0, 1.0, 0.0, 0.5])


def make(kind, **settings):
    return ESTIMATORS.get(kind)(seed001_model(), X0.copy(), np.eye(4), **settings)


def innovation_std(est, i):
    """``sqrt(S_ii)`` with the filter's ``E[R]`` (H = I)."""
    return float(np.sqrt(est.P[i, i] + est.R_hat[i, i]))


def warm(est, steps=4):
    """A few updates with noise-free readings of the prior mean (three receipts for qivbf)."""
    for k in range(steps):
        est.predict(None, 1.0)
        est.t = k + 1.0
        est.update(est.model.h(est.x))


@pytest.mark.parametrize("kind", ["vbakf", "qivbf"])
def test_the_gate_rejects_a_10_sigma_outlier_and_keeps_the_rest(kind):
    f, ref = make(kind, gate_probability=0.9999), make(kind)
    for est in (f, ref):
        warm(est)
        est.predict(None, 1.0)
        est.t = 5.0
    z = f.model.h(f.x)
    z[2] += 10.0 * innovation_std(f, 2)
    f.update(z)
    assert f.diagnostics["gated"] == 1.0
    if kind == "vbakf":  # the same filter updated without that component
        ref.update(z, mask=np.array([True, True, False, True]))
    else:  # qivbf: the rejected component is lost, hence extrapolated
        assert f.diagnostics["extrapolated"] == 1.0
        z_ref = z.copy()
        z_ref[2] = np.nan
        ref.update(z_ref)
    np.testing.assert_array_equal(f.x, ref.x)
    np.testing.assert_array_equal(f.U, ref.U)
    g = make(kind, gate_probability=0.9999)  # a 1-sigma reading passes
    warm(g)
    g.predict(None, 1.0)
    g.t = 5.0
    z = g.model.h(g.x) + np.array([1.0, -1.0, 1.0, -1.0]) * np.sqrt(np.diag(g.P) + 1.0)
    g.update(z)
    assert g.diagnostics["gated"] == 0.0


def test_the_gate_uses_the_estimated_R():
    # E[R] = 25 R: a reading 8 nominal sigma off is 1.7 sigma off with the learned R and passes
    f = make("vbakf", gate_probability=0.9999)
    f.predict(None, 1.0)
    nominal = float(np.sqrt(f.P[0, 0] + f.model.R[0, 0]))
    f.U = 25.0 * f.U
    z = f.model.h(f.x)
    z[0] += 8.0 * nominal
    assert (8.0 * nominal) ** 2 / innovation_std(f, 0) ** 2 < 15.1
    f.update(z)
    assert f.diagnostics["gated"] == 0.0


def test_qivbf_keeps_a_gated_value_out_of_the_extrapolation_history():
    f = make("qivbf", gate_probability=0.9999)
    warm(f, 3)
    f.predict(None, 1.0)
    f.t = 4.0
    z = f.model.h(f.x)
    z[1] += 10.0 * innovation_std(f, 1)
    f.update(z)
    assert f.diagnostics["gated"] == 1.0
    assert [t for t, _ in f.interpolator.history[1]] == [1.0, 2.0, 3.0]
    assert [t for t, _ in f.interpolator.history[0]] == [2.0, 3.0, 4.0]


@pytest.mark.parametrize("kind", ["vbakf", "qivbf"])
def test_without_the_gate_the_outlier_is_used(kind):
    # the VB update takes it, and adapts E[R] to it (so the state moves little)
    f, ref = make(kind), make("vbakf")
    for est in (f, ref):
        warm(est)
        est.predict(None, 1.0)
        est.t = 5.0
    z = f.model.h(f.x)
    z[0] += 100.0
    f.update(z)
    ref.update(z, mask=np.array([False, True, True, True]))
    assert "gated" not in f.diagnostics
    assert f.x[0] - ref.x[0] > 0.01
    assert f.R_hat[0, 0] > 100.0 * ref.R_hat[0, 0]


@pytest.mark.parametrize("kind", ["vbakf", "qivbf"])
def test_gate_probability_is_checked(kind):
    cls = ESTIMATORS.get(kind)
    with pytest.raises(ScenarioError, match="gate_probability"):
        cls.from_settings(seed001_model(), X0, np.eye(4), {"gate_probability": 1.5},
                          where="s.toml")
