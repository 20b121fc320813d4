"""What the solver families build for one compiled model on first use, typed and kept with it
(:class:`Artifacts`, ``CompiledModel.artifacts``): compiled Taylor modules (plain, with events,
with input series, variational), the compiled event functions and their gradients, the
sensitivity libraries, the pool of CVODE options structs.

Each entry lives under its type and a key and is made once: a lock per model, so that two
threads asking for the same artifact build it once and get the same object. A value found under
a key is checked to be of the type asked for, so that two families can never read each other's
entries by a clash of keys."""

from __future__ import annotations

import threading
from typing import Callable, Hashable, TypeVar

T = TypeVar("T")


class Artifacts:
    """The artifacts of one compiled model, by (type, key)."""

    __slots__ = ("_items", "_lock")

    def __init__(self):
        self._items: dict = {}
        self._lock = threading.RLock()  # re-entrant: making one artifact may ask for another

    def get(self, kind: type[T], key: Hashable, make: Callable[[], T]) -> T:
        """The artifact of type ``kind`` under ``key``, made by ``make()`` on first use."""
        found = self._items.get((kind, key))
        if found is not None:
            return found
        with self._lock:
            found = self._items.get((kind, key))
            if found is None:
                found = make()
                if not isinstance(found, kind):
                    raise TypeError(f"an artifact {key!r:.80} made as {type(found).__name__}, not {kind.__name__}")
                self._items[(kind, key)] = found
        return found

    def find(self, kind: type[T], key: Hashable) -> T | None:
        """The artifact of type ``kind`` under ``key`` if made, else None (TypeError for a key
        that does not hash)."""
        return self._items.get((kind, key))

    def keep(self, kind: type[T], key: Hashable, value: T) -> T:
        """``value`` kept under ``key`` as well (e.g. the events as given beside the events as
        checked); returns it."""
        if not isinstance(value, kind):
            raise TypeError(f"an artifact {key!r:.80} of type {type(value).__name__}, not {kind.__name__}")
        with self._lock:
            self._items[(kind, key)] = value
        return value

    def __len__(self) -> int:
        return len(self._items)
