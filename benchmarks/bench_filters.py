"""Time per step of our filters and of FilterPy, Stone Soup and `particles` on one TAN problem.

Every filter runs the same simulated truth and measurements of the TAN model (4 states, DVL
velocities and the terrain depth over the synthetic map of seed 7), from the same initial
estimate, with the same ``Q`` (set every step) and ``R``. A step is ``predict`` + ``update`` +
reading the mean (and covariance where the library keeps one); ours call ``est.step(u, dt, z)``,
the one call the estimator bank makes (the compiled Kalman steps do it in one compiled call).
Each row says what it runs:

- ``ours X`` / ``ours X compiled``: our filter, numpy step / ``compiled = true`` (the model's
  compiled form, :mod:`uwcosim.filters.kalman_kernels`); ``ours pf-N`` the bootstrap PF.
- ``filterpy ukf|ekf``, ``stonesoup ukf|ekf|pf-N``, ``particles bootstrap-N``: the library's
  filter with our closed-form transition (``model.f``, ``model.F``) and either
  ``terrain=model``: the model's own ``h``/``H``/``h_batch`` (our bicubic table lookups), or
  ``terrain=spline``: ``scipy.interpolate.RectBivariateSpline`` of the map's depth grid, what a
  user of those libraries would write (an interpolating cubic spline like ours, with other end
  conditions: a slightly different terrain, hence a slightly different RMSE).

The same sigma-point rule everywhere (alpha = 1, beta = 2, kappa = 0); the EKFs update in the
Joseph form (FilterPy, ours) or the standard form (Stone Soup). RMSE (position, second half of
the run) is checked against our numpy filter of the same algorithm: to 1e-6 relative for the
same algorithm and terrain, 5 % with the spline terrain. The particle filters draw from other
random streams, and one trajectory's RMSE of a 1000-particle filter is no evidence (it is
heavy-tailed: locked or not): their spline rows are checked against the same library's
``terrain=model`` row (the same stream, 5 %), and the ``terrain=model`` rows against ours over
``--pf-runs`` truth seeds (:mod:`pf_agreement`: run by run, the mean difference within 3 Monte
Carlo standard errors). Every particle filter gets ``PF_SETTINGS`` (systematic resampling below
ESS = N/2, no roughening), one initial cloud drawn from ``N(x0, P0)`` (:func:`initial_cloud`),
``Q`` and ``R``: ``tests/test_bench_pf_fairness.py`` checks it on one step of each.

Each row's time is the best median of ``--repeats`` interleaved runs (with its mean and 95th
percentile). Numba is loaded first unless ``--no-numba`` (then no compiled rows): the model's
terrain lookups, which the ``terrain=model`` rows of the libraries call too, then run
compiled (:mod:`uwcosim.models.terrain_kernels`, the same bits).

    .venv/bin/python benchmarks/bench_filters.py [--steps 2000] [--repeats 3] [--particles 1000]
        [--pf-runs 20] [--pf-steps 2000]

FilterPy, Stone Soup and `particles` are benchmark-only (``pip install -e .[bench]``;
``particles`` declares ``numpy<2``: ``pip install --no-deps particles``; it needs ``joblib``,
which the extra brings); a row whose library is missing is replaced by one line saying so.
"""

from __future__ import annotations

import argparse
import datetime
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from uwcosim.filters import kalman, particle, sigma_point  # noqa: E402, F401
from uwcosim.filters.base import ESTIMATORS  # noqa: E402
from uwcosim.models.tan import tan_model  # noqa: E402
from uwcosim.models.terrain import synthetic_bathymetry  # noqa: E402
from uwcosim.models.trajectory import simulate as simulate_model  # noqa: E402

STD0 = np.array([30.0, 30.0, 0.05, 0.05])
START = np.array([2000.0, 18000.0, 0.5, 0.0])
GOALS = {"ours ekf compiled": 5.0, "ours ukf compiled": 8.0}  # median us per step
RATIO_GOAL = 0.15  # ours compiled / FilterPy, same algorithm, terrain=model
T0 = datetime.datetime(2026, 1, 1)  # Stone Soup's time stamps: T0 + k s
#: how to install each library of the comparison (benchmark-only)
INSTALL = {"filterpy": "pip install -e .[bench]", "stonesoup": "pip install -e .[bench]",
           "particles": "pip install -e .[bench] and pip install --no-deps particles"}
