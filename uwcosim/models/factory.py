"""Build the filters' state-space model of a scenario (``[model]``) from its truth settings.

By default the filters are matched to the truth: ``Q`` from the ``[noise]`` PSDs and ``R`` from
the sensors' ``sigma``; ``model.q_psd`` overrides the former. ``model.control_noise`` names the
``[noise]`` source on the controls whose PSDs the TAN model's ``Q`` includes (not part of the
default ``q_psd``). The scenario was validated when
it was loaded (:func:`uwcosim.scenario.validate.reference_problems`: sensors, sigma per output,
the number of PSDs and the sensors the TAN model takes, a map for a depth sensor).

This is where the implementation is chosen, explicitly: ``kind = "tan"`` gives the closed-form
numpy :class:`~uwcosim.models.tan.TANModel` (its CasADi form, from the same expressions as the
FMUs, is ``model.symbolic``), ``kind = "cv"`` the :class:`~uwcosim.models.linear.LinearModel`.
The filters use the model they are given and import nothing from :mod:`uwcosim.models`.
"""

from __future__ import annotations

import numpy as np

from uwcosim.models.terrain import Bathymetry
from uwcosim.scenario.schema import model_noise_psds


def build_model(loaded, bathymetry: Bathymetry | None):
    """The filters' model of a validated scenario (``[model]``)."""
    spec = loaded.spec
    m = spec.model
    q, qc = model_noise_psds(spec)
    sensors = [spec.sensors[s] for s in m.sensors]
    names = tuple(o for s in sensors for o in s.outputs)
    if m.kind == "tan":
        from uwcosim.models.tan import tan_model

        depth = len(sensors) == 2
        return tan_model(q, sensors[0].sigma, sensors[1].sigma[0] if depth else None,
                         bathymetry if depth else None, names, control_psd=qc)
    from uwcosim.models.linear import constant_velocity_model

    r = np.array([sg**2 for s in sensors for sg in s.sigma])
    return constant_velocity_model(q_psd=q, R=np.diag(r), measurement_names=names)
