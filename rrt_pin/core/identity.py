"""Values kept for the last few objects, found by the objects' identity: one helper for every such cache.

Pinocchio models, controllers and :class:`~rrt_pin.robot.params.Params` are looked up by
identity, not equality: comparing or hashing them would cost more than what is kept
(a robot's description, a pool of Pinocchio data, compiled arrays). Python reuses the
``id`` of an object once it is freed, so each entry holds its objects alive: an
``id`` in the cache is always that object's. A caller checks whatever may have
changed inside a mutable object (a Pinocchio model's masses) itself.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Generic, TypeVar

__all__ = ["IdentityCache"]

V = TypeVar("V")


class IdentityCache(Generic[V]):
    """The values of the last ``size`` keys, a key being a tuple of objects compared by identity.

    Thread-safe; the least recently used entry goes first.

    Args:
        size: how many entries it keeps (>= 1).
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self._items: OrderedDict[tuple[int, ...], tuple[tuple[object, ...], V]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, *key: object) -> V | None:
        """The value kept for exactly these objects, or None."""
        ids = tuple(map(id, key))
        with self._lock:
            entry = self._items.get(ids)
            if entry is None or any(a is not b for a, b in zip(entry[0], key, strict=True)):
                return None
            self._items.move_to_end(ids)
            return entry[1]

    def put(self, *key: object, value: V) -> V:
        """Keep ``value`` for these objects (held alive while kept); returns it."""
        ids = tuple(map(id, key))
        with self._lock:
            self._items[ids] = (key, value)
            self._items.move_to_end(ids)
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return value

    def clear(self) -> None:
        """Forget every entry."""
        with self._lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)
