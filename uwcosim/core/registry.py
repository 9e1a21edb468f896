"""Name -> factory registries that list the valid names on a typo.

What a registered factory takes (a filter's settings, for instance) is declared on the
factory itself (:mod:`uwcosim.filters.settings`), not here.

A registry may have a ``fallback``: a function that finds a name the registry does not hold
(a user's filter named ``package.module:Name`` or by an entry point:
:mod:`uwcosim.filters.plugins` installs it on :data:`uwcosim.filters.base.ESTIMATORS`), raising
the one-line error itself. ``in`` and :meth:`Registry.names` count the registered names only.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from uwcosim.core.errors import ScenarioError

T = TypeVar("T")


class Registry(Generic[T]):
    """A mapping of names to factories; ``get`` raises a one-line error listing valid names."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._items: dict[str, T] = {}
        #: finds a name that is not registered (or raises ScenarioError); None: no fallback
        self.fallback: Callable[[str], T] | None = None

    def register(self, name: str) -> Callable[[T], T]:
        def deco(obj: T) -> T:
            if name in self._items:
                raise ValueError(f"{self.kind} {name!r} registered twice")
            self._items[name] = obj
            return obj

        return deco

    def add(self, name: str, obj: T) -> None:
        self.register(name)(obj)

    def get(self, name: str, where: str = "") -> T:
        try:
            return self._items[name]
        except KeyError:
            if self.fallback is not None:
                try:
                    return self.fallback(name)
                except ScenarioError as exc:
                    raise ScenarioError(f"{where}: {exc}" if where else str(exc)) from None
            valid = ", ".join(sorted(self._items))
            prefix = f"{where}: " if where else ""
            raise ScenarioError(
                f"{prefix}unknown {self.kind} {name!r} (valid: {valid})"
            ) from None

    def names(self) -> list[str]:
        return sorted(self._items)

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(self._items))
