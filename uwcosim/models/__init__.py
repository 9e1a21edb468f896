"""Symbolic models (CasADi) shared by the FMUs and the estimators: equations defined once.

The filters' models: the built-in ones (``tan``: :mod:`uwcosim.models.tan`, ``cv``:
:mod:`uwcosim.models.linear`) and a user's, from a few lines of CasADi
(:func:`from_casadi`, :mod:`uwcosim.models.symbolic`) or any object of the
:class:`~uwcosim.models.protocol.StateSpaceModel` protocol, built from a scenario's
:class:`ModelContext` by the function ``[model] type`` names (:mod:`uwcosim.models.builder`).

The three public names are imported on first use: importing a module of the package (the
state names of :mod:`uwcosim.models.states`, say) loads neither CasADi nor the terrain map.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

_EXPORTS = {
    "ModelContext": "uwcosim.models.builder",
    "SymbolicModel": "uwcosim.models.symbolic",
    "from_casadi": "uwcosim.models.symbolic",
}

__all__ = ["ModelContext", "SymbolicModel", "from_casadi"]

if TYPE_CHECKING:
    from uwcosim.models.builder import ModelContext
    from uwcosim.models.symbolic import SymbolicModel, from_casadi


def __getattr__(name: str) -> object:
    if name in _EXPORTS:  # imported on first use
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'uwcosim.models' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
