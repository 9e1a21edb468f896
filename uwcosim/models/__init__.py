"""Symbolic models (CasADi) shared by the FMUs and the estimators: equations defined once.

The filters' models: the built-in ones (``tan``: :mod:`uwcosim.models.tan`, ``cv``:
:mod:`uwcosim.models.linear`) and a user's, from a few lines of CasADi
(:func:`from_casadi`, :mod:`uwcosim.models.symbolic`) or any object of the
:class:`~uwcosim.models.protocol.StateSpaceModel` protocol, built from a scenario's
:class:`ModelContext` by the function ``[model] type`` names (:mod:`uwcosim.models.builder`).
"""

from uwcosim.models.builder import ModelContext
from uwcosim.models.symbolic import SymbolicModel, from_casadi

__all__ = ["ModelContext", "SymbolicModel", "from_casadi"]
