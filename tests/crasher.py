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

from pathlib import Path

import casadi as ca

from uwcosim.fmu import specs
from uwcosim.fmu.specs import ModelSpec, Var

NAME = "Crasher"
HOOKS = Path(__file__).resolve().parent / "data" / "crasher" / "crash.c"
#: ``mode`` and ``where`` codes (as in crash.c)
MODES = {"segfault": 1, "exit": 2, "abort": 3, "spin": 4, "sleep": 5}
WHERE = {"doStep": 1, "get": 2, "init": 3}


def _equations(x, u, p, z):
    return ca.SX(0, 1), u[0]


def crasher_spec() -> ModelSpec:
    return ModelSpec(
        name=NAME,
        description="Test model y = u that segfaults, exits, aborts, spins or sleeps at a "
                    "given time, in doStep, an output getter or initialization",
        equations=_equations,
        inputs=(Var("u", None, 0.0, "Input"),),
        params=(
            Var("mode", None, 0.0, "0 none, 1 segfault, 2 exit(exit_code), 3 abort, 4 spin, "
                "5 sleep", tunable=True),
            Var("where", None, 0.0, "1 doStep, 2 output getter, 3 initialization",
                tunable=True),
            Var("exit_code", None, 0.0, "The status exit() is called with", tunable=True),
            Var("crash_time", "s", 0.0, "The fault happens once time >= crash_time",
                tunable=True),
        ),
        outputs=(Var("y", None, 0.0, "Output (= u)"),),
        hooks=HOOKS,
    )


def register() -> None:
    """Make ``Crasher`` a model of the FMU builder in this process."""
    specs.MODELS.setdefault(NAME, crasher_spec)
