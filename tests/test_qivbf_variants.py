"""QIVBF variants of issue 14: ``extrapolate = "isolated"`` (seed 001's Assumption 1) and the
``inflate_r`` correction by the Lagrange noise gain (ours, not in seed 001)."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.filters.base import ESTIMATORS
from uwcosim.filters.policies import Extrapolate, noise_gain
from uwcosim.models.linear import seed001_model


def test_noise_gain_of_one_step_after_three_is_19():
    assert noise_gain([1.0, 2.0, 3.0], 4.0) == pytest.approx(19.0)
    # two steps after: weights (3, -8, 6), 9 + 64 + 36
    assert noise_gain([1.0, 2.0, 3.0], 5.0) == pytest.approx(109.0)


@pytest.mark.parametrize("mode", ["runs", "isolated"])
def test_isolated_mode_extrapolates_only_after_three_receipts(mode):
    p = Extrapolate(1, mode)
    received = [True, True, True, False, False, True, True, True, False, True, False]
    filled = []
    for k, ok in enumerate(received):
        z = np.array([float(k * k)]) if ok else np.array([np.nan])
        z2, m2 = p(float(k), z, np.array([ok]))
        if not ok:
            filled.append(bool(m2[0]))
            if m2[0]:
                assert p.gain[0] > 1.0
    if mode == "runs":  # every loss once three values were received
        assert filled == [True, True, True, True]
    else:  # k=3 (after 0,1,2) and k=8 (after 5,6,7); not k=4 (a run) nor k=10 (one receipt)
        assert filled == [True, False, True, False]
    with pytest.raises(ValueError, match="extrapolate must be one of runs, isolated"):
        Extrapolate(1, "all")


def test_inflate_r_divides_the_extrapolated_rows_by_the_gain():
    """An extrapolated value with R inflated by g = 19 moves the state less than with R."""
    model = seed001_model()
    out = {}
    for inflate in (False, True):
        est = ESTIMATORS.get("qivbf").from_settings(
            model, np.zeros(4), np.eye(4), {"inflate_r": inflate, "iterations": 1})
        for k in range(3):
            est.predict(None, 1.0)
            est.t = k + 1.0
            est.update(np.array([0.0, 0.0, 0.0, 0.0]))
        est.predict(None, 1.0)
        est.t = 4.0
        x_prior = est.x.copy()
        # last three received values 0, 0, 0 -> extrapolation 0; shift them to see the gain
        est.interpolator.history[0][2] = (3.0, 1.0)  # values 0, 0, 1 -> 0*1 - 3*0 + 3*1 = 3
        est.update(np.full(4, np.nan), np.zeros(4, dtype=bool))
        assert est.diagnostics["extrapolated"] == 4.0
        out[inflate] = est.x[0] - x_prior[0]
    assert 0 < out[True] < out[False] / 3
