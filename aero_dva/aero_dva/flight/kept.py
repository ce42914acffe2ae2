"""A few values kept between calls by key, the least recently used dropped first.

The batch simulator keeps the sampled wing of the last models it flew, the switched flight the
maps of its last flights: values that cost as much to build as a short flight and that the
next call (the next seed of an evaluation case, the next repeat of a benchmark) asks for
again. Thread-safe; the values themselves are shared, so nobody may write into them.
"""
from __future__ import annotations

import threading
from collections import OrderedDict

__all__ = ["KeptByKey"]


class KeptByKey:
    """At most ``size`` values by hashable key, the most recently used last."""

    def __init__(self, size: int):
        if size < 1:
            raise ValueError(f"size must be >= 1, got {size}")
        self.size = int(size)
        self._items: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key):
        """The value kept for ``key`` (now the most recent), or None. Raises TypeError for an
        unhashable key."""
        with self._lock:
            value = self._items.get(key)
            if value is not None:
                self._items.move_to_end(key)
            return value

    def keep(self, key, value):
        """Keep ``value`` for ``key`` unless one is kept already; return the kept one (a value
        built by another thread meanwhile wins, so every caller shares one)."""
        with self._lock:
            value = self._items.setdefault(key, value)
            self._items.move_to_end(key)
            while len(self._items) > self.size:
                self._items.popitem(last=False)
            return value

    def latest(self):
        """The most recently used value (None when empty)."""
        with self._lock:
            return next(reversed(self._items.values()), None)

    def clear(self) -> None:
        with self._lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)
