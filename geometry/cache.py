"""The one memo of the toolkit: bounded, keyed on values, read-only outputs, cleared by :func:`clear_caches`.

Repeated work (elevation matrices of one tile's faces, validated knot vectors of thousands of composed tiles,
Gauss rules, compiled kernels) is done once, and memory stays bounded however long a process runs.  Every
cache of the library is a :class:`BoundedCache`, a function wrapped by :func:`memo`, or a :class:`PerObject`
memo (facts about one live object, dropped with it); all of them register here, so :func:`clear_caches`
empties them all.  Stored arrays (also inside tuples, lists and SciPy sparse matrices) are made read-only
when stored: a caller that edits what it was given gets an error instead of corrupting every later call.
"""

from __future__ import annotations

import functools
import weakref
from collections import OrderedDict
from typing import Callable, Hashable

import numpy as np

__all__ = ["BoundedCache", "PerObject", "memo", "clear_caches", "value_key"]

_ALL: list = []  # every cache made by this module (they live as long as their modules)


def _freeze(value):
    """``value`` with every NumPy array in it (tuples, lists, dicts and SciPy sparse matrices searched) made
    read-only; returned for chaining."""
    if isinstance(value, np.ndarray):
        value.setflags(write=False)
    elif isinstance(value, (tuple, list)):
        for v in value:
            _freeze(v)
    elif isinstance(value, dict):
        for v in value.values():
            _freeze(v)
    elif hasattr(value, "tocsr") and hasattr(value, "data"):  # a SciPy sparse matrix or array
        for name in ("data", "indices", "indptr", "row", "col", "offsets"):
            a = getattr(value, name, None)
            if isinstance(a, np.ndarray):
                a.setflags(write=False)
    return value


def value_key(value) -> Hashable:
    """A hashable key for ``value`` by what it holds: arrays by dtype, shape and bytes; lists as tuples."""
    if isinstance(value, np.ndarray):
        return ("ndarray", value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, (list, tuple)):
        return (type(value).__name__,) + tuple(value_key(v) for v in value)
    if isinstance(value, np.generic):
        return value.item()
    return value


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
        _ALL.append(self)

    def get(self, key: Hashable, make: Callable[[], object]):
        """The value stored under ``key``, made by ``make()`` (stored read-only) the first time."""
        items = self._items
        if key in items:
            items.move_to_end(key)
            return items[key]
        value = items[key] = _freeze(make())
        if len(items) > self.size:
            items.popitem(last=False)
        return value

    def lookup(self, key: Hashable, default=None):
        """The value stored under ``key`` (counted as a use), or ``default``."""
        if key in self._items:
            self._items.move_to_end(key)
            return self._items[key]
        return default

    def clear(self) -> None:
        self._items.clear()

    def __contains__(self, key) -> bool:
        return key in self._items

    def __len__(self) -> int:
        return len(self._items)


class PerObject:
    """Facts about live objects (a spline's inversion start grid), dropped when the object is: keyed on the
    object itself through a weak reference, so an ``id()`` is never reused for another object.

    ``get(obj, make)`` returns the stored value for ``obj`` or stores ``make()`` (read-only)."""

    def __init__(self):
        self._items: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        _ALL.append(self)

    def get(self, obj, make: Callable[[], object]):
        try:
            return self._items[obj]
        except KeyError:
            value = self._items[obj] = _freeze(make())
            return value

    def __contains__(self, obj) -> bool:
        return obj in self._items

    def __len__(self) -> int:
        return len(self._items)

    def peek(self, obj, default=None):
        """The stored value for ``obj`` without making one."""
        return self._items.get(obj, default)

    def clear(self) -> None:
        self._items.clear()


def memo(size: int):
    """Decorator: cache a function of hashable or array arguments in a :class:`BoundedCache` of ``size``
    entries keyed on the arguments' values (:func:`value_key`); the results are stored read-only.
    The wrapper's ``cache_clear()`` empties it (as ``functools.lru_cache``'s does)."""

    def wrap(fn):
        cache = BoundedCache(size)

        @functools.wraps(fn)
        def cached(*args, **kwargs):
            key = (value_key(args), value_key(tuple(sorted(kwargs.items()))))
            return cache.get(key, lambda: fn(*args, **kwargs))

        cached.cache_clear = cache.clear
        cached.cache = cache
        return cached

    return wrap


def clear_caches() -> None:
    """Empty every cache of the toolkit (memory back after a large study; results are recomputed)."""
    for cache in _ALL:
        cache.clear()
