"""A user's filter model in a scenario: ``[model] type`` names a builder, which gets a context.

``[model] type = "package.module:build"`` (imported by path: the scenario's folder, then the
current folder, in front of ``sys.path`` for the import; :mod:`uwcosim.core.plugins`) or the
name of an entry point of group :data:`GROUP` (``uwcosim.models``) names a callable::

    def build(context: ModelContext, **parameters) -> StateSpaceModel

called once per run (and by ``uwcosim check``) with the scenario's :class:`ModelContext` and
the keys of ``[model.parameters]`` as keyword arguments. It returns any object of the
:class:`~uwcosim.models.protocol.StateSpaceModel` protocol, most simply one made by
:func:`uwcosim.models.symbolic.from_casadi`. The model's measurement names must be the outputs
of ``[model] sensors`` in order (the measurement vector the filters get), its states are the
``[model] truth`` signals in order, and its control vector is ``[model] controls``.

What the builder is given (decided here, once): the noise as the scenario states it (the
default process-noise PSDs exactly as the built-in models take them, and every source by
name), the sensors' sigmas (and the default ``R``), the map (the
:class:`~uwcosim.models.terrain.Bathymetry` and its terrain function as a CasADi function, for
terrain rows in ``h``), the names of controls, truth and sensors, the step and the scenario's
folder. Nothing is drawn: the builder gets no random stream.

:func:`model_problems` checks a built model against the scenario (one line each).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from uwcosim.core.errors import ScenarioError
from uwcosim.core.plugins import (
    Origin,
    entry_points,
    import_object,
    is_import_path,
    load_entry_point,
)

if TYPE_CHECKING:  # the map comes with the context: building one is the caller's (scipy)
    from uwcosim.models.terrain import Bathymetry

#: the entry-point group of installed model builders
GROUP = "uwcosim.models"
#: the built-in filter models (``[model] kind``)
BUILT_IN = {"tan": "the TAN model of seed 000 eq. 54-55 (closed form; DVL and terrain depth)",
            "cv": "the constant-velocity linear-Gaussian model (seed 001)"}
#: the members of the StateSpaceModel protocol a built model must have
PROTOCOL = ("nx", "nz", "state_names", "measurement_names", "R", "f", "F", "Q", "h", "H",
            "f_batch", "h_batch")
_RESOLVED: dict[str, tuple[Callable, Origin]] = {}


@dataclass(frozen=True)
class ModelContext:
    """What a model builder receives from the scenario (its first argument)."""

    #: the outputs of ``[model] sensors`` in order: the rows of ``h``, the names the model
    #: must give as ``measurement_names``
    measurement_names: tuple[str, ...]
    #: the sensor's ``sigma`` of each measurement (by measurement name)
    sigma: dict[str, float]
    #: the process-noise PSDs the built-in models take: ``model.q_psd``, else every
    #: ``[noise]`` source's PSDs but the control noise, in the scenario's order
    q_psd: tuple[float, ...]
    #: every ``[noise.NAME]`` source's PSDs, by name (to pick the ones the model knows)
    noise: dict[str, tuple[float, ...]] = field(default_factory=dict)
    #: the PSDs of ``model.control_noise`` (noise on the controls), or None
    control_psd: tuple[float, ...] | None = None
    #: the names of ``[model] controls``: the control vector ``u`` in order
    controls: tuple[str, ...] = ()
    #: the ``[model] truth`` signals: one per state, in order
    truth: tuple[str, ...] = ()
    #: ``[model] sensors`` and each one's outputs
    sensors: dict[str, tuple[str, ...]] = field(default_factory=dict)
    #: the communication step (s): the filters' ``dt``
    step: float = 1.0
    #: the scenario's map (None without ``[map]``)
    bathymetry: Bathymetry | None = None
    #: the scenario file's folder (for files the builder reads)
    scenario_dir: Path = Path(".")

    @property
    def R(self) -> np.ndarray:
        """The default measurement covariance: ``diag(sigma^2)`` in measurement order."""
        return np.diag([self.sigma[n] ** 2 for n in self.measurement_names])

    @cached_property
    def terrain(self):
        """The map's depth ``h_d([x, y])`` as a CasADi function (a cubic B-spline, exact
        derivatives; MX: call it with ``ca.MX`` symbols), or None without a map."""
        return None if self.bathymetry is None else self.bathymetry.casadi_function()


def builder_problem(obj: object) -> str:
    """Why ``obj`` cannot be a model builder (empty string if it can)."""
    return "" if callable(obj) else f"it is not callable (an object of type {type(obj).__name__})"


def model_types() -> dict[str, str]:
    """The built-in model kinds and the installed builders (entry points of :data:`GROUP`)."""
    out = dict(BUILT_IN)
    for name, ep in entry_points(GROUP).items():
        out.setdefault(name, f"entry point {GROUP} ({ep.value})")
    return out


def resolve_builder(kind: str, search: Sequence[str | Path] = ()) -> Callable:
    """The builder named ``kind`` (import path or entry point); ScenarioError otherwise."""
    hit = _RESOLVED.get(kind)
    if hit is not None:
        return hit[0]
    if is_import_path(kind):
        obj, origin = import_object(kind, search or (Path.cwd(),))
    elif kind in entry_points(GROUP):
        obj, origin = load_entry_point(GROUP, kind)
    else:
        valid = ", ".join(n for n in model_types() if n not in BUILT_IN) or "none installed"
        raise ScenarioError(f"unknown model builder {kind!r} (entry points of {GROUP}: "
                            f"{valid}; or a function of yours as 'package.module:build'; "
                            f"the built-in models are chosen with 'kind')")
    why = builder_problem(obj)
    if why:
        raise ScenarioError(f"model type {kind!r}: {why}")
    _RESOLVED[kind] = (obj, origin)
    return obj


def builder_origin(kind: str) -> Origin:
    """Where the builder ``kind`` comes from (resolving it if needed)."""
    resolve_builder(kind)
    return _RESOLVED[kind][1]


def model_problems(model: Any, kind: str, context: ModelContext) -> list[str]:
    """What is wrong with the model ``kind`` built for ``context``: one phrase per problem
    (the protocol's members, the measurement names, the states and controls)."""
    missing = [m for m in PROTOCOL if not hasattr(model, m)]
    if missing:
        return [f"the model built by {kind!r} ({type(model).__name__}) has no "
                f"{', '.join(missing)} (a StateSpaceModel: uwcosim.models.protocol; "
                f"uwcosim.models.from_casadi builds one)"]
    out = []
    nx, nz = int(model.nx), int(model.nz)
    names = tuple(model.measurement_names)
    if names != context.measurement_names:
        out.append(f"the model built by {kind!r} measures {list(names)}; expected the "
                   f"outputs of model.sensors in order: {list(context.measurement_names)}")
    if len(tuple(model.state_names)) != nx:
        out.append(f"the model built by {kind!r} has {nx} states but "
                   f"{len(tuple(model.state_names))} state_names")
    if np.shape(model.R) != (nz, nz):
        out.append(f"the model built by {kind!r} has R of shape {np.shape(model.R)}, expected "
                   f"{nz}x{nz}")
    nu = getattr(model, "nu", None)
    if nu is not None and int(nu) != len(context.controls):
        out.append(f"the model built by {kind!r} takes {nu} controls; model.controls gives "
                   f"{len(context.controls)} ({', '.join(context.controls) or 'none'})")
    return out
