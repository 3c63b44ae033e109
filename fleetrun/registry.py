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

    def __init__(self, kind: str, hint: str | None = None, aliases: dict[str, str] | None = None):
        self.kind = kind
        self.hint = hint
        # characters users may write for others, e.g. {"-": "_"} for effect ids
        self._aliases = aliases or {}
        self._items: dict[str, T] = {}

    def register(self, name: str, item: T) -> T:
        if name in self._items:
            raise ValueError(f"{self.kind} '{name}' is registered twice")
        self._items[name] = item
        return item

    def _key(self, name: str) -> str:
        key = str(name).strip().lower()
        for written, meant in self._aliases.items():
            key = key.replace(written, meant)
        return key

    def get(self, name: str) -> T:
        """The item called ``name`` (case-insensitive, aliases applied) or an error that lists
        the valid names and the closest match."""
        key = self._key(name)
        for known, item in self._items.items():
            if self._key(known) == key:
                return item
        raise unknown_name_error(self.kind, name, self._items, hint=self.hint)

    def __getitem__(self, name: str) -> T:
        return self._items[name]

    def values(self):
        return self._items.values()

    def items(self):
        return self._items.items()

    def __len__(self) -> int:
        return len(self._items)

    def names(self) -> list[str]:
        return list(self._items)

    def __contains__(self, name: str) -> bool:
        return self._key(name) in {self._key(k) for k in self._items}

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)


#: Differential baselines: objects with ``efficiency(configuration, torque_fraction,
#: speed_rpm, gear_ratio, *, low_gear_ratio, axle_gear, oil_temp_C)``.
PHYSICS: Registry = Registry("physics", hint="Choose one with --physics")

#: Physics the thesis left out (fleetrun/effects): ``Effect`` objects by id, for ``--with``
#: and ``fleetrun diagnose``.
EFFECTS: Registry = Registry("effect", hint="See docs/effects.md", aliases={"-": "_"})
