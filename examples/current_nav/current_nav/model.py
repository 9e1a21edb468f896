"""The filters' model of the current_nav vehicle, for ``[model] type = "current_nav.model:build"``.

uwcosim calls :func:`build` with the scenario's :class:`uwcosim.models.ModelContext` and the
keys of ``[model.parameters]``; it returns the model :func:`uwcosim.models.from_casadi` makes
from the CasADi equations of :mod:`current_nav.equations`.
"""

from __future__ import annotations

import casadi as ca

from current_nav.equations import STATE_NAMES, beacon_range, vehicle_rates
from uwcosim.models import ModelContext, from_casadi


def build(context: ModelContext, beacons: dict[str, list[float]],
          current_tau_s: float = 600.0, process_noise: str = "process"):
    """The model: the vehicle of :mod:`current_nav.equations` and one measurement row per
    output of ``[model] sensors``: ``*.vx_m``/``*.vy_m`` (a DVL in water track),
    ``RANGER.range_m`` (the range to the beacon ``beacons[RANGER] = [bx, by, dz]``: its
    position and depth difference, by the ranging FMU's name) and ``*.depth_m`` (the map's
    terrain depth under the vehicle).

    ``process_noise``: the ``[noise.NAME]`` source whose six PSDs the filters take (the
    scenario's other sources, e.g. multipath outliers on the range, are unknown to them).
    ``R`` is the sensors' sigmas squared (``context.R``)."""
    # MX symbols: the terrain function is a CasADi B-spline (it has no SX form)
    x = [ca.MX.sym(n) for n in STATE_NAMES]
    u = ca.MX.sym("u", 2)
    rows = []
    for name in context.measurement_names:
        what = name.rsplit(".", 1)[-1]
        if what == "vx_m":
            rows.append(x[2])
        elif what == "vy_m":
            rows.append(x[3])
        elif what == "range_m":
            fmu = name.rsplit(".", 1)[0]
            if fmu not in beacons:
                raise ValueError(f"measurement {name!r}: no beacon {fmu!r} in the parameter "
                                 f"'beacons' (beacons: {', '.join(beacons) or 'none'})")
            bx, by, dz = beacons[fmu]
            rows.append(beacon_range(x[0], x[1], bx, by, dz))
        elif what == "depth_m":
            if context.terrain is None:
                raise ValueError("a depth measurement needs the scenario's [map]")
            rows.append(context.terrain(ca.vertcat(x[0], x[1])))
        else:
            raise ValueError(f"measurement {name!r}: current_nav measures *.vx_m, *.vy_m, "
                             f"*.range_m and *.depth_m")
    if process_noise not in context.noise:
        raise ValueError(f"no [noise.{process_noise}] source (noise: {list(context.noise)})")
    return from_casadi(
        states=x, controls=u, control_names=context.controls,
        f=vehicle_rates(ca.vertcat(*x), u, 0, current_tau_s),   # + w: additive noise
        h=rows, Q=list(context.noise[process_noise]), R=context.R,
        measurements=context.measurement_names, control_psd=context.control_psd)
