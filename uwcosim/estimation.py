"""Drives a scenario's estimators from the master, as a per-step hook.

At each communication step ``t_k -> t_{k+1}`` every estimator predicts with the control held
over the step, then updates with the measurements received at ``t_{k+1}`` (common random
numbers: all estimators see the same measurements), after its lost-measurement policy has
decided what to feed it. A diverging estimator is flagged and stopped; the others go on.
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lapack

from uwcosim.errors import FilterDivergence, ScenarioError
from uwcosim.filters import ESTIMATORS, Estimator
from uwcosim.filters.numerics import check_finite
from uwcosim.filters.projection_kernels import interrupted
from uwcosim.master.sources import gaussian, stream

_gesv = lapack.dgesv


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
    step_times: list[float] = field(default_factory=list)


class EstimatorBank:
    """All estimators of a run, fed from the master's bus."""

    def __init__(self, master, model, where: str) -> None:
        from uwcosim.filters.policies import POLICIES

        spec = master.spec
        self.model = model
        self.where = where
        mspec = spec.model
        self.truth_slots = np.array([master._slot(s, "model.truth") for s in mspec.truth])
        self.control_slots = np.array(
            [master.slots[f"controls.{c}"] if f"controls.{c}" in master.slots
             else self._bad(f"model.controls: unknown control {c!r} "
                            f"(controls: {', '.join(spec.controls)})")
             for c in mspec.controls], dtype=np.intp)
        names, slots, sensor_of = [], [], []
        for sname in mspec.sensors:
            sensor = master.sensors.get(sname)
            if sensor is None:
                self._bad(f"model.sensors: unknown sensor {sname!r} "
                          f"(sensors: {', '.join(master.sensors)})")
            names += sensor.outputs
            slots += list(sensor.slots)
            sensor_of += [sname] * len(sensor.outputs)
        self.meas_slots = np.array(slots, dtype=np.intp)
        self._z_step = -1
        # sensors with sigma but no noise inputs: the master's stream adds the noise here
        n = master.n_steps + 1
        self.additive = np.zeros((n, len(slots)))
        col = 0
        for sname in mspec.sensors:
            s = spec.sensors[sname]
            if s.sigma and not s.noise_inputs:
                if len(s.sigma) != len(s.outputs):
                    self._bad(f"sensors.{sname}.sigma: additive noise needs one sigma per "
                              f"output ({len(s.outputs)})")
                self.additive[:, col:col + len(s.outputs)] = gaussian(
                    stream(master.seed, f"sensor-noise:{sname}"), n, s.sigma)
            col += len(s.outputs)
        self.sensor_of = sensor_of
        self.received = np.stack([master.sensors[s].received for s in sensor_of], axis=1) \
            if sensor_of else np.zeros((master.n_steps + 1, 0), bool)
        x_true0 = master.bus[self.truth_slots]
        est_common = spec.estimation
        init_rng = stream(master.seed, "initial-error")
        std0 = np.asarray(est_common.initial_std if est_common else np.ones(model.nx), float)
        err0 = init_rng.standard_normal(model.nx) * std0
        if est_common is not None and est_common.initial_error == "zero":
            err0[:] = 0.0
        self.tracks: list[Track] = []
        for ename, es in spec.estimators.items():
            key = f"estimators.{ename}"
            cls = ESTIMATORS.get(es.type, where=f"{where}: key '{key}.type'")
            settings = dict(es.model_extra or {})
            if "rng" in inspect.signature(cls.__init__).parameters:
                settings["rng"] = stream(master.seed, f"estimator:{ename}")
            std = np.asarray(es.initial_std, float) if es.initial_std else std0
            est = cls.from_settings(model, x_true0 + err0, np.diag(std**2), settings,
                                    where=f"{where}: key '{key}'")
            est.t = master.t0
            policy = POLICIES.get(es.policy, where=f"{where}: key '{key}.policy'")(model.nz)
            use_sensors = es.sensors if es.sensors is not None else list(mspec.sensors)
            for s in use_sensors:
                if s not in mspec.sensors:
                    self._bad(f"{key}.sensors: {s!r} is not among model.sensors "
                              f"({', '.join(mspec.sensors)})")
            use = np.array([s in use_sensors for s in sensor_of], dtype=bool)
            self.tracks.append(Track(ename, est, policy, use))

    def _bad(self, msg: str):
        raise ScenarioError(f"{self.where}: key '{msg.split(':')[0]}':{msg.split(':', 1)[1]}")

    def measurements(self, master) -> tuple[np.ndarray, np.ndarray]:
        """``(z, received)`` at the master's current step; z is NaN where not received.

        Computed once per step (the estimators and the logger both read it)."""
        if self._z_step != master.k:
            rec = self.received[master.k]
            self._z = np.where(rec, master.bus[self.meas_slots] + self.additive[master.k],
                               np.nan), rec
            self._z_step = master.k
        return self._z

    def __call__(self, master) -> None:
        u = master.bus[self.control_slots]
        z, rec = self.measurements(master)
        t = master.t
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
                check_finite("estimate", est.x, est.P)
            except FilterDivergence as exc:
                tr.diverged_at = t
                tr.error = str(exc)
            except SystemError as exc:  # Ctrl-C while a compiled (Numba) kernel returned
                if interrupted(exc):
                    raise KeyboardInterrupt from None
                raise
            tr.step_times.append(time.perf_counter() - a)
            tr.nees = self.nees(est, master) if tr.diverged_at is None else float("nan")

    def nees(self, est: Estimator, master) -> float:
        """``e' P^-1 e`` with ``e = x_true - x`` (NaN if ``P`` is singular)."""
        e = master.bus[self.truth_slots] - est.x
        _, _, y, info = _gesv(est.P, e)  # LAPACK gesv, as np.linalg.solve, fewer checks
        return float(e @ y) if info == 0 else float("nan")
