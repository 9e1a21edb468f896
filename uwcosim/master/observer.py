"""What watches a co-simulation: the :class:`Observer` protocol and the :class:`StepView` it gets.

The master knows nothing of what records or filters its run (as libcosim's observers and the
collectors of ``particles`` are outside their algorithms): it calls each observer's
``on_step(k, view)`` in one place, :meth:`uwcosim.master.master.Master.notify`, in the order
the observers were added, once at the start time (``k = 0``, at the end of
:meth:`~uwcosim.master.master.Master.initialize`) and after every completed step ``k``
(``t = t0 + k*h``). An observer that raises stops the run there (the master's state is that
of step ``k``). The view is read-only: the bus is a non-writable array, the measurement the
sensor bank's record of step ``k``.

Whoever composes a run decides the order (:func:`uwcosim.run.simulate.simulate`: estimator
bank, log recorder, density snapshots, progress, signal guard).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from uwcosim.master.measurement import Measurement


class SteppedSystem(Protocol):
    """What a :class:`StepView` reads: the master's state (``k``, ``t = t0 + k*h``, the bus and
    its names, the integer side bus and the text values), its measurement and typed values."""

    k: int
    h: float
    bus: np.ndarray
    xbus: np.ndarray
    slots: dict[str, int]
    exact: dict[int, tuple[int, bool]]
    text: dict[int, str]

    @property
    def t(self) -> float: ...
    @property
    def native(self) -> dict[int, object]: ...
    def signal(self, name: str) -> float: ...
    def measurement(self) -> Measurement: ...
    def value(self, name: str) -> str | int | bool | float: ...


class StepView:
    """A read-only view of a master at its current step (valid during ``on_step``)."""

    __slots__ = ("_master", "bus", "exact", "slots", "text", "xbus")

    def __init__(self, master: SteppedSystem) -> None:
        self._master = master
        #: the signal bus (float64, one slot per signal), not writable
        self.bus: np.ndarray = master.bus.view()
        self.bus.flags.writeable = False
        #: signal name -> bus slot
        self.slots: Mapping[str, int] = MappingProxyType(master.slots)
        #: the exact values of the 64-bit integer signals (int64; a UInt64 as its bit
        #: pattern), not writable; ``exact`` gives each one's bus slot -> (position, unsigned)
        self.xbus: np.ndarray = master.xbus.view()
        self.xbus.flags.writeable = False
        self.exact: Mapping[int, tuple[int, bool]] = MappingProxyType(master.exact)
        #: text of the String outputs, by bus slot
        self.text: Mapping[int, str] = MappingProxyType(master.text)

    @property
    def native(self) -> dict[int, object]:
        """The exact values of the String and 64-bit integer signals, by bus slot."""
        return self._master.native

    @property
    def k(self) -> int:
        """The step index: the view shows the system at ``t0 + k*h``."""
        return self._master.k

    @property
    def t(self) -> float:
        """``t0 + k*h``."""
        return self._master.t

    @property
    def h(self) -> float:
        """The base step."""
        return self._master.h

    @property
    def dt(self) -> float:
        """The duration of the step that ended at ``k``, which the filters predict over: the
        master's grid is uniform, its base step ``h`` (a replay's view, whose steps are the gaps
        between the file's time stamps, overrides it: :mod:`uwcosim.run.replay`)."""
        return self._master.h

    def signals(self, slots: np.ndarray) -> np.ndarray:
        """A copy of the bus at ``slots``."""
        return self.bus[slots]

    def signal(self, name: str) -> float:
        """The current value of the signal ``name`` (or array element ``a.y[1]``) as a
        float."""
        slot = self.slots.get(name)
        return float(self.bus[slot]) if slot is not None else self._master.signal(name)

    def value(self, name: str) -> str | int | bool | float:
        """The current value of the signal ``name`` as its own type (str, int, bool, float)."""
        return self._master.value(name)

    def measurement(self) -> Measurement:
        """The measurement of step ``k`` (the sensor bank's: NaN where not received)."""
        return self._master.measurement()


class Observer(Protocol):
    """Anything with ``on_step(k, view)``: called at ``k = 0`` and after every step."""

    def on_step(self, k: int, view: StepView) -> None: ...


@dataclass(frozen=True)
class Callback:
    """An observer made of a function ``fn(k, view)``."""

    fn: Callable[[int, StepView], object]

    def on_step(self, k: int, view: StepView) -> None:
        self.fn(k, view)