#: what every particle filter of the comparison is given (Stone Soup's and ``particles``' own
#: names for them in :func:`stonesoup_pf`, :func:`particles_smc`): resample systematically
#: when the ESS falls below half the particles, no roughening
PF_SETTINGS = {"ess_threshold": 0.5, "resampling": "systematic", "roughening": 0.0}


def controls(k: int) -> np.ndarray:
    return np.array([0.4 * np.sin(k / 60.0), 0.0005 if k < 200 else 0.0])


def simulate(model, steps: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    X, _, zs = simulate_model(model.symbolic, START, controls, steps, rng)
    return X[1:], zs, START + STD0 * rng.standard_normal(4)


class Terrain:
    """The measurement function of one terrain choice: ``h(x)``, ``H(x)``, ``h_batch(X)``."""

    def __init__(self, model, kind: str) -> None:
        self.model, self.kind = model, kind
        if kind == "spline":
            from scipy.interpolate import RectBivariateSpline

            b = model.terrain
            ny, nx = b.shape
            xs, ys = b.x0 + b.dx * np.arange(nx), b.y0 + b.dy * np.arange(ny)
            self.spline = RectBivariateSpline(xs, ys, b.depth_grid.T, kx=3, ky=3, s=0)

    def h(self, x):
        if self.kind == "model":
            return self.model.h(x)
        return np.array([x[2], x[3], self.spline.ev(x[0], x[1])])

    def H(self, x):
        if self.kind == "model":
            return self.model.H(x)
        H = np.zeros((3, 4))
        H[0, 2] = H[1, 3] = 1.0
        H[2, 0] = self.spline.ev(x[0], x[1], dx=1)
        H[2, 1] = self.spline.ev(x[0], x[1], dy=1)
        return H

    def h_batch(self, X):
        """``(N, 3)`` for states as rows."""
        if self.kind == "model":
            return self.model.h_batch(X)
        return np.column_stack([X[:, 2], X[:, 3], self.spline.ev(X[:, 0], X[:, 1])])


def timed(zs, step):
    """Run ``step(k, z) -> x`` over the measurements: (seconds per step, estimates)."""
    times = np.empty(len(zs))
    xs = np.empty((len(zs), 4))
    for k, z in enumerate(zs):
        t0 = time.perf_counter()
        x = step(k, z)
        times[k] = time.perf_counter() - t0
        xs[k] = x
    return times, xs


def initial_cloud(x0, n_particles: int, seed: int = 1) -> np.ndarray:
    """The particle filters' shared initial cloud, ``(4, N)`` draws of ``N(x0, P0)`` from a
    stream of its own (``default_rng([seed, 1])``): every PF of a run starts from the same
    particles (the prior's draw decides much of whether a 1000-particle filter locks onto the
    terrain, so sharing it makes their comparison paired: ``pf_agreement.py``)."""
    e = np.random.default_rng([seed, 1]).standard_normal((4, n_particles))
    return np.asarray(x0, dtype=float)[:, None] + STD0[:, None] * e


def ours_filter(name, model, x0, settings, seed: int = 1):
    """Our estimator ``name`` from ``N(x0, P0)`` with ``settings``, its stream seeded ``seed``;
    the particle filter starts from :func:`initial_cloud` (the same distribution as its own
    draw)."""
    est = ESTIMATORS.get(name).from_settings(model, x0, np.diag(STD0**2), settings,
                                             rng=np.random.default_rng(seed))
    if name == "pf":
        est.particles = initial_cloud(x0, est.n, seed)  # before anything reads x or P
    return est


def ours(name, model, x0, settings, seed: int = 1):
    def job(zs):
        est = ours_filter(name, model, x0, settings, seed)

        def step(k, z):
            est.step(controls(k), 1.0, z)  # predict + update (compiled: one call)
            _ = est.P
            return est.x

        return timed(zs, step)
    return job


def filterpy_job(kind, model, x0, terrain):
    def job(zs):
        from filterpy.kalman import (
            ExtendedKalmanFilter,
            MerweScaledSigmaPoints,
            UnscentedKalmanFilter,
        )

        if kind == "ukf":
            points = MerweScaledSigmaPoints(4, alpha=1.0, beta=2.0, kappa=0.0)
            f = UnscentedKalmanFilter(4, 3, 1.0, hx=terrain.h,
                                      fx=lambda x, dt, u: model.f(x, u, dt), points=points)
        else:
            f = ExtendedKalmanFilter(4, 3)
        f.x = x0.copy()
        f.P = np.diag(STD0**2)
        f.R = model.R.copy()

        def step(k, z):
            u = controls(k)
            f.Q = model.Q(f.x, u, 1.0)
            if kind == "ukf":
                f.predict(dt=1.0, u=u)
                f.update(z)
            else:  # FilterPy's EKF predicts with a linear F x + B u: set x and P ourselves
                F = model.F(f.x, u, 1.0)
                f.x = model.f(f.x, u, 1.0)
                f.P = F @ f.P @ F.T + f.Q
                f.update(z, terrain.H, terrain.h)
            _ = f.P
            return f.x

        return timed(zs, step)
    return job


def stonesoup_models(model, terrain):
    """Stone Soup's transition and measurement models of the TAN problem: our closed-form step
    with ``Q = model.Q`` (the control ``u`` comes as a keyword), the DVL velocities and the
    depth of ``terrain`` with ``R = model.R``."""
    from stonesoup.base import Property
    from stonesoup.models.base import GaussianModel
    from stonesoup.models.measurement.base import MeasurementModel
    from stonesoup.models.transition.nonlinear import GaussianTransitionModel
    from stonesoup.types.array import StateVector, StateVectors

    class Transition(GaussianTransitionModel):
        """Our closed-form TAN step; the control ``u`` comes as a keyword."""

        ndim_state: int = Property(default=4)

        @property
        def ndim(self):
            return 4

        def function(self, state, noise=False, **kw):
            X = np.asarray(state.state_vector, dtype=float)
            out = model.f_batch(X.T, kw["u"], 1.0).T
            if noise is True:
                noise = self.rvs(num_samples=X.shape[1], **kw)
            elif noise is False or noise is None:
                noise = 0
            return StateVectors(out + noise) if X.shape[1] > 1 else StateVector(out + noise)

        def jacobian(self, state, **kw):
            return model.F(None, kw["u"], 1.0)

        def covar(self, **kw):
            return model.Q(None, kw["u"], 1.0)

    class Measurement(MeasurementModel, GaussianModel):
        """DVL velocities and the terrain depth of ``terrain``."""

        ndim_state: int = Property(default=4)
        mapping: tuple = Property(default=(0, 1, 2, 3))

        @property
        def ndim_meas(self):
            return 3

        def function(self, state, noise=False, **kw):
            X = np.asarray(state.state_vector, dtype=float)
            Z = terrain.h_batch(X.T).T
            return StateVectors(Z) if X.shape[1] > 1 else StateVector(Z)

        def jacobian(self, state, **kw):
            return terrain.H(np.asarray(state.state_vector, dtype=float)[:, 0])

        def covar(self, **kw):
            return model.R

    return Transition(), Measurement()


def stonesoup_pf(trans, meas, x0, n_particles, seed: int = 1):
    """Stone Soup's particle filter with the shared settings (:data:`PF_SETTINGS`): the prior
    ``(state, predictor, updater)``, the prior's particles :func:`initial_cloud`. Stone Soup
    draws its noise and resampling from numpy's global stream, seeded ``seed``."""
    from stonesoup.predictor.particle import ParticlePredictor
    from stonesoup.resampler.particle import ESSResampler, SystematicResampler
    from stonesoup.types.array import StateVectors
    from stonesoup.types.state import ParticleState
    from stonesoup.updater.particle import ParticleUpdater

    np.random.seed(seed)
    state = ParticleState(StateVectors(initial_cloud(x0, n_particles, seed)), log_weight=np.full(
        n_particles, -np.log(n_particles)), timestamp=T0)
    resampler = ESSResampler(threshold=PF_SETTINGS["ess_threshold"] * n_particles,
                             resampler=SystematicResampler())
    return state, ParticlePredictor(trans), ParticleUpdater(meas, resampler=resampler)


def stonesoup_job(kind, model, x0, terrain, n_particles, seed: int = 1):
    def job(zs):
        from stonesoup.predictor.kalman import ExtendedKalmanPredictor, UnscentedKalmanPredictor
        from stonesoup.types.array import StateVector
        from stonesoup.types.detection import Detection
        from stonesoup.types.hypothesis import SingleHypothesis
        from stonesoup.types.state import GaussianState
        from stonesoup.updater.kalman import ExtendedKalmanUpdater, UnscentedKalmanUpdater

        trans, meas = stonesoup_models(model, terrain)
        if kind == "pf":
            state, predictor, updater = stonesoup_pf(trans, meas, x0, n_particles, seed)
        else:
            state = GaussianState(StateVector(x0), np.diag(STD0**2), timestamp=T0)
            if kind == "ukf":
                predictor = UnscentedKalmanPredictor(trans, alpha=1.0, beta=2.0, kappa=0.0)
                updater = UnscentedKalmanUpdater(meas, alpha=1.0, beta=2.0, kappa=0.0)
            else:
                predictor, updater = ExtendedKalmanPredictor(trans), ExtendedKalmanUpdater(meas)
        one = datetime.timedelta(seconds=1)

        def step(k, z):
            nonlocal state
            t = T0 + (k + 1) * one
            pred = predictor.predict(state, timestamp=t, u=tuple(controls(k)))  # hashable
            det = Detection(StateVector(z), timestamp=t, measurement_model=meas)
            state = updater.update(SingleHypothesis(pred, det))
            return np.asarray(state.mean, dtype=float).ravel()

        return timed(zs, step)
    return job


def particles_model(model, cloud, terrain):
    """``particles``' state-space model of the TAN problem (a class built for ``model``, the
    initial ``cloud`` and ``terrain``): ``X_t ~ N(f(X_{t-1}, u_t), Q)``, ``Y_t ~ N(h(X_t), R)``
    with ``R`` diagonal (a product of normals). ``particles`` observes ``X_0``; ours observe
    after the first step, so ``X_0`` here is the first step from the cloud,
    ``N(f(cloud_i, u_0), Q)`` (from ``N(x0, P0)``: ``N(f(x0), F P0 F' + Q)``)."""
    from particles import distributions as dists
    from particles import state_space_models as ssm

    sd = np.sqrt(np.diag(model.R))
    u0 = controls(0)
    X0 = model.f_batch(np.ascontiguousarray(cloud.T), u0, 1.0)

    class TAN(ssm.StateSpaceModel):
        def PX0(self):
            return dists.MvNormal(loc=X0, cov=model.Q(None, u0, 1.0))

        def PX(self, t, xp):
            u = controls(t)
            return dists.MvNormal(loc=model.f_batch(xp, u, 1.0), cov=model.Q(None, u, 1.0))

        def PY(self, t, xp, x):
            Z = terrain.h_batch(x)
            return dists.IndepProd(*[dists.Normal(loc=Z[:, i], scale=sd[i])
                                     for i in range(3)])

    return TAN


def particles_smc(model, x0, terrain, zs, n_particles, seed: int = 1):
    """``particles``' bootstrap filter on the measurements ``zs`` with the shared settings
    (:data:`PF_SETTINGS`), from :func:`initial_cloud`; numpy's global stream, which it draws
    from, seeded ``seed``."""
    import particles
    from particles import state_space_models as ssm

    cloud = initial_cloud(x0, n_particles, seed)
    fk = ssm.Bootstrap(ssm=particles_model(model, cloud, terrain)(),
                       data=[np.asarray(z) for z in zs])
    np.random.seed(seed)
    return particles.SMC(fk=fk, N=n_particles, resampling=PF_SETTINGS["resampling"],
                         ESSrmin=PF_SETTINGS["ess_threshold"])


def particles_job(model, x0, terrain, n_particles, seed: int = 1):
    def job(zs):
        alg = particles_smc(model, x0, terrain, zs, n_particles, seed)

        def step(k, z):
            next(alg)  # resamples (ESS of the last weights), moves, weights
            return np.average(alg.X, axis=0, weights=alg.wgts.W)  # before resampling

        return timed(zs, step)
    return job


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--pf-runs", type=int, default=20,
                    help="truth seeds per library of the particle filters' RMSE check (0: none)")
    ap.add_argument("--pf-steps", type=int, default=2000, help="steps of each of those runs")
    ap.add_argument("--no-numba", action="store_true",
                    help="no compiled rows; the model's terrain lookups in numpy")
    args = ap.parse_args()
    compiled = not args.no_numba
    if compiled:
        import numba  # noqa: F401

    terrain = synthetic_bathymetry(7)
    model = tan_model([0.01, 0.01, 1e-6, 1e-6], 0.05, 2.0, terrain)
    truth, zs, x0 = simulate(model, args.steps)
    N = args.particles
    print(f"TAN model, {args.steps} steps, best of {args.repeats} interleaved runs; "
          f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}; "
          f"the model's terrain lookups {'compiled' if compiled else 'numpy'}")

    jobs, reference = {}, {}
    for name, settings in (("ekf", {}), ("ukf", {}), ("pf", {"n_particles": N, **PF_SETTINGS})):
        label = f"ours {name}" + (f"-{N}" if name == "pf" else "")
        jobs[label] = ours(name, model, x0, settings)
        reference[name] = label
        if compiled and name != "pf":
            jobs[label + " compiled"] = ours(name, model, x0, {**settings, "compiled": True})
    missing = []
    kinds = {"model": Terrain(model, "model"), "spline": Terrain(model, "spline")}
    for lib, rows in (("filterpy", ("ekf", "ukf")), ("stonesoup", ("ekf", "ukf", "pf")),
                      ("particles", ("pf",))):
        try:
            __import__(lib)
        except ImportError:
            missing.append(lib)
            continue
        for kind in rows:
            for tname, t in kinds.items():
                if lib == "filterpy":
                    jobs[f"filterpy {kind}, terrain={tname}"] = filterpy_job(kind, model, x0, t)
                elif lib == "stonesoup":
                    n = f"-{N}" if kind == "pf" else ""
                    jobs[f"stonesoup {kind}{n}, terrain={tname}"] = stonesoup_job(
                        kind, model, x0, t, N)
                else:
                    jobs[f"particles bootstrap-{N}, terrain={tname}"] = particles_job(
                        model, x0, t, N)
    for lib in missing:
        print(f"{lib} not installed ({INSTALL[lib]}): its rows are left out")

    for job in jobs.values():  # warm-up: caches, lazy imports, kernels, CPU clock
        job(zs[:100])
    results: dict[str, tuple] = {}
    for _ in range(args.repeats):
        for label, job in jobs.items():
            times, xs = job(zs)
            med = float(np.median(times)) * 1e6
            if label not in results or med < results[label][0]:
                results[label] = (med, float(np.mean(times)) * 1e6,
                                  float(np.percentile(times, 95)) * 1e6, xs)

    half = slice(args.steps // 2, None)
    rmse = {label: float(np.sqrt(np.mean(np.sum((r[3] - truth)[half, :2] ** 2, axis=1))))
            for label, r in results.items()}
    print(f"\n{'filter':40s} {'median us':>10s} {'mean us':>9s} {'p95 us':>9s} "
          f"{'RMSE m':>8s}  RMSE vs ours (numpy)")
    for label, (med, mean, p95, _) in results.items():
        kind = "pf" if "pf" in label or "bootstrap" in label else label.split()[1][:3]
        ref_label = reference[kind]
        if kind == "pf":  # other random streams: one trajectory is no evidence (pf_agreement)
            ref_label = label.replace("terrain=spline", "terrain=model")
        ref = rmse[ref_label]
        tol = 0.05 if "spline" in label else 1e-6
        rel = abs(rmse[label] - ref) / ref
        if label == reference[kind]:
            check = "reference"
        elif label == ref_label:
            check = "over seeds: below"
        else:
            check = f"{'equal' if rel <= tol else 'DIFFERS'} ({rel:.1e}, tol {tol:g})"
            if kind == "pf":
                check += " to terrain=model"
        print(f"{label:40s} {med:10.1f} {mean:9.1f} {p95:9.1f} {rmse[label]:8.2f}  {check}")

    print("\ngoals")
    for label, goal in GOALS.items():
        if label in results:
            med = results[label][0]
            print(f"  {label:28s} {med:6.1f} us/step  (goal <= {goal:g}: "
                  f"{'met' if med <= goal else 'NOT met'})")
    for kind in ("ekf", "ukf"):
        ref = f"filterpy {kind}, terrain=model"
        if f"ours {kind} compiled" in results and ref in results:
            r = results[f"ours {kind} compiled"][0] / results[ref][0]
            print(f"  ours {kind} compiled / {ref:26s} = {r:6.3f}  (goal <= {RATIO_GOAL}: "
                  f"{'met' if r <= RATIO_GOAL else 'NOT met'})")

    if args.pf_runs > 0:  # the particle filters' RMSE over seeds (benchmarks/pf_agreement.py)
        import pf_agreement

        print(f"\nparticle filters over seeds (pf_agreement.py): {args.pf_runs} truth seeds, "
              f"{args.pf_steps} steps, terrain=model; RMSE = position, second half")
        model_mc, sim = pf_agreement.problem(args.pf_steps)
        mc = pf_agreement.monte_carlo(model_mc, sim, pf_agreement.filters(model_mc, N),
                                      args.pf_runs)
        print("\n".join(pf_agreement.report(mc)))


if __name__ == "__main__":
    main()
