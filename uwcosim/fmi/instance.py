"""One instantiated FMU: the handle its adapter and its model-exchange integrator call through.

An :class:`Instance` is made by :meth:`~uwcosim.fmi.adapter.FMUAdapter.instantiate` once fmpy
has loaded the FMU's library and instantiated it. It holds fmpy's object (``FMU2Slave``,
``FMU2Model``, ``FMU3Slave`` or ``FMU3Model``: its checked and logged calls serve the setup and
the event mode), the component pointer, the library's FMI functions as C functions (the hot
path calls them directly, without fmpy's status check and call logging, and checks the status
itself) and the one-line errors that name the FMU, its file and its last log message.
:class:`~uwcosim.fmi.solvers.ModelExchange` gets this handle, not the adapter.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.fmi.binding import Binding

#: FMI status codes (fmi2Status / fmi3Status) by value
STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]

T = TypeVar("T")


def status_label(status: int) -> str:
    """``"OK"``, ``"Warning"``... for an FMI status code (the number itself if unknown)."""
    return STATUS[status] if 0 <= status < len(STATUS) else str(status)


class Instance:
    """The loaded library and the component of one FMU instance (see the module docstring)."""

    def __init__(self, fmu: object, name: str, path: Path, fmi3: bool,
                 messages: list[str]) -> None:
        #: fmpy's object of this instance (setup and event-mode calls)
        self.fmu = fmu
        #: the component pointer: the first argument of every FMI function
        self.component = fmu.component
        self.name = name
        self.path = Path(path)
        self.fmi3 = fmi3
        #: the FMU's log messages (the adapter's logger callback appends to this list)
        self.messages = messages

    def function(self, name: str) -> Callable[..., int]:
        """The FMI function ``name`` (``fmi2SetReal``, ``fmi3DoStep``...) of the FMU's library:
        the C function with the argument types fmpy declared when it loaded the library."""
        return getattr(self.fmu.dll, name)

    def _last_message(self) -> str:
        return f": {self.messages[-1]}" if self.messages else ""

    def check(self, status: int, what: str, t: float) -> None:
        """:class:`FMUError` if ``status`` (of the call ``what`` at time ``t``) is worse than
        Warning."""
        if status > 1:
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): {what} returned "
                           f"{status_label(status)} at t={t:g}{self._last_message()}")

    def guard(self, what: str, fn: Callable[[], T], t: float) -> T:
        """``fn()`` (fmpy calls), any error but our own as one :class:`FMUError` line."""
        try:
            return fn()
        except (FMUError, ScenarioError):
            raise
        except Exception as exc:  # noqa: BLE001 - fmpy's FMICallException and friends
            raise FMUError(f"FMU '{self.name}' ({self.path.name}): {what} failed at t={t:g} "
                           f"({exc}){self._last_message()}") from None

    def reason(self, what: str) -> str:
        """Why the FMU asked to stop: ``what`` (``terminateSimulation``, ``fmi2Terminated``)
        and the FMU's last log message."""
        return f"{what}: {self.messages[-1]}" if self.messages else what

    def resolve(self, b: Binding) -> None:
        """The get/set functions of ``b``'s typed groups (named until the library is loaded)."""
        for g in b.groups:
            if isinstance(g.get, str):
                g.get, g.set = self.function(g.get), self.function(g.set)
