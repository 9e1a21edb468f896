"""A loaded scenario as the master's input: :func:`to_system`.

The master knows no scenario (:mod:`uwcosim.master`): it takes a
:class:`~uwcosim.master.system.System`. The scenario's FMU, control, noise and sensor records
are already the system's own types (the schema reuses them), so the conversion copies them and
adds the time grid, the seed, the measured sensors (``model.sensors``), the variables to read
although they are not outputs (``observe``: every ``[log] signals`` entry without a wildcard,
and ``model.truth``: locals and states are logged by their exact names), the folder relative
paths are resolved against and the file error messages name.
"""

from __future__ import annotations

import dataclasses

from uwcosim.master.system import System
from uwcosim.scenario.load import LoadedScenario


def to_system(loaded: LoadedScenario) -> System:
    """The system of a loaded scenario."""
    spec = loaded.spec
    return System(
        fmus={name: dataclasses.replace(f) for name, f in spec.fmus.items()},
        step=spec.run.step, duration=spec.run.duration,
        start_time=spec.run.start_time, seed=spec.run.seed,
        connections=[tuple(c) for c in spec.connections], controls=dict(spec.controls),
        noise=dict(spec.noise), sensors=dict(spec.sensors),
        measured=list(spec.model.sensors) if spec.model is not None else [],
        observe=[p for p in spec.log.signals if not any(c in p for c in "*?")]
        + (list(spec.model.truth) if spec.model is not None else []),
        stop_on_terminate=spec.run.stop_on_terminate, algorithm=spec.run.algorithm,
        algebraic_loops=spec.run.algebraic_loops, loop_tolerance=spec.run.loop_tolerance,
        loop_max_iterations=spec.run.loop_max_iterations, name=spec.name,
        base_dir=loaded.base_dir, where=str(loaded.path),
    )
