"""A bounded memo keyed on values: repeated work (elevation matrices of one tile's faces, validated knot
vectors of thousands of composed tiles) is done once, and memory stays bounded however long a process runs."""

from __future__ import annotations

from collections import OrderedDict
from typing import Callable, Hashable


class BoundedCache:
    """At most ``size`` entries, least recently used dropped first; keys must be hashable *values*
    (bytes of arrays, numbers, tuples), never ``id()`` of an object that may die.

    >>> cache = BoundedCache(2)
    >>> [cache.get(k, lambda: k * k) for k in (2, 3, 2, 4)]
    [4, 9, 4, 16]
    >>> len(cache), 3 in cache  # 3 was the least recently used
    (2, False)
    """

    def __init__(self, size: int):
        if not (isinstance(size, int) and size >= 1):
            raise ValueError(f"cache size must be an integer >= 1, got {size!r}")
        self.size = size
        self._items: OrderedDict = OrderedDict()

    def get(self, key: Hashable, make: Callable[[], object]):
        """The value stored under ``key``, made by ``make()`` (and stored) the first time."""
        items = self._items
        if key in items:
            items.move_to_end(key)
            return items[key]
        value = items[key] = make()
        if len(items) > self.size:
            items.popitem(last=False)
        return value

    def __contains__(self, key) -> bool:
        return key in self._items

    def __len__(self) -> int:
        return len(self._items)
