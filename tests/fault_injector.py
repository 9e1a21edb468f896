"""The test model FaultInjector: ``y = u`` that fails, outputs NaN or hangs at given times.

Its fault behaviour is C code of the tests (``tests/data/fault_injector/faults.c``, the hooks of
the FMU template); the shipped FMUs (``uwcosim fmu build``) have none. :func:`register` adds
the model to :data:`uwcosim.fmu.specs.MODELS` for the test session (``tests/conftest.py``), so
the FMU builds of the tests (``fmus/``, ``fmu_dir``) include ``FaultInjector.fmu`` and
``FaultInjector_fmi2.fmu``.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca

from uwcosim.fmu import specs
from uwcosim.fmu.specs import ModelSpec, Var

NAME = "FaultInjector"
HOOKS = Path(__file__).resolve().parent / "data" / "fault_injector" / "faults.c"


def _equations(x, u, p, z):
    return ca.SX(0, 1), u[0]


def fault_injector_spec() -> ModelSpec:
    never = 1e300
    return ModelSpec(
        name=NAME,
        description="Test model y = u that fails, outputs NaN or hangs at given times "
                    "(time >= threshold, compared with a relative tolerance of 1e-9)",
        equations=_equations,
        inputs=(Var("u", None, 0.0, "Input"),),
        params=(
            Var("fail_time", "s", never, "Calls return Error when time >= fail_time",
                tunable=True),
            Var("nan_time", "s", never, "Output is NaN when time >= nan_time", tunable=True),
            Var("hang_time", "s", never, "doStep sleeps hang_seconds when time >= hang_time",
                tunable=True),
            Var("hang_seconds", "s", 3600.0, "Duration of the simulated hang", tunable=True),
        ),
        outputs=(Var("y", None, 0.0, "Output (= u)"),),
        hooks=HOOKS,
    )


def register() -> None:
    """Make ``FaultInjector`` a model of the FMU builder in this process."""
    specs.MODELS.setdefault(NAME, fault_injector_spec)
