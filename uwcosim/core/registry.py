"""Name -> factory registries that list the valid names on a typo.

What a registered factory takes (a filter's settings, for instance) is declared on the
factory itself (:mod:`uwcosim.filters.settings`), not here.

A registry may have a ``fallback``: a function that finds a name the registry does not hold
(a user's filter named ``package.module:Name`` or by an entry point:
:mod:`uwcosim.filters.plugins` installs it on :data:`uwcosim.filters.base.ESTIMATORS`), raising
the one-line error itself. ``in`` and :meth:`Registry.names` count the registered and the
declared names only.

A name may be *declared* before it is registered (:meth:`Registry.declare`): the registry then
knows which module registers it and imports that module on the first lookup of the name, so
that a program imports the modules of the names it uses, not all of them (``uwcosim run`` of a
scenario with Kalman filters only does not import the grid filters and their scipy modules).
The declared module must register the name when imported; the lookup says so in one line if it
does not.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from uwcosim.core.errors import ScenarioError

T = TypeVar("T")


class Registry(Generic[T]):
    """A mapping of names to factories; ``get`` raises a one-line error listing valid names."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._items: dict[str, T] = {}
        #: name -> the module that registers it when imported (names not yet registered)
        self._declared: dict[str, str] = {}
        #: finds a name that is not registered (or raises ScenarioError); None: no fallback
        self.fallback: Callable[[str], T] | None = None

    def register(self, name: str) -> Callable[[T], T]:
        def deco(obj: T) -> T:
            if name in self._items:
                raise ValueError(f"{self.kind} {name!r} registered twice")
            self._items[name] = obj
            self._declared.pop(name, None)
            return obj

        return deco

    def add(self, name: str, obj: T) -> None:
        self.register(name)(obj)

    def declare(self, name: str, module: str) -> None:
        """Say that importing ``module`` registers ``name`` (imported on its first lookup)."""
        if name in self._items or name in self._declared:
            raise ValueError(f"{self.kind} {name!r} declared twice")
        self._declared[name] = module

    def load(self, name: str) -> None:
        """Import the module that registers the declared ``name`` (nothing if registered)."""
        module = self._declared.get(name)  # registering a name drops its declaration
        if module is None:
            return
        importlib.import_module(module)
        if name not in self._items:
            raise ValueError(f"{self.kind} {name!r}: importing {module} did not register it")

    def load_all(self) -> None:
        """Import the modules of every declared name."""
        for name in list(self._declared):
            self.load(name)

    def get(self, name: str, where: str = "") -> T:
        self.load(name)
        try:
            return self._items[name]
        except KeyError:
            if self.fallback is not None:
                try:
                    return self.fallback(name)
                except ScenarioError as exc:
                    raise ScenarioError(f"{where}: {exc}" if where else str(exc)) from None
            valid = ", ".join(self.names())
            prefix = f"{where}: " if where else ""
            raise ScenarioError(
                f"{prefix}unknown {self.kind} {name!r} (valid: {valid})"
            ) from None

    def loaded(self) -> dict[str, T]:
        """The names registered so far and their objects (no declared module imported)."""
        return dict(self._items)

    def names(self) -> list[str]:
        """The registered and the declared names, sorted."""
        return sorted({*self._items, *self._declared})

    def __contains__(self, name: object) -> bool:
        return name in self._items or name in self._declared

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())
