"""The project's FMUs: generated from the CasADi equations, compiled with a C template.

- :func:`build_fmus` / :func:`build_fmu` (:mod:`uwcosim.fmu.build`) build ``fmus/<Model>.fmu``
  (FMI 3.0) and ``fmus/<Model>_fmi2.fmu`` (FMI 2.0), each with ModelExchange and CoSimulation;
- :func:`fmu_info` / :func:`validate` (:mod:`uwcosim.fmu.info`) describe and check any FMU.

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
