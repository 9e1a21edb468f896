"""The system layer: the co-simulation master, its input and what observes it.

The system's types (:mod:`uwcosim.master.system`: ``System``, ``FMU``, ``Control``, ``Noise``,
``Sensor``, the loss models), the connection graph (``graph``: order, algebraic loops), the
algorithms by name and the units of FMUs stepped together (``algorithms``), the values
exchanged inside a unit and the loops' Newton solver (``loops``), one FMU on the bus (``node``),
the sources (``sources``), the sensors and measurements (``measurement``), the wiring checks
and the bus layout (``checks``: arrays, integer ranges, observed locals), the stepping loop
(``master``) and the observer protocol (``observer``). It imports only :mod:`uwcosim.core`
and :mod:`uwcosim.fmi`, and knows no scenario.

``from uwcosim.master import Master, System, FMU, Control, Noise, Sensor`` builds and runs a
system in code; ``Master.measurement()`` gives the step's :class:`Measurement` from the
master's :class:`SensorBank`. The names are imported on first use.
"""

import importlib

_EXPORTS = {
    **{name: "uwcosim.master.system" for name in (
        "System", "FMU", "Control", "Noise", "Sensor", "BernoulliLoss", "GilbertElliottLoss")},
    "Master": "uwcosim.master.master",
    "Measurement": "uwcosim.master.measurement", "SensorBank": "uwcosim.master.measurement",
    **{name: "uwcosim.master.observer" for name in ("Observer", "StepView", "Callback")},
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:  # imported on first use: importing the package stays light
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'uwcosim.master' has no attribute {name!r}")
