"""The estimator interface every filter implements, and the state-space model it consumes.

An estimator holds a mean ``x`` and covariance ``P`` and is driven by the master (or by user
code, numpy in and numpy out)::

    est.predict(u, dt)        # time update over dt with control u held
    est.update(z, mask)       # measurement update; mask[i] False = component i missing
    est.update(None)          # no measurement this step (FilterPy's update(z=None))
    est.step(u, dt, z, mask)  # predict then update, as one call (the compiled Kalman steps
                              # fuse them); t= sets est.t between the two
    est.diagnostics           # per-step diagnostics (dict of floats), reset every step
    est.t                     # time of the current estimate; the driver sets it (the master
                              # sets est.t = t0 + k*h before each update; it is never summed)

A filter declares its settings once, on its class (``Settings``, a
:class:`~uwcosim.filters.settings.FilterSettings`); the constructor takes them as keywords,
validates them and keeps them as ``self.settings``. Scenarios name filters through
:data:`ESTIMATORS` (:func:`register`; a user's class named ``package.module:ClassName`` or by an
entry point is found through the registry's fallback, :mod:`uwcosim.filters.plugins`);
:func:`build` makes one from validated settings and :meth:`Estimator.from_settings` from raw
ones, with one-line errors.

:class:`FilterBase` holds what every filter of the package shares: the ``measurements`` setting
(the subset of measurement names a filter uses), per-step diagnostics (reset when a step begins,
i.e. at ``predict``, or at ``update`` when no ``predict`` came before it; ``pd_repairs`` always,
``nis``/``nis_dof`` after an update with data, plus each filter's own) and finiteness checks that
raise :class:`~uwcosim.core.errors.FilterDivergence`. A filter uses the model it is given: which
implementation that is (CasADi, or the closed-form TAN model) is chosen where the model is built
(:mod:`uwcosim.run.factory`); the filters see it only through
:class:`~uwcosim.models.protocol.StateSpaceModel`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from uwcosim.core.errors import ScenarioError
from uwcosim.core.registry import Registry
from uwcosim.filters.gating import gate, gate_threshold
from uwcosim.filters.numerics import check_finite
from uwcosim.filters.settings import FilterSettings, settings_problems
from uwcosim.models.protocol import StateSpaceModel


class Estimator(ABC):
    """Base class: mean ``x``, covariance ``P``, ``predict``/``update`` and diagnostics."""

    #: registry name, set by :func:`register`
    kind: ClassVar[str] = ""
    #: the filter's settings, the keywords of its constructor (none: the base model)
    Settings: ClassVar[type[FilterSettings]] = FilterSettings
    #: the filter draws random numbers: it takes the master's stream as ``rng``
    needs_rng: ClassVar[bool] = False

    def __init__(self, model: StateSpaceModel, x0: np.ndarray, P0: np.ndarray, *,
                 rng: np.random.Generator | None = None, seed: int | None = None,
                 **settings: Any) -> None:
        """``settings``: the keywords of :attr:`Settings`. A filter that draws
        (:attr:`needs_rng`) takes its random numbers from ``rng`` (the master passes its stream
        ``estimator:NAME``), or from ``numpy.random.default_rng(seed)`` when ``seed`` is
        given (it wins over ``rng``); with neither, from ``default_rng(0)``: a filter made in
        code without one is still reproducible."""
        #: the validated settings (an instance of :attr:`Settings`)
        self.settings = self.validate_settings(settings)
        if seed is not None:
            rng = np.random.default_rng(seed)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.model = model
        self.x = np.array(x0, dtype=float).reshape(-1)
        self.P = np.array(P0, dtype=float)
        if self.P.ndim == 1:
            self.P = np.diag(self.P)
        if self.x.shape != (model.nx,) or self.P.shape != (model.nx, model.nx):
            raise ScenarioError(
                f"estimator {self.kind}: x0 must have {model.nx} elements and P0 be "
                f"{model.nx}x{model.nx}, got {self.x.shape} and {self.P.shape}"
            )
        self.diagnostics: dict[str, float] = {}
        self.t = 0.0

    @abstractmethod
    def predict(self, u: np.ndarray, dt: float) -> None:
        """Time update from t to t + dt with the control ``u`` held."""

    @abstractmethod
    def update(self, z: np.ndarray | None, mask: np.ndarray | None = None) -> None:
        """Measurement update; ``z=None`` or an all-False ``mask`` means no measurement."""

    def step(self, u: np.ndarray, dt: float, z: np.ndarray | None,
             mask: np.ndarray | None = None, t: float | None = None) -> None:
        """A whole step: ``predict(u, dt)``, then ``self.t = t`` (if given), then
        ``update(z, mask)``. A filter may do it in one call (the compiled Kalman steps) with the
        same result as the three."""
        self.predict(u, dt)
        if t is not None:
            self.t = t
        self.update(z, mask)

    @classmethod
    def validate_settings(cls, settings: dict[str, Any]) -> FilterSettings:
        """``settings`` checked against :attr:`Settings`: an instance, or a one-line
        TypeError (unknown key) or ValueError (a wrong value) naming every problem."""
        problems = settings_problems(cls.Settings, cls.kind or cls.__name__, settings)
        if problems:
            unknown = any(p.startswith("unknown setting") for p in problems)
            raise (TypeError if unknown else ValueError)("; ".join(problems))
        return cls.Settings.model_validate(settings)

    @classmethod
    def from_settings(
        cls, model: StateSpaceModel, x0, P0, settings: dict[str, Any], where: str = "",
        rng: np.random.Generator | None = None,
    ) -> Estimator:
        """Build from scenario settings, checked against the filter's :attr:`Settings`; every
        problem in one line."""
        problems = settings_problems(cls.Settings, cls.kind, settings)
        if problems:
            raise ScenarioError(f"{where}: {'; '.join(problems)}")
        try:
            return cls(model, x0, P0, rng=rng, **settings)
        except (TypeError, ValueError) as exc:
            raise ScenarioError(f"{where}: {exc}") from None
        except MemoryError:
            raise ScenarioError(f"{where}: not enough memory for these settings") from None


ESTIMATORS: Registry[type[Estimator]] = Registry("estimator")


def register(name: str):
    """Class decorator: register an estimator class under ``name``."""

    def deco(cls: type[Estimator]) -> type[Estimator]:
        cls.kind = name
        ESTIMATORS.add(name, cls)
        return cls

    return deco


def settings_model(kind: str) -> type[FilterSettings]:
    """The settings model of filter ``kind`` (registered, or a user's filter that
    :mod:`uwcosim.filters.plugins` resolves: none declared is no setting)."""
    return getattr(ESTIMATORS.get(kind), "Settings", FilterSettings)


def build(kind: str, model: StateSpaceModel, x0: np.ndarray, P0: np.ndarray,
          settings: dict[str, Any], rng: np.random.Generator | None = None) -> Estimator:
    """Construct filter ``kind`` from settings already validated against its ``Settings``
    (only the keys the scenario gives: the others take their declared defaults); ``rng``
    goes to a filter that draws. A user's class that does not derive from :class:`Estimator`
    is called ``cls(model, x0, P0, **settings)``, with ``rng=`` only if it ``needs_rng``."""
    cls = ESTIMATORS.get(kind)
    if isinstance(cls, type) and issubclass(cls, Estimator):
        return cls(model, x0, P0, rng=rng if cls.needs_rng else None, **settings)
    if getattr(cls, "needs_rng", False):
        settings = {**settings, "rng": rng}
    return cls(model, x0, P0, **settings)


def select(z: np.ndarray | None, mask: np.ndarray | None, nz: int) -> np.ndarray | None:
    """Indices of the available measurement components (None when nothing is available)."""
    if z is None:
        return None
    if mask is None:
        idx = np.flatnonzero(np.isfinite(z))
    else:
        idx = np.flatnonzero(np.asarray(mask, dtype=bool) & np.isfinite(z))
    return idx if idx.size else None


def measurement_use(model, measurements: list[str] | None) -> np.ndarray:
    """Boolean mask of the measurement components a filter uses (default: all)."""
    names = model.measurement_names
    if measurements is None:
        return np.ones(model.nz, dtype=bool)
    unknown = [m for m in measurements if m not in names]
    if unknown:
        raise ValueError(f"unknown measurements {unknown} (valid: {', '.join(names)})")
    return np.array([n in measurements for n in names])


class FilterBase(Estimator):
    """Shared plumbing: measurement subset, step diagnostics, divergence checks."""

    def __init__(self, model: StateSpaceModel, x0: np.ndarray, P0: np.ndarray, *,
                 rng: np.random.Generator | None = None, seed: int | None = None,
                 **settings: Any) -> None:
        super().__init__(model, x0, P0, rng=rng, seed=seed, **settings)
        self._use = measurement_use(model, self.measurements_used())
        self._predicted = False
        self._R_blocks: dict[bytes, np.ndarray] = {}
        self._all_idx = np.arange(model.nz)
        self._all_idx.flags.writeable = False
        p = getattr(self.settings, "gate_probability", None)  # the Kalman family's gate
        self._gate_threshold = gate_threshold(p) if p is not None else None
        check_finite("initial state or covariance", self.x, self.P)

    def measurements_used(self) -> list[str] | None:
        """The names of the measurement components this filter uses (None: all): its
        ``measurements`` setting, if it has one."""
        return getattr(self.settings, "measurements", None)

    def _begin_predict(self) -> None:
        self.diagnostics = {"pd_repairs": 0.0}
        self._predicted = True

    def _begin_update(self, z, mask) -> np.ndarray | None:
        """Start the update half of a step; the indices of the usable components (or None)."""
        if not self._predicted:
            self.diagnostics = {"pd_repairs": 0.0}
        self._predicted = False
        if z is None:
            return None
        ok = np.isfinite(z)  # as select(), without its wrappers (every step of every filter)
        ok &= self._use
        if mask is not None:
            ok &= np.asarray(mask, dtype=bool)
        n = int(np.count_nonzero(ok))
        idx = self._all_idx if n == ok.size else ok.nonzero()[0] if n else None
        if idx is not None and self._gate_threshold is not None:  # filters.gating
            idx, rejected = gate(self.model, self.x, self.P, z, idx, self._gate_threshold,
                                 self._gate_variances(idx))
            self.diagnostics["gated"] = float(rejected)
        return idx  # all components: the read-only _all_idx, the common case

    def _gate_variances(self, idx: np.ndarray) -> np.ndarray | None:
        """The noise variances the gate uses for components ``idx`` (None: the model's)."""
        return None

    def _R(self, idx: np.ndarray) -> np.ndarray:
        """``R[idx, idx]`` (cached per set of components)."""
        key = idx.tobytes()
        R = self._R_blocks.get(key)
        if R is None:
            R = self._R_blocks[key] = self.model.R[np.ix_(idx, idx)]
        return R

    def _check(self, what: str) -> None:
        x, P = self.x, self.P
        if not math.isfinite(float(x.sum()) + float(P.sum())):  # the message only if needed
            check_finite(f"{self.kind} {what}", x, P)
