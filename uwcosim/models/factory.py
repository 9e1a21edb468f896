"""Build the filters' state-space model of a scenario (``[model]``) from its truth settings.

By default the filters are matched to the truth: ``Q`` from the ``[noise]`` PSDs and ``R`` from
the sensors' ``sigma``; ``model.q_psd`` overrides the former. The scenario was validated when
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


def build_model(loaded, bathymetry: Bathymetry | None):
    """The filters' model of a validated scenario (``[model]``)."""
    spec = loaded.spec
    m = spec.model
    q = m.q_psd if m.q_psd is not None else [p for nz in spec.noise.values() for p in nz.psd]
    sensors = [spec.sensors[s] for s in m.sensors]
    names = tuple(o for s in sensors for o in s.outputs)
    if m.kind == "tan":
        from uwcosim.models.tan import tan_model

        depth = len(sensors) == 2
        return tan_model(q, sensors[0].sigma, sensors[1].sigma[0] if depth else None,
                         bathymetry if depth else None, names)
    from uwcosim.models.linear import constant_velocity_model

    r = np.array([sg**2 for s in sensors for sg in s.sigma])
    return constant_velocity_model(q_psd=q, R=np.diag(r), measurement_names=names)
