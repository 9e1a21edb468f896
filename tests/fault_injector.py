"""The test model FaultInjector: ``y = u`` that fails, outputs NaN or hangs at given times.

Its fault behaviour is C code of the tests (``tests/data/fault_injector/faults.c``, the hooks of
the FMU template); the shipped FMUs (``uwcosim fmu build``) have none. :func:`register` adds
the model to :data:`uwcosim.fmu.specs.MODELS` for the test session (``tests/conftest.py``), so
the FMU builds of the tests (``fmus/``, ``fmu_dir``) include ``FaultInjector.fmu`` and
``FaultInjector_fmi2.fmu``.
"""

from __future__ import annotations

try:
    from hooked_model import DATA, hooked_spec
    from hooked_model import register as register_model
except ImportError:  # pragma: no cover - imported as tests.<module> from the project root
    from tests.hooked_model import DATA, hooked_spec
    from tests.hooked_model import register as register_model

from uwcosim.fmu.specs import ModelSpec, Var

NAME = "FaultInjector"
HOOKS = DATA / "fault_injector" / "faults.c"


def fault_injector_spec() -> ModelSpec:
    never = 1e300
    return hooked_spec(
        NAME,
        "Test model y = u that fails, outputs NaN or hangs at given times (time >= threshold, "
        "compared with a relative tolerance of 1e-9)",
        (
            Var("fail_time", "s", never, "Calls return Error when time >= fail_time",
                tunable=True),
            Var("nan_time", "s", never, "Output is NaN when time >= nan_time", tunable=True),
            Var("hang_time", "s", never, "doStep sleeps hang_seconds when time >= hang_time",
                tunable=True),
            Var("hang_seconds", "s", 3600.0, "Duration of the simulated hang", tunable=True),
        ),
        HOOKS,
    )


def register() -> None:
    """Make ``FaultInjector`` a model of the FMU builder in this process."""
    register_model(NAME, fault_injector_spec)
