"""Master-owned randomness: named streams, noise scaling and measurement-loss models."""

from __future__ import annotations

import numpy as np
import pytest

from uwcosim.core.rng import stream
from uwcosim.master.sources import loss_drawer, noise_drawer
from uwcosim.master.system import BernoulliLoss, GilbertElliottLoss


def white_noise(rng, n_steps, psd, h):
    """Held white-noise samples ``[n_steps, n]`` of the master's noise sources, in one draw."""
    return noise_drawer(rng, psd, h)(0, n_steps)


def loss_mask(rng, n, spec):
    """The received mask of ``n`` samples of the master's loss models, in one draw."""
    return loss_drawer(rng, n, spec)(0, n)


def test_streams_are_reproducible_and_independent():
    a = stream(3, "noise:process").standard_normal(5)
    b = stream(3, "noise:process").standard_normal(5)
    c = stream(3, "loss:dvl").standard_normal(5)
    d = stream(4, "noise:process").standard_normal(5)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert not np.allclose(a, d)


def test_white_noise_variance_is_psd_over_step():
    x = white_noise(stream(0, "w"), 200_000, [0.5, 2.0], h=0.5)
    # variance psd/h: 1.0 and 4.0; the sample variance of 2e5 draws is within 1%
    np.testing.assert_allclose(x.var(axis=0), [1.0, 4.0], rtol=0.01)


@pytest.mark.parametrize("p", [0.0, 0.1, 0.5, 1.0])
def test_bernoulli_loss_rate(p):
    rec = loss_mask(stream(1, "loss"), 100_000, BernoulliLoss(model="bernoulli", p=p))
    # binomial standard deviation of the loss fraction is <= 0.0016: 0.01 is > 6 sigma
    assert abs((~rec).mean() - p) < 0.01


def test_gilbert_elliott_bursts():
    spec = GilbertElliottLoss(model="gilbert_elliott", p_good_to_bad=0.02, p_bad_to_good=0.2)
    rec = loss_mask(stream(2, "loss"), 200_000, spec)
    # stationary probability of the bad state: 0.02 / (0.02 + 0.2) = 0.0909
    assert abs((~rec).mean() - 0.0909) < 0.01
    # mean burst length 1 / p_bad_to_good = 5 samples
    lost = np.flatnonzero(~rec)
    starts = np.sum(np.diff(lost) > 1) + 1
    assert lost.size / starts == pytest.approx(5.0, rel=0.1)


def test_no_loss_model_receives_everything():
    assert loss_mask(stream(0, "x"), 10, None).all()
