"""A user's filter as a first-class estimator: named by import path or by an entry point.

``[estimators.NAME] type`` is one of

- a registered filter (the built-in ones, and any a user's module registers with
  :func:`~uwcosim.filters.base.register` once imported);
- ``package.module:ClassName``: imported by path (:func:`uwcosim.core.plugins.import_object`:
  the scenario's folder, then the current folder, in front of ``sys.path`` for that import);
- the name of an entry point of group :data:`GROUP` (``uwcosim.estimators``) of an installed
  distribution, e.g. ``gated_ekf = "gated_ekf.filter:GatedEKF"`` in its ``pyproject.toml``.

The class is resolved once per process (:func:`resolve_estimator`, called by the scenario's
validation with the scenario's folder) and then found by its type string everywhere, through
the fallback this module installs on :data:`~uwcosim.filters.base.ESTIMATORS` (so
:func:`~uwcosim.filters.base.build` and :func:`~uwcosim.filters.base.settings_model` take it as
they take a built-in one). A campaign's worker loads the scenario itself, so it imports the
class by path too.

The class must implement the estimator interface (:class:`~uwcosim.filters.base.Estimator`:
``predict(u, dt)``, ``update(z, mask)``, ``x``, ``P``, optional ``diagnostics``); deriving from
``Estimator`` (or a built-in filter) is the simple way, a plain class with these members works
too. Its settings are declared on the class as ``Settings``, a
:class:`~uwcosim.filters.settings.FilterSettings` subclass (none: it takes no setting), and
``needs_rng = True`` asks for the master's random stream. :func:`estimator_origin` says where a
type came from (:class:`~uwcosim.core.plugins.Origin`: module file, sha256, distribution and
version), for the log's metadata and ``uwcosim list estimators``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from uwcosim.core.errors import ScenarioError
from uwcosim.core.plugins import (
    Origin,
    entry_points,
    import_object,
    is_import_path,
    load_entry_point,
    origin_of,
)
from uwcosim.filters.base import ESTIMATORS, Estimator
from uwcosim.filters.settings import FilterSettings

#: the entry-point group of installed estimators
GROUP = "uwcosim.estimators"
#: type string -> (class, origin) of every user's filter resolved in this process
_RESOLVED: dict[str, tuple[type, Origin]] = {}


def interface_problem(obj: object) -> str:
    """Why ``obj`` cannot be an estimator class (empty string if it can)."""
    if not isinstance(obj, type):
        return f"it is not a class (an object of type {type(obj).__name__})"
    missing = [m for m in ("predict", "update") if not callable(getattr(obj, m, None))]
    if missing:
        return (f"it has no {' and no '.join(missing)} method (an estimator implements "
                f"predict(u, dt) and update(z, mask); derive from uwcosim.filters.Estimator)")
    settings = getattr(obj, "Settings", FilterSettings)
    if not (isinstance(settings, type) and issubclass(settings, FilterSettings)):
        return ("its Settings is not a uwcosim.filters.FilterSettings subclass (declare "
                "'class Settings(FilterSettings)' on the class)")
    if issubclass(obj, Estimator) and getattr(obj, "__abstractmethods__", None):
        return (f"it is abstract (does not implement "
                f"{', '.join(sorted(obj.__abstractmethods__))})")
    return ""


def estimator_names() -> list[str]:
    """The registered filters and the installed entry points of :data:`GROUP`."""
    return sorted(set(ESTIMATORS.names()) | set(entry_points(GROUP)))


def _unknown(kind: str) -> ScenarioError:
    return ScenarioError(f"unknown estimator {kind!r} (valid: {', '.join(estimator_names())}; "
                         f"or a class of yours as 'package.module:ClassName')")


def resolve_estimator(kind: str, search: Sequence[str | Path] = ()) -> type:
    """The estimator class of type ``kind``: registered, imported by path (``search``: the
    folders in front of ``sys.path`` for the import, default the current folder) or an entry
    point of :data:`GROUP`. ScenarioError (one line) otherwise."""
    if kind in ESTIMATORS:
        return ESTIMATORS.get(kind)
    hit = _RESOLVED.get(kind)
    if hit is not None:
        return hit[0]
    if is_import_path(kind):
        obj, origin = import_object(kind, search or (Path.cwd(),))
    elif kind in entry_points(GROUP):
        obj, origin = load_entry_point(GROUP, kind)
    else:
        raise _unknown(kind)
    why = interface_problem(obj)
    if why:
        raise ScenarioError(f"estimator type {kind!r}: {why}")
    if "kind" not in vars(obj):  # its own name in its messages (not its base class's)
        obj.kind = kind
    _RESOLVED[kind] = (obj, origin)
    return obj


def estimator_origin(kind: str) -> Origin:
    """Where filter type ``kind`` comes from (resolving it if needed)."""
    cls = resolve_estimator(kind)
    hit = _RESOLVED.get(kind)
    if hit is not None:
        return hit[1]
    if cls.__module__.startswith("uwcosim."):
        return Origin("built-in", kind, f"{cls.__module__}:{cls.__qualname__}")
    return origin_of(cls, kind, "registered")


def user_estimators() -> dict[str, Origin]:
    """The user's filters known to this process (resolved, or registered by a user's
    module): type string -> origin."""
    out = {k: o for k, (_, o) in _RESOLVED.items()}
    for name, cls in ESTIMATORS.loaded().items():
        if not cls.__module__.startswith("uwcosim."):
            out[name] = estimator_origin(name)
    return out


ESTIMATORS.fallback = resolve_estimator
