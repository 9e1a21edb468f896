"""The filters' side of a scenario: its bathymetry map (:func:`scenario_map`) and the filters'
state-space model (:func:`build_model`, from ``[model]`` and the truth settings).

By default the filters are matched to the truth: ``Q`` from the ``[noise]`` PSDs and ``R`` from
the sensors' ``sigma``; ``model.q_psd`` overrides the former. ``model.control_noise`` names the
``[noise]`` source on the controls whose PSDs the TAN model's ``Q`` includes (not part of the
default ``q_psd``). The scenario was validated when
it was loaded (:func:`uwcosim.scenario.validate.reference_problems`: sensors, sigma per output,
the number of PSDs and the sensors the TAN model takes, a map for a depth sensor).

This is where the implementation is chosen, explicitly: ``kind = "tan"`` gives the closed-form
numpy :class:`~uwcosim.models.tan.TANModel` (its CasADi form, from the same expressions as the
FMUs, is ``model.symbolic``), ``kind = "cv"`` the :class:`~uwcosim.models.linear.LinearModel`.
The filters use the model they are given and see it only through
:class:`uwcosim.models.protocol.StateSpaceModel`.
"""

from __future__ import annotations

import numpy as np

from uwcosim.models.linear import LinearModel, constant_velocity_model
from uwcosim.models.tan import TANModel, tan_model
from uwcosim.models.terrain import Bathymetry, load_map, synthetic_bathymetry
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.schema import model_noise_psds


def scenario_map(loaded: LoadedScenario) -> Bathymetry | None:
    """The bathymetry of the scenario's ``[map]`` (None without one)."""
    m = loaded.spec.map
    if m is None:
        return None
    if m.kind == "file":  # a lat/lon file: projected to the frame of [geo] origin or its centre
        geo = getattr(loaded.spec, "geo", None)
        origin = (geo.origin.lat, geo.origin.lon) if geo is not None and geo.origin else None
        res = m.resolution if "resolution" in m.model_fields_set else None
        return load_map(loaded.resolve(m.file), m.variable, origin=origin,
                        projection=m.projection, resolution=res)
    return synthetic_bathymetry(m.seed, m.extent, m.resolution, relief_std=m.relief_std)


def build_model(loaded: LoadedScenario, bathymetry: Bathymetry | None) -> TANModel | LinearModel:
    """The filters' model of a validated scenario (``[model]``)."""
    spec = loaded.spec
    m = spec.model
    q, qc = model_noise_psds(spec)
    sensors = [spec.sensors[s] for s in m.sensors]
    names = tuple(o for s in sensors for o in s.outputs)
    if m.kind == "tan":
        depth = len(sensors) == 2
        return tan_model(q, sensors[0].sigma, sensors[1].sigma[0] if depth else None,
                         bathymetry if depth else None, names, control_psd=qc)
    r = np.array([sg**2 for s in sensors for sg in s.sigma])
    return constant_velocity_model(q_psd=q, R=np.diag(r), measurement_names=names)
