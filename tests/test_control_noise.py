"""Noisy heading and acceleration (issue 14, item 3): the vehicle FMU's control-noise inputs,
the TAN model's ``Q`` with the control noise (``model.control_noise``), its validation, and a
short run of the paper-like Table 1 campaign (``scenarios/campaigns/table1_paper.toml``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from uwcosim.core.errors import ScenarioError
from uwcosim.master.observer import Callback
from uwcosim.models.tan import control_jacobian, tan_model

ROOT = Path(__file__).resolve().parents[1]
CONTROL_NOISE = ('noise.controls={targets=["vehicle.w_psi", "vehicle.w_a"], psd=[%r, %r]}')
Q_PSD = [0.05, 0.05, 1e-5, 1e-5]


def noisy(qpsi: float, qa: float) -> list[str]:
    """Overrides: control noise of PSDs ``(qpsi, qa)`` on the truth, known to the filters."""
    return [CONTROL_NOISE % (qpsi, qa), 'model.control_noise="controls"']


def _trajectory(loaded, steps: int, names=("vehicle.x", "vehicle.y", "vehicle.vx",
                                           "vehicle.vy")) -> np.ndarray:
    from uwcosim.master.master import Master
    from uwcosim.scenario import to_system

    master = Master(to_system(loaded))
    rows = []
    master.observers.append(Callback(
        lambda k, v: k and rows.append([v.signal(n) for n in names])))
    master.initialize()
    master.run_until(loaded.spec.run.start_time + steps * loaded.spec.run.step)
    master.close()
    return np.array(rows)


# -- the truth FMU -------------------------------------------------------------------------
def test_zero_control_noise_gives_the_old_trajectory_bit_for_bit(tan):
    """Driving w_psi, w_a with zero noise (a new noise source, its own random stream) leaves
    the truth unchanged to the bit: the inputs are added to psi and a, and x + 0.0 == x."""
    base = ["run.duration=300", "estimators={}"]
    old = _trajectory(tan(base), 300)
    new = _trajectory(tan(base + noisy(0.0, 0.0)), 300)
    assert old.shape == (300, 4)
    np.testing.assert_array_equal(new, old)


def test_control_noise_has_the_right_variance(tan):
    """Acceleration noise alone (heading 0, no process noise, a = 0): the velocity increments
    are dt * w_a with variance psd * dt; heading noise alone at speed v: the cross-track
    position increments are dt * v * sin(w_psi), variance ~ psd * v^2 * dt. Checked against the
    two-sided 99.9 % chi-square band of the sample variance."""
    n, dt = 3000, 1.0
    common = ["run.duration=3000", "estimators={}", "noise.process.psd=[0.0, 0.0, 0.0, 0.0]",
              "controls.psi.table=[[0.0, 0.0]]", "controls.a.table=[[0.0, 0.0]]"]
    qa = 4e-6
    X = _trajectory(tan(common + noisy(0.0, qa)), n)
    dv = np.diff(X[:, 2])
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], dv.size - 1) / (dv.size - 1)
    ratio = np.var(dv, ddof=1) / (qa * dt)
    assert lo < ratio < hi, ratio
    np.testing.assert_array_equal(X[:, 3], 0.0)  # heading 0: nothing along y

    qpsi = 0.0025  # 0.05 rad per step
    X = _trajectory(tan(common + noisy(qpsi, 0.0)), n)
    np.testing.assert_array_equal(X[:, 2], 0.5)  # a = 0: the velocity state does not move
    dy = np.diff(X[:, 1])
    expected = 0.5**2 * dt**2 * (1.0 - np.exp(-2.0 * qpsi / dt)) / 2.0  # var(sin w) exactly
    ratio = np.var(dy, ddof=1) / expected
    assert lo < ratio < hi, ratio


# -- the filters' model --------------------------------------------------------------------
X0 = np.array([2000.0, 18000.0, 0.9, -0.3])
U0 = np.array([0.6, 0.002])
QC = np.array([0.0025, 4e-6])


def test_control_jacobian_matches_finite_differences():
    m = tan_model(Q_PSD, [0.75, 0.75])
    x = X0 * [0.0, 0.0, 1.0, 1.0]  # J does not depend on the position: no round-off of 1e4 m
    J = control_jacobian(x, U0, 1.0)
    np.testing.assert_array_equal(J, control_jacobian(X0, U0, 1.0))
    h = 1e-5
    for j in range(2):
        du = np.zeros(2)
        du[j] = h
        fd = (m.f(x, U0 + du, 1.0) - m.f(x, U0 - du, 1.0)) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("q_psd", [Q_PSD, [0.0] * 4], ids=["with_process", "control_only"])
def test_Q_with_control_noise_matches_monte_carlo_and_casadi(q_psd):
    """``Q`` against the sample covariance of the exact step with sampled process and control
    noise (2e5 draws: a relative error of the entries of about 1 %, tolerance 3 % of
    ``sqrt(Q_ii Q_jj)``; the linearization in the heading errs by O(var psi) = 0.25 %); the
    numpy and CasADi forms agree to round-off; the factor squares to ``Q``."""
    dt = 1.0
    m = tan_model(q_psd, [0.75, 0.75], control_psd=QC)
    Q = m.Q(X0, U0, dt)
    rng = np.random.default_rng(5)
    n = 200_000
    dpsi, da = (rng.standard_normal((2, n)) * np.sqrt(QC / dt)[:, None])
    w = rng.standard_normal((4, n)) * np.sqrt(np.asarray(q_psd) / dt)[:, None]
    psi, a = U0[0] + dpsi, U0[1] + da
    c, s = np.cos(psi), np.sin(psi)
    vx, vy = X0[2], X0[3]
    # exact step of eq. (54), all held: p' = p + dt (Rot v + w_p) + dt^2/2 Rot (a e + w_v)
    ax, ay = a * c + w[2], a * s + w[3]
    x1 = dt * (vx * c - vy * s + w[0]) + 0.5 * dt**2 * (ax * c - ay * s)
    y1 = dt * (vy * c + vx * s + w[1]) + 0.5 * dt**2 * (ay * c + ax * s)
    S = np.cov(np.vstack([x1, y1, dt * ax, dt * ay]))
    # entrywise, relative to the scale sqrt(Q_ii Q_jj) of each entry
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    assert np.all(np.abs(S - Q) <= 0.03 * scale), (S - Q) / scale
    # with the process noise the control noise adds 27 % on vx and 4 % on y; alone, the
    # comparison above checks J diag(q_c/dt) J' itself
    Q0 = tan_model(q_psd, [0.75, 0.75]).Q(X0, U0, dt)
    assert Q[2, 2] > 1.2 * Q0[2, 2] and Q[1, 1] > 1.03 * Q0[1, 1]
    np.testing.assert_allclose(m.symbolic.Q(X0, U0, dt), Q, rtol=1e-12, atol=1e-18)
    L = m.Q_factor(X0, U0, dt)
    np.testing.assert_allclose(L @ L.T, Q, rtol=1e-12, atol=1e-18)
    F, Qf = m.FQ(X0, U0, dt)
    np.testing.assert_array_equal(Qf, Q)
    assert m.Q_depends_on_x and not tan_model(q_psd, [0.75, 0.75]).Q_depends_on_x
    # state dependence through the velocity only
    assert not np.allclose(m.Q(X0 * [1, 1, 2, 2], U0, dt), Q)
    np.testing.assert_allclose(m.Q(X0 + [500.0, -300.0, 0, 0], U0, dt), Q, rtol=1e-15)


def test_grid_filters_use_the_same_Q_and_keep_the_constant_drift_path():
    """The grid filters' step (evaluated at their estimate) has the model's Q; the velocity
    stays a Kalman state, and the position's drift and diffusion do not depend on the position:
    PFM-PSI keeps its constant-drift prediction (no Galerkin step)."""
    from uwcosim.filters.grid.partition import Partition

    m = tan_model(Q_PSD, [0.75, 0.75], control_psd=QC)
    part = Partition(m.symbolic)
    assert (part.p, part.k) == ([0, 1], [2, 3])
    assert part.drift_constant and part.diffusion_constant
    _, _, Q = part.step(X0, U0, 1.0)
    np.testing.assert_allclose(Q, m.Q(X0, U0, 1.0), rtol=1e-12, atol=1e-18)


# -- the scenario option ---------------------------------------------------------------------
@pytest.mark.parametrize("overrides, message", [
    (['model.control_noise="nope"'],
     "key 'model.control_noise': unknown noise source 'nope' (noise: process)"),
    ([CONTROL_NOISE % (0.1, 0.1)],
     "the TAN model needs 4 process-noise PSDs (x, y, vx, vy), got 6; name the control-noise "
     "source in model.control_noise or give model.q_psd"),
    (['noise.controls={targets=["vehicle.w_psi"], psd=[0.1]}', 'model.control_noise="controls"'],
     "key 'model.control_noise': noise 'controls' needs one PSD per model control (psi, a): 2 "
     "PSDs and 2 model.controls, got 1 and 2"),
    (['model.control_noise=3'], "model.control_noise"),
])
def test_control_noise_option_errors(tan, overrides, message):
    with pytest.raises(ScenarioError) as err:
        tan(overrides)
    text = str(err.value)
    assert message in text and "\n" not in text


def test_control_noise_is_in_the_json_schema():
    from uwcosim.scenario.json_schema import scenario_json_schema

    props = scenario_json_schema()["$defs"]["ModelSpec"]["properties"]
    assert "control_noise" in props and "psi" in props["control_noise"]["description"]


def test_the_model_knows_the_control_noise_only_when_asked(tan):
    from uwcosim.run.factory import build_model

    name = "tan_dead_reckoning.toml"  # no map needed
    on = tan([CONTROL_NOISE % (0.0025, 4e-6), 'model.control_noise="controls"'], name=name)
    off = tan([CONTROL_NOISE % (0.0025, 4e-6), "model.q_psd=[0.05, 0.05, 1e-5, 1e-5]"],
              name=name)
    m_on, m_off = build_model(on, None), build_model(off, None)
    np.testing.assert_array_equal(m_on.q_psd, Q_PSD)
    np.testing.assert_array_equal(m_on.control_psd, [0.0025, 4e-6])
    assert m_off.control_psd is None


# -- the campaign ----------------------------------------------------------------------------
def test_table1_paper_campaign_short_run(project_fmus, tmp_path):
    """200 steps of both variants of the paper-like Table 1 campaign: every filter runs to the
    end and keeps the track (position error far below the 30 m initial spread)."""
    import pyarrow.parquet as pq

    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.driver import run_campaign

    spec = load_campaign(ROOT / "scenarios" / "campaigns" / "table1_paper.toml")
    for v in spec.spec.variants:
        v.set.append("run.duration=200")
    summary = run_campaign(spec, tmp_path / "c", runs=1, workers=1, figures=False)
    assert summary["runs"] == 2
    rows = pq.read_table(tmp_path / "c" / "runs.parquet").to_pylist()
    assert {r["estimator"] for r in rows} == {"ukf", "pf", "pfm_psi", "ekf", "point_mass"}
    assert len(rows) == 10 and not any(r["diverged"] for r in rows)
    assert all(np.isfinite(r["rmse_position_m"]) and r["rmse_position_m"] < 100 for r in rows)


def test_note_when_the_truth_has_no_control_noise_inputs():
    """A vehicle without w_psi, w_a runs without the control noise; the run's note says the
    filters' model still adds it (not that it is process noise)."""
    from types import SimpleNamespace

    from uwcosim.run.simulate import noise_free_notes

    system = SimpleNamespace(noise={
        "process": SimpleNamespace(targets=["vehicle.w_x"]),
        "controls": SimpleNamespace(targets=["vehicle.w_psi", "vehicle.w_a"])})
    notes = noise_free_notes(system, {"process": "vehicle", "controls": "vehicle"}, False,
                             "controls")
    assert notes[0].endswith("the filters' process noise is model.q_psd, which defaults to "
                             "these PSDs")
    assert notes[1] == ("the truth ran noise-free: FMU 'vehicle' has no inputs w_psi, w_a for "
                        "noise 'controls'; the filters' model still adds it as control noise "
                        "(model.control_noise)")
