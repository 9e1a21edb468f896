"""Build the filters' state-space model of a scenario (``[model]``) from its truth settings.

By default the filters are matched to the truth: ``Q`` from the ``[noise]`` PSDs and ``R`` from
the sensors' ``sigma``; ``model.q_psd`` overrides the former.
"""

from __future__ import annotations

import numpy as np

from uwcosim.errors import ScenarioError
from uwcosim.models.bathymetry import Bathymetry


def build_model(loaded, bathymetry: Bathymetry | None):
    spec = loaded.spec
    m = spec.model
    where = f"{loaded.path}: key 'model"
    if m is None:
        raise ScenarioError(f"{loaded.path}: key 'model': required when estimators are given")
    q = m.q_psd if m.q_psd is not None else [p for nz in spec.noise.values() for p in nz.psd]
    sensors = []
    for s in m.sensors:
        if s not in spec.sensors:
            raise ScenarioError(f"{where}.sensors': unknown sensor {s!r} "
                                f"(sensors: {', '.join(spec.sensors)})")
        sensors.append((s, spec.sensors[s]))
    names = tuple(o for _, s in sensors for o in s.outputs)
    for sname, s in sensors:
        if len(s.sigma) != len(s.outputs):
            raise ScenarioError(f"{loaded.path}: key 'sensors.{sname}.sigma': the filter model "
                                f"needs one sigma per output ({len(s.outputs)})")
    if m.kind == "tan":
        from uwcosim.models.tan import tan_model

        if len(q) != 4:
            raise ScenarioError(f"{where}.q_psd': the TAN model needs 4 process-noise PSDs "
                                f"(x, y, vx, vy), got {len(q)}")
        shapes = [len(s.outputs) for _, s in sensors]
        if shapes not in ([2], [2, 1]):
            raise ScenarioError(f"{where}.sensors': the TAN model takes a 2-output velocity "
                                f"sensor and optionally a 1-output depth sensor, got {shapes}")
        depth_sigma = sensors[1][1].sigma[0] if len(sensors) == 2 else None
        terrain = bathymetry if len(sensors) == 2 else None
        if len(sensors) == 2 and bathymetry is None:
            raise ScenarioError(f"{loaded.path}: key 'map': a depth sensor needs a map")
        return tan_model(q, sensors[0][1].sigma, depth_sigma, terrain, names)
    if m.kind == "cv":
        from uwcosim.models.cv_model import constant_velocity_model

        r = np.array([sg**2 for _, s in sensors for sg in s.sigma])
        return constant_velocity_model(q_psd=q, R=np.diag(r), measurement_names=names)
    raise ScenarioError(f"{where}.kind': unknown model kind {m.kind!r}")
