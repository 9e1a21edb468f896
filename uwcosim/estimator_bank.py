"""Drives a scenario's estimators from the master, as a per-step hook.

At each communication step ``t_k -> t_{k+1}`` every estimator predicts with the control held
over the step, then updates with the measurements received at ``t_{k+1}`` (common random
numbers: all estimators see the same :class:`~uwcosim.master.measurement.Measurement`, from the
master's sensor bank, which the log records too), after its lost-measurement policy has
decided what to feed it. A diverging estimator (:mod:`uwcosim.divergence`: non-finite state,
covariance not symmetric positive definite, negative NIS/NEES, position out of bounds) is
flagged and stopped; the others go on.

The scenario was validated when it was loaded (:mod:`uwcosim.scenario.validate`: sensors,
controls, filter types, policies and settings), so the bank trusts it.
"""

from __future__ import annotations

import time
from array import array
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from uwcosim.errors import FilterDivergence, ScenarioError
from uwcosim.filters import Estimator
from uwcosim.filters.grid.jit import interrupted
from uwcosim.master.sources import stream

if TYPE_CHECKING:
    from uwcosim.master.master import Master
    from uwcosim.models.casadi_model import CasadiModel
    from uwcosim.models.linear import LinearModel
    from uwcosim.models.tan import TANModel


@dataclass
class Track:
    """One estimator and what the bank keeps about it."""

    name: str
    estimator: Estimator
    policy: object
    use: np.ndarray  # bool [nz]: components of sensors this estimator uses
    nees: float = float("nan")
    diverged_at: float | None = None
    error: str = ""
    step_times: array = field(default_factory=lambda: array("d"))  # 8 bytes per step


class EstimatorBank:
    """All estimators of a run, fed from the master's bus."""

    def __init__(self, master: Master, model: CasadiModel | LinearModel | TANModel, where: str,
                 map_extent: tuple[float, float, float, float] | None = None) -> None:
        from uwcosim.divergence import DivergenceCheck, default_bound
        from uwcosim.evaluation.metrics import position_velocity_indices
        from uwcosim.filters.policies import POLICIES
        from uwcosim.filters.settings import build
        from uwcosim.scenario.validate import validated_settings

        spec = master.spec
        self.model = model
        self.where = where
        mspec = spec.model
        self.truth_slots = np.array([master._slot(s, "model.truth") for s in mspec.truth])
        self.control_slots = np.array([master.slots[f"controls.{c}"] for c in mspec.controls],
                                      dtype=np.intp)
        sensor_of = master.sensors.sensor_of  # the model's sensors (System.measured)
        x_true0 = master.bus[self.truth_slots]
        est_common = spec.estimation
        bound = est_common.position_bound if est_common is not None else None
        if bound is None and map_extent is not None:
            bound = default_bound(map_extent)
        pos = position_velocity_indices(model.state_names)[0]
        self.check = DivergenceCheck(tuple(pos), tuple(bound) if bound is not None else None)
        init_rng = stream(master.seed, "initial-error")
        std0 = np.asarray(est_common.initial_std if est_common else np.ones(model.nx), float)
        err0 = init_rng.standard_normal(model.nx) * std0
        if est_common is not None and est_common.initial_error == "zero":
            err0[:] = 0.0
        self.tracks: list[Track] = []
        for ename, es in spec.estimators.items():
            std = np.asarray(es.initial_std, float) if es.initial_std else std0
            try:
                est = build(es.type, model, x_true0 + err0, np.diag(std**2),
                            validated_settings(es), rng=stream(master.seed, f"estimator:{ename}"))
            except (TypeError, ValueError) as exc:  # what needs the model (names, memory)
                raise ScenarioError(f"{where}: key 'estimators.{ename}': {exc}") from None
            except MemoryError:
                raise ScenarioError(f"{where}: key 'estimators.{ename}': not enough memory "
                                    f"for these settings") from None
            est.t = master.t0
            policy = POLICIES.get(es.policy)(model.nz)
            use_sensors = es.sensors if es.sensors is not None else list(mspec.sensors)
            use = np.array([s in use_sensors for s in sensor_of], dtype=bool)
            self.tracks.append(Track(ename, est, policy, use))

    def __call__(self, master: Master) -> None:
        u = master.bus[self.control_slots]
        meas = master.measurement()
        z, rec = meas.z, meas.received
        t = master.t
        stepped = []
        for tr in self.tracks:
            if tr.diverged_at is not None:
                continue
            est = tr.estimator
            a = time.perf_counter()
            try:
                est.predict(u, master.h)
                est.t = t
                z_in, mask = tr.policy(t, z, rec & tr.use)
                mask = np.asarray(mask, dtype=bool) & tr.use
                est.update(z_in if mask.any() else None, mask)
            except FilterDivergence as exc:
                tr.diverged_at = t
                tr.error = str(exc)
                tr.nees = float("nan")
            except SystemError as exc:  # Ctrl-C while a compiled (Numba) kernel returned
                if interrupted(exc):
                    raise KeyboardInterrupt from None
                raise
            tr.step_times.append(time.perf_counter() - a)
            if tr.diverged_at is None:
                stepped.append(tr)
        if stepped:
            self._assess(stepped, master, t)

    def _assess(self, tracks: list[Track], master: Master, t: float) -> None:
        """NEES and divergence checks of this step's estimates, all at once
        (:meth:`uwcosim.divergence.DivergenceCheck.assess`)."""
        X = np.array([tr.estimator.x for tr in tracks], dtype=float)
        Ps = np.array([tr.estimator.P for tr in tracks], dtype=float)
        nis = np.array([tr.estimator.diagnostics.get("nis", np.nan) for tr in tracks],
                       dtype=float)
        whys, nees = self.check.assess(X, Ps, master.bus[self.truth_slots] - X, nis)
        for tr, why, v in zip(tracks, whys, nees.tolist(), strict=True):
            tr.nees = v
            if why:
                tr.diverged_at, tr.error = t, why
