"""Deprecated alias of :mod:`uwcosim.core.errors` (the error hierarchy moved to the core layer
in 0.2; import from ``uwcosim.core.errors``). Kept so that ``from uwcosim.errors import ...``
in user code keeps working."""

from uwcosim.core.errors import (
    AlgebraicLoopError,
    FilterDivergence,
    FilterError,
    FMUError,
    MapError,
    RegressionInputError,
    RunInterrupted,
    ScenarioError,
    UwcosimError,
)

__all__ = ["AlgebraicLoopError", "FMUError", "FilterDivergence", "FilterError", "MapError",
           "RegressionInputError", "RunInterrupted", "ScenarioError", "UwcosimError"]
