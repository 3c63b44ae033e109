"""Name -> implementation registries for physics baselines and effects.

Baselines (``--physics``) and effects (``--with``) are chosen by name; an unknown name gets
an error listing the valid names and the closest match.
"""
from __future__ import annotations

from typing import Generic, Iterator, TypeVar

from fleetrun.errors import unknown_name_error

T = TypeVar("T")


class Registry(Generic[T]):
    """An ordered mapping of names to implementations of one kind (e.g. "physics")."""

    def __init__(self, kind: str, hint: str | None = None):
        self.kind = kind
        self.hint = hint
        self._items: dict[str, T] = {}

    def register(self, name: str, item: T) -> T:
        if name in self._items:
            raise ValueError(f"{self.kind} '{name}' is registered twice")
        self._items[name] = item
        return item

    def get(self, name: str) -> T:
        key = name.strip().lower()
        for known, item in self._items.items():
            if known.lower() == key:
                return item
        raise unknown_name_error(self.kind, name, self._items, hint=self.hint)

    def names(self) -> list[str]:
        return list(self._items)

    def __contains__(self, name: str) -> bool:
        return name.strip().lower() in {k.lower() for k in self._items}

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)


#: Differential baselines: objects with ``efficiency(configuration, torque_fraction,
#: speed_rpm, gear_ratio, *, low_gear_ratio, axle_gear, oil_temp_C)``.
PHYSICS: Registry = Registry("physics", hint="Choose one with --physics")
