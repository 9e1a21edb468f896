"""A loaded scenario as the master's input: :func:`to_system`.

The master knows no scenario (:mod:`uwcosim.master`): it takes a
:class:`~uwcosim.master.system.System`. The scenario's FMU, control, noise and sensor records
are already the system's own types (the schema reuses them), so the conversion copies them and
adds the time grid, the seed, the measured sensors (``model.sensors``), the variables to read
although they are not outputs (``observe``: every ``[log] signals`` entry without a wildcard,
and ``model.truth``: locals and states are logged by their exact names), the folder relative
paths are resolved against and the file error messages name. Two things are resolved here,
above the master: a control read from a file (``[controls.NAME] file``) becomes its table
(:func:`uwcosim.scenario.control_files.control_table`), and ``[geo] start`` becomes start
values of the truth's position (:func:`uwcosim.scenario.geo.start_values`). A ``[map.truth]
offset`` (tide or depth bias) becomes the control ``map_truth_offset`` of the sounder's
``offset_h`` input (:func:`truth_offset_control`).
"""

from __future__ import annotations

import dataclasses

from uwcosim.core.errors import ScenarioError
from uwcosim.master.system import Control, System
from uwcosim.scenario.control_files import control_table
from uwcosim.scenario.geo import scenario_frame, start_values
from uwcosim.scenario.load import LoadedScenario
from uwcosim.scenario.schema import Scenario


def to_system(loaded: LoadedScenario) -> System:
    """The system of a loaded scenario."""
    spec = loaded.spec
    where = str(loaded.path)
    if spec.replay is not None:
        raise ScenarioError(f"{where}: key 'replay': a replay scenario has no FMUs to "
                            f"co-simulate (uwcosim run replays it)")
    fmus = {name: dataclasses.replace(f) for name, f in spec.fmus.items()}
    geo_start = start_values(loaded, scenario_frame(loaded)) \
        if getattr(spec, "geo", None) is not None else {}
    for fmu, values in geo_start.items():
        fmus[fmu] = dataclasses.replace(fmus[fmu], start={**fmus[fmu].start, **values})
    controls = {name: control_table(name, c, loaded.base_dir, where)
                for name, c in spec.controls.items()}
    offset = truth_offset_control(spec)
    if offset is not None:
        controls[OFFSET_CONTROL] = offset
    return System(
        fmus=fmus,
        step=spec.run.step, duration=spec.run.duration,
        start_time=spec.run.start_time, seed=spec.run.seed,
        connections=[tuple(c) for c in spec.connections], controls=controls,
        noise=dict(spec.noise), sensors=dict(spec.sensors),
        measured=list(spec.model.sensors) if spec.model is not None else [],
        observe=[p for p in spec.log.signals if not any(c in p for c in "*?")]
        + (list(spec.model.truth) if spec.model is not None else []),
        stop_on_terminate=spec.run.stop_on_terminate, algorithm=spec.run.algorithm,
        algebraic_loops=spec.run.algebraic_loops, loop_tolerance=spec.run.loop_tolerance,
        loop_max_iterations=spec.run.loop_max_iterations, name=spec.name,
        base_dir=loaded.base_dir, where=str(loaded.path),
        fmu_max_unpacked_mb=spec.run.fmu_max_unpacked_mb,
    )


#: the control of a [map.truth] offset (logged as controls.map_truth_offset)
OFFSET_CONTROL = "map_truth_offset"


def truth_offset_control(spec: Scenario) -> Control | None:
    """The tide or depth-bias offset of ``[map.truth]`` as a control (None without one): its
    table on ``offset_input``, by default ``offset_h`` of the FMU of ``map.fmu_parameter``."""
    m = spec.map
    t = m.truth if m is not None else None
    if t is None or t.offset is None:
        return None
    target = t.offset_input or f"{m.fmu_parameter.partition('.')[0]}.offset_h"
    return Control(target=target, table=[tuple(r) for r in t.offset])
