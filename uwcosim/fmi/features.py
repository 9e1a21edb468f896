"""What an FMU needs that the master does not do, from its model description alone.

The master runs FMI 2.0 and 3.0 FMUs through their Co-Simulation or Model Exchange interface,
in step mode (:mod:`uwcosim.fmi.adapter`). :func:`missing_features` says, one line each, what
else an FMU needs to run:

- an FMI 3 FMU with **ScheduledExecution** only (no Co-Simulation, no Model Exchange): the
  master has no scheduler for model partitions;
- an FMU with **FMI 3 clocks** (``Clock`` variables; clocked partitions, co-simulation event
  mode, FMI 3.0 section 5): the master does not tick clocks, so their partitions would never
  run.

``uwcosim fmu info`` and ``fmu check`` list them, and the master refuses such an FMU when it is
opened (one line naming the feature), before anything runs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription

#: the interfaces the master runs, and their model description attributes
RUN_INTERFACES = {"cs": "coSimulation", "me": "modelExchange"}


def clock_variables(md: ModelDescription) -> list[str]:
    """Names of the FMU's Clock variables (FMI 3)."""
    return [v.name for v in md.modelVariables if v.type == "Clock"]


def interfaces(md: ModelDescription) -> list[str]:
    """Every interface the FMU declares: ``cs``, ``me`` and ``se`` (ScheduledExecution)."""
    out = [k for k, attr in RUN_INTERFACES.items() if getattr(md, attr, None) is not None]
    if getattr(md, "scheduledExecution", None) is not None:
        out.append("se")
    return out


def missing_features(md: ModelDescription) -> list[str]:
    """One line per feature the FMU needs that the master does not support (empty: none)."""
    out = []
    have = interfaces(md)
    if "se" in have and not set(have) & set(RUN_INTERFACES):
        out.append("it needs scheduled execution (FMI 3 ScheduledExecution is its only "
                   "interface): the master runs co-simulation and model exchange only")
    elif not set(have) & set(RUN_INTERFACES):
        out.append("it declares neither co-simulation nor model exchange")
    clocks = clock_variables(md)
    if clocks:
        shown = ", ".join(clocks[:4]) + (f" and {len(clocks) - 4} more" if len(clocks) > 4
                                         else "")
        out.append(f"it has FMI 3 clocks ({shown}): clocked partitions and co-simulation "
                   f"event mode (FMI 3.0 section 5) are not supported by the master")
    return out
