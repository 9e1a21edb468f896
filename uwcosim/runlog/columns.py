"""The log's column schema: every column name is built and parsed here, nowhere else.

A run's log has one row per communication step, ``time`` first, then

- the logged signals, by their bus names (``vehicle.x``, ``controls.psi``); an FMI 3 array
  signal one column per element, row-major, ``sig.y[0]``, ``sig.y[1]``... (``sig.M[0,2]`` for
  more dimensions, 0-based: :func:`element`, :func:`signal_columns`);
- with estimators: the measurements ``z.NAME`` (NaN when not received), then per estimator
  ``E`` one *block*: its mean ``est.E.STATE`` for every state, its variance
  ``est.E.var.STATE`` for every state, ``est.E.nis`` and ``est.E.nees``;
- in a georeferenced run (:mod:`uwcosim.models.geo`): the latitude and longitude (degrees,
  WGS 84) of the truth's position, ``truth.lat_deg``, ``truth.lon_deg``, then of each
  estimator's, ``est.E.lat_deg``, ``est.E.lon_deg``;
- with ``[evaluation] bound`` (:mod:`uwcosim.run.bound`): the posterior Cramér-Rao bound on
  each state's RMSE at the step, ``bound.STATE`` (no such columns without it);
- the Boolean flags, after the float columns: ``z.NAME.received`` per measurement, then
  ``est.E.diverged`` per estimator.

:class:`LogLayout` is that layout for one run (names, positions in a row, the block of each
estimator); :class:`EstimateBlock` the positions inside one estimator's block, which the
estimator bank fills and the recorder copies. The functions build single names and read them
back from an existing log (:func:`estimators_in`, :func:`states_in`), for the evaluation, the
figures, the HTML report and the exports.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

TIME = "time"
_EST = "est."
_Z = "z."
_BOUND = "bound."


def element(signal: str, index: tuple[int, ...]) -> str:
    """``sig.y[1]``, ``sig.M[0,2]``: the column of one element of an array signal (0-based)."""
    return f"{signal}[{','.join(str(i) for i in index)}]"


def signal_columns(signal: str, shape: tuple[int, ...] = ()) -> list[str]:
    """The columns of a signal: its name, or (an array of ``shape``) one per element in
    row-major order."""
    if not shape:
        return [signal]
    return [element(signal, idx) for idx in itertools.product(*(range(d) for d in shape))]


def measurement(name: str) -> str:
    """``z.NAME``: a measurement component as received (NaN when not)."""
    return f"{_Z}{name}"


def received(name: str) -> str:
    """``z.NAME.received``: the flag of a measurement component."""
    return f"{_Z}{name}.received"


def estimate(estimator: str, state: str) -> str:
    """``est.E.STATE``: estimator ``E``'s mean of ``state``."""
    return f"{_EST}{estimator}.{state}"


def variance(estimator: str, state: str) -> str:
    """``est.E.var.STATE``: estimator ``E``'s variance of ``state``."""
    return f"{_EST}{estimator}.var.{state}"


def nis(estimator: str) -> str:
    """``est.E.nis``: the normalized innovation squared of the step's update."""
    return f"{_EST}{estimator}.nis"


def nees(estimator: str) -> str:
    """``est.E.nees``: the normalized estimation error squared against the truth."""
    return f"{_EST}{estimator}.nees"


def diverged(estimator: str) -> str:
    """``est.E.diverged``: the flag of an estimator stopped for divergence."""
    return f"{_EST}{estimator}.diverged"


def bound(state: str) -> str:
    """``bound.STATE``: the posterior Cramér-Rao bound on ``state``'s RMSE at the step."""
    return f"{_BOUND}{state}"


def bound_position() -> str:
    """``bound.position``: the bound on the position error norm's RMSE (``bound.parquet``)."""
    return f"{_BOUND}position"


def bound_states_in(columns: Iterable[str]) -> list[str]:
    """The states of an existing log's ``bound.STATE`` columns, in column order."""
    return [c[len(_BOUND):] for c in columns
            if c.startswith(_BOUND) and c != bound_position()]


#: whose position a latitude/longitude column gives: the truth's, or an estimator's
TRUTH = None


