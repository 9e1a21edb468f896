"""The co-simulation master: FMU adapters, connection graph, sources and the stepping loop.

``from uwcosim.master import Master, System, FMU, Control, Noise, Sensor`` builds and runs a
system in code (see :mod:`uwcosim.master.system`); ``Master.measurement()`` gives the step's
:class:`Measurement` from the master's :class:`SensorBank`. The names are imported on first
use.
"""

_EXPORTS = {"Master": "uwcosim.master.master", "System": "uwcosim.master.system",
            "FMU": "uwcosim.master.system", "Control": "uwcosim.master.system",
            "Noise": "uwcosim.master.system", "Sensor": "uwcosim.master.system",
            "Measurement": "uwcosim.master.measurement",
            "SensorBank": "uwcosim.master.measurement"}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'uwcosim.master' has no attribute {name!r}")
