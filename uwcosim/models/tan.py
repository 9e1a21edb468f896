"""The terrain-aided navigation model of seed 000 Example 2 for the filters.

State ``[x, y, vx, vy]``, control ``[psi, a]``, process noise on all four states (eq. 54);
measurements ``[vx, vy]`` from the DVL and, with a map, the terrain depth ``h_d(x, y)``
(eq. 55). Built from the same CasADi expressions as the FMUs.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from uwcosim.models.bathymetry import Bathymetry
from uwcosim.models.statespace import CasadiModel
from uwcosim.models.vehicle import STATE_NAMES, vehicle_ode

DVL_NAMES = ("dvl.vx_m", "dvl.vy_m")
DEPTH_NAME = "sounder.depth_m"


def tan_model(
    q_psd,
    dvl_sigma,
    depth_sigma: float | None = None,
    terrain: Bathymetry | None = None,
    measurement_names: tuple[str, ...] | None = None,
) -> CasadiModel:
    """TAN model; without ``terrain`` only the DVL is measured (dead-reckoning variant)."""
    x = ca.MX.sym("x", 4)
    rows = [x[2], x[3]]
    r = list(np.broadcast_to(np.asarray(dvl_sigma, dtype=float), (2,)) ** 2)
    names = list(DVL_NAMES)
    if terrain is not None:
        if depth_sigma is None:
            raise ValueError("depth_sigma is required with a terrain map")
        rows.append(terrain.casadi_function()(x[:2]))
        r.append(float(depth_sigma) ** 2)
        names.append(DEPTH_NAME)
    h = ca.Function("h", [x], [ca.vertcat(*rows)], ["x"], ["z"])
    model = CasadiModel(
        vehicle_ode(), h, q_psd, np.array(r), STATE_NAMES,
        tuple(measurement_names) if measurement_names else tuple(names),
    )
    model.terrain = terrain
    return model