def latitude(estimator: str | None = TRUTH) -> str:
    """``truth.lat_deg`` or ``est.E.lat_deg``: latitude (degrees) of the truth's or estimator
    ``E``'s position."""
    return "truth.lat_deg" if estimator is None else f"{_EST}{estimator}.lat_deg"


def longitude(estimator: str | None = TRUTH) -> str:
    """``truth.lon_deg`` or ``est.E.lon_deg``: longitude (degrees) of the position."""
    return "truth.lon_deg" if estimator is None else f"{_EST}{estimator}.lon_deg"


class EstimateBlock(NamedTuple):
    """Positions inside one estimator's block of a row: ``[mean | variance | nis, nees]``."""

    mean: slice
    var: slice
    nis: int
    nees: int
    width: int

    @classmethod
    def of(cls, nx: int) -> EstimateBlock:
        return cls(slice(0, nx), slice(nx, 2 * nx), 2 * nx, 2 * nx + 1, 2 * nx + 2)


def estimator_columns(estimator: str, states: Sequence[str]) -> list[str]:
    """The float columns of one estimator's block, in :class:`EstimateBlock` order."""
    return ([estimate(estimator, s) for s in states] + [variance(estimator, s) for s in states]
            + [nis(estimator), nees(estimator)])


@dataclass(frozen=True)
class LogLayout:
    """The columns of one run's log and where each part sits in a row (``time`` at 0)."""

    signals: tuple[str, ...]
    measurements: tuple[str, ...] = ()
    estimators: tuple[str, ...] = ()
    states: tuple[str, ...] = ()
    #: latitude/longitude columns of the truth and of each estimator (a georeferenced run)
    geo: bool = False
    #: the ``bound.STATE`` columns, one per state (a run with ``[evaluation] bound``)
    bound: bool = False

    @property
    def block(self) -> EstimateBlock:
        return EstimateBlock.of(len(self.states))

    @property
    def columns(self) -> list[str]:
        """The float columns after ``time``."""
        out = list(self.signals) + [measurement(n) for n in self.measurements]
        for e in self.estimators:
            out += estimator_columns(e, self.states)
        if self.geo:
            for owner in (TRUTH, *self.estimators):
                out += [latitude(owner), longitude(owner)]
        if self.bound:
            out += [bound(s) for s in self.states]
        return out

    @property
    def flags(self) -> list[str]:
        """The Boolean columns, after the float ones."""
        return [received(n) for n in self.measurements] + [diverged(e) for e in self.estimators]

    @property
    def width(self) -> int:
        """Floats per row, ``time`` included."""
        return self.bound_part.stop

    @property
    def signal_part(self) -> slice:
        return slice(1, 1 + len(self.signals))

    @property
    def measurement_part(self) -> slice:
        start = 1 + len(self.signals)
        return slice(start, start + len(self.measurements))

    @property
    def estimates(self) -> slice:
        """Every estimator's block, one after the other."""
        start = self.measurement_part.stop
        return slice(start, start + len(self.estimators) * self.block.width)

    @property
    def geo_part(self) -> slice:
        """The latitude/longitude pairs (truth, then each estimator; empty unless ``geo``)."""
        start = self.estimates.stop
        return slice(start, start + (2 * (1 + len(self.estimators)) if self.geo else 0))

    @property
    def bound_part(self) -> slice:
        """The ``bound.STATE`` columns (empty unless ``bound``)."""
        start = self.geo_part.stop
        return slice(start, start + (len(self.states) if self.bound else 0))


def estimators_in(columns: Iterable[str]) -> list[str]:
    """The estimator names of an existing log, in column order (from ``est.E.nis``)."""
    suffix = ".nis"
    return [c[len(_EST):-len(suffix)] for c in columns
            if c.startswith(_EST) and c.endswith(suffix)]


def states_in(columns: Iterable[str], estimator: str) -> list[str]:
    """The state names of ``estimator``'s block in an existing log (from ``est.E.var.S``)."""
    prefix = variance(estimator, "")
    return [c[len(prefix):] for c in columns if c.startswith(prefix)]
