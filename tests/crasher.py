"""The test model Crasher: ``y = u`` whose library ends or stalls the process it runs in.

A segmentation fault, ``exit(n)``, ``abort()``, a busy loop or an hour's sleep, in ``doStep``, in
an output getter or at initialization, once the time reaches ``crash_time`` (parameters
``mode``, ``where``, ``exit_code``, ``crash_time``), or when the library is loaded (environment
variable ``UWC_CRASHER_AT_LOAD``). The C code is the tests' (``tests/data/crasher/crash.c``,
the hooks of the FMU template; its header says the codes). :func:`register` adds the model to
:data:`uwcosim.fmu.specs.MODELS` for the test session (``tests/conftest.py``), so the FMU builds
of the tests include ``Crasher.fmu`` and ``Crasher_fmi2.fmu``.
"""

from __future__ import annotations

try:
    from hooked_model import DATA, hooked_spec
    from hooked_model import register as register_model
except ImportError:  # pragma: no cover - imported as tests.<module> from the project root
    from tests.hooked_model import DATA, hooked_spec
    from tests.hooked_model import register as register_model

from uwcosim.fmu.specs import ModelSpec, Var

NAME = "Crasher"
HOOKS = DATA / "crasher" / "crash.c"
#: ``mode`` and ``where`` codes (as in crash.c)
MODES = {"segfault": 1, "exit": 2, "abort": 3, "spin": 4, "sleep": 5}
WHERE = {"doStep": 1, "get": 2, "init": 3}


def crasher_spec() -> ModelSpec:
    return hooked_spec(
        NAME,
        "Test model y = u that segfaults, exits, aborts, spins or sleeps at a given time, in "
        "doStep, an output getter or initialization",
        (
            Var("mode", None, 0.0, "0 none, 1 segfault, 2 exit(exit_code), 3 abort, 4 spin, "
                "5 sleep", tunable=True),
            Var("where", None, 0.0, "1 doStep, 2 output getter, 3 initialization",
                tunable=True),
            Var("exit_code", None, 0.0, "The status exit() is called with", tunable=True),
            Var("crash_time", "s", 0.0, "The fault happens once time >= crash_time",
                tunable=True),
        ),
        HOOKS,
    )


def register() -> None:
    """Make ``Crasher`` a model of the FMU builder in this process."""
    register_model(NAME, crasher_spec)
