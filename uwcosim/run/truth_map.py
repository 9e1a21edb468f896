"""The truth side's seafloor of a scenario with ``[map.truth]``: :func:`scenario_truth_map`.

Without ``[map.truth]`` the DepthSounder FMU reads the filters' map (the same ``map.bin``, so
the logs are those of earlier versions). With it, the FMU reads ``map_truth.bin``: the map of
:func:`uwcosim.models.truth_map.truth_bathymetry`, whose random fields come from the run's
seeded streams ``map-truth:fine-relief`` and ``map-truth:survey-error`` (:mod:`uwcosim.core.rng`);
the filters keep ``[map]``. The truth's grid defaults to the filters' map's extent and
resolution. The tide or depth-bias ``offset`` becomes a control of the sounder
(:func:`offset_control`, added by :func:`uwcosim.scenario.system.to_system`).
"""

from __future__ import annotations

from uwcosim.core.rng import stream
from uwcosim.models.terrain import Bathymetry
from uwcosim.models.truth_map import truth_bathymetry
from uwcosim.run.factory import build_map
from uwcosim.scenario.loaded import LoadedScenario

#: the truth's map in a run directory (the DepthSounder's mapFile) when it has [map.truth]
TRUTH_MAP_FILE = "map_truth.bin"


def scenario_truth_map(loaded: LoadedScenario, survey: Bathymetry,
                       seed: int) -> Bathymetry | None:
    """The truth's map of run ``seed`` (None without ``[map.truth]``: the truth reads
    ``survey``, the filters' map)."""
    m = loaded.spec.map
    t = m.truth if m is not None else None
    if t is None:
        return None
    base = survey
    if t.base_keys():  # another seafloor: [map] with the truth's overrides
        update = {**t.base_keys(), "truth": None}
        for k in ("extent", "resolution"):
            if getattr(t, k) is not None:
                update[k] = getattr(t, k)
        base = build_map(loaded, m.model_copy(update=update))
    extent = t.extent if t.extent is not None else survey.extent
    resolution = t.resolution if t.resolution is not None else survey.dx
    se = t.survey_error
    return truth_bathymetry(
        base, extent, resolution, fine_relief_m=t.fine_relief_m, fine_scale_m=t.fine_scale_m,
        survey_std_m=se.std_m if se is not None else 0.0,
        survey_correlation_m=se.correlation_m if se is not None else 500.0,
        fine_rng=stream(seed, "map-truth:fine-relief"),
        survey_rng=stream(seed, "map-truth:survey-error"))
