"""Test models ``y = u`` whose fault behaviour is C code of the tests (the hooks of the FMU
template): what :mod:`crasher` and :mod:`fault_injector` share.

:func:`hooked_spec` is the model (one input ``u``, one output ``y = u``, no state, the given
tunable parameters and C hooks ``tests/data/<folder>/<file>``); :func:`register` adds a model
to :data:`uwcosim.fmu.specs.MODELS` for the test session (``tests/conftest.py``), so the FMU
builds of the tests (``fmus/``, ``fmu_dir``) include ``<NAME>.fmu`` and ``<NAME>_fmi2.fmu``.
The shipped FMUs (``uwcosim fmu build``) have none of these models.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import casadi as ca

from uwcosim.fmu import specs
from uwcosim.fmu.specs import ModelSpec, Var

DATA = Path(__file__).resolve().parent / "data"


def _equations(x, u, p, z):
    return ca.SX(0, 1), u[0]


def hooked_spec(name: str, description: str, params: tuple[Var, ...], hooks: Path
                ) -> ModelSpec:
    """The model ``name``: ``y = u`` with the tunable ``params`` and the C ``hooks``."""
    return ModelSpec(
        name=name,
        description=description,
        equations=_equations,
        inputs=(Var("u", None, 0.0, "Input"),),
        params=params,
        outputs=(Var("y", None, 0.0, "Output (= u)"),),
        hooks=hooks,
    )


def register(name: str, spec: Callable[[], ModelSpec]) -> None:
    """Make the model ``name`` (built by ``spec``) a model of the FMU builder in this process."""
    specs.MODELS.setdefault(name, spec)
