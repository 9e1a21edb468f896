"""Name -> factory registries that list the valid names on a typo.

A registry may also hold a *settings model* per name (a pydantic model of the keyword settings
its factory takes, :mod:`uwcosim.filters.settings`), used by the scenario validation, ``uwcosim
list`` and ``uwcosim schema``.
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
        self._settings: dict[str, type] = {}

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
            valid = ", ".join(sorted(self._items))
            prefix = f"{where}: " if where else ""
            raise ScenarioError(
                f"{prefix}unknown {self.kind} {name!r} (valid: {valid})"
            ) from None

    def declare_settings(self, name: str, model: type) -> None:
        """Declare ``model`` (a pydantic model) as the settings of ``name``."""
        if name in self._settings:
            raise ValueError(f"settings of {self.kind} {name!r} declared twice")
        self._settings[name] = model

    def settings(self, name: str) -> type | None:
        """The settings model declared for ``name`` (None: none declared)."""
        return self._settings.get(name)

    def names(self) -> list[str]:
        return sorted(self._items)

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(self._items))
