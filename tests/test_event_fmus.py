"""The event test FMUs (tests/data/event_fmus) checked with fmpy against closed forms.

These tests prove the FMUs right (FMI 2.0 and 3.0, co-simulation and model exchange, run by
``fmpy.simulate_fmu``), so the master's tests can compare against fmpy on them.
"""

from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

try:
    from event_fmus import MODELS, VERSIONS, event_fmu, event_fmus
except ImportError:  # tests/ imported as a package
    from tests.event_fmus import MODELS, VERSIONS, event_fmu, event_fmus

__all__ = ["event_fmus"]  # fixture

BOTH = [(v, i) for v in VERSIONS for i in ("CoSimulation", "ModelExchange")]


def _ids(params):
    return [f"fmi{v[0]}-{'cs' if i == 'CoSimulation' else 'me'}" for v, i in params]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("version", VERSIONS)
def test_fmus_are_valid(event_fmus, model, version):
    path = event_fmus[(model, version)]
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path), validate=True)
    assert md.fmiVersion == version
    assert md.coSimulation.modelIdentifier == model == md.modelExchange.modelIdentifier
    assert md.defaultExperiment is not None and float(md.defaultExperiment.stopTime) > 0
    assert event_fmu(model, version) == path


# ---- BouncingBall ---------------------------------------------------------------------------


def ball_exact(t, h0=1.0, g=9.81, e=0.7, v_min=0.1):
    """Closed form of the ball dropped from rest at h0: (h, v, bounces) at t, bounce times."""
    t_b = [math.sqrt(2.0 * h0 / g)]
    v = math.sqrt(2.0 * g * h0)  # impact speed
    v_up = []  # speed after each bounce (0: rests)
    while True:
        v *= e
        if v < v_min:
            v_up.append(0.0)
            break
        v_up.append(v)
        t_b.append(t_b[-1] + 2.0 * v / g)
    t_b, v_up = np.array(t_b), np.array(v_up)
    t = np.asarray(t, dtype=float)
    k = np.searchsorted(t_b, t, side="right")  # bounces done by t
    tau = np.where(k == 0, t, t - t_b[np.maximum(k - 1, 0)])
    v0 = np.where(k == 0, 0.0, v_up[np.maximum(k - 1, 0)])
    h = np.where(k == 0, h0, 0.0) + v0 * tau - 0.5 * g * tau**2
    vel = v0 - g * tau
    rest = k == len(t_b)
    return np.where(rest, 0.0, h), np.where(rest, 0.0, vel), k, t_b


def _simulate(path, fmi_type, **kw):
    return fmpy.simulate_fmu(str(path), fmi_type=fmi_type, **kw)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("start", [{}, {"h": 2.0, "e": 0.5, "g": 3.7}], ids=["default", "set"])
def test_ball_me_bounce_times_match_the_closed_form(event_fmus, version, start):
    path = event_fmus[("BouncingBall", version)]
    r = _simulate(path, "ModelExchange", stop_time=3.0, output_interval=1e-3,
                  relative_tolerance=1e-10, start_values=start)
    p = {"h0": start.get("h", 1.0), "e": start.get("e", 0.7), "g": start.get("g", 9.81)}
    h, v, k, t_b = ball_exact(r["time"], **p)
    n = int(np.sum(t_b <= 3.0))
    # the time of the first row with bounces == j is the j-th bounce
    seen = np.array([r["time"][np.argmax(r["bounces"] >= j)] for j in range(1, n + 1)])
    assert r["bounces"][-1] == n
    np.testing.assert_allclose(seen, t_b[:n], rtol=0, atol=1e-6)
    np.testing.assert_allclose(seen[0], math.sqrt(2 * p["h0"] / p["g"]), rtol=0, atol=1e-6)
    np.testing.assert_allclose(r["h"], h, rtol=0, atol=1e-6)
    assert r["h"].min() > -1e-8  # never through the floor
    away = np.min(np.abs(r["time"][:, None] - t_b[None, :]), axis=1) > 1e-6
    np.testing.assert_allclose(r["v"][away], v[away], rtol=0, atol=1e-5)
    np.testing.assert_array_equal(r["bounces"][away], k[away])


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("step", [0.01, 0.1])
def test_ball_cs_locates_bounces_inside_the_steps(event_fmus, version, step):
    path = event_fmus[("BouncingBall", version)]
    r = _simulate(path, "CoSimulation", stop_time=3.0, output_interval=step)
    h, v, k, _ = ball_exact(r["time"])
    # RK4 is exact for the parabolas and bisection locates each bounce to 1e-13 s
    np.testing.assert_allclose(r["h"], h, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["v"], v, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(r["bounces"], k)
    assert r["bounces"][-1] == 11 and r["h"][-1] == 0.0 and r["v"][-1] == 0.0
