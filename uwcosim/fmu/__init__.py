"""FMU tools: the project's FMUs, built from the CasADi equations, and checks of any FMU.

- :mod:`~uwcosim.fmu.specs` describes each of the project's models once (variables, units,
  start values, equations); :mod:`~uwcosim.fmu.codegen` makes their C sources and
  :mod:`~uwcosim.fmu.model_description` their ``modelDescription.xml``; the C template is in
  ``templates/``;
- :func:`build_fmus` / :func:`build_fmu` (:mod:`uwcosim.fmu.build`) build ``fmus/<Model>.fmu``
  (FMI 3.0) and ``fmus/<Model>_fmi2.fmu`` (FMI 2.0), each with ModelExchange and CoSimulation
  (``uwcosim fmu build``);
- :func:`fmu_info` / :func:`validate` (:mod:`uwcosim.fmu.info`) describe and check any FMU
  (``uwcosim fmu info|validate``);
- :func:`~uwcosim.fmu.check.check_fmu` (:mod:`uwcosim.fmu.check`): can an FMU play a role,
  the vehicle's with a smoke run (``uwcosim fmu check``).

Imports are lazy so that ``python -m uwcosim.fmu.build`` runs cleanly.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "archive_name": "uwcosim.fmu.build",
    "build_fmu": "uwcosim.fmu.build",
    "build_fmus": "uwcosim.fmu.build",
    "fmu_info": "uwcosim.fmu.info",
    "validate": "uwcosim.fmu.info",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'uwcosim.fmu' has no attribute {name!r}")
