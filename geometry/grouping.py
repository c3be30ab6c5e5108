"""Grouping of objects that are the same object (patches sharing one tile spline, one map).

Batching keys on object identity: a paving places one tile spline many times,
and the work done once per spline (face spaces, corners, proofs) is shared by
its placements.  ``id(obj)`` alone is a valid key only while ``obj`` lives; an
:class:`ObjectIndex` holds every object it has numbered, so a number is never
reused for another object during the index's life (one call, one model).
:func:`identity_groups` groups a whole list at once (``np.unique`` over the
identities), valid for the same reason: the list holds its objects.
"""

from __future__ import annotations

import numpy as np


class ObjectIndex:
    """Numbers distinct objects 0, 1, 2, ... by identity, holding each one so its number stays its own.

    >>> index = ObjectIndex()
    >>> a, b = [1], [1]  # equal values, two objects
    >>> index(a), index(b), index(a)
    (0, 1, 0)
    """

    def __init__(self):
        self._number: dict[int, int] = {}
        self._held: list = []

    def __call__(self, obj) -> int:
        """The number of ``obj`` (a new one the first time it is seen)."""
        key = id(obj)
        number = self._number.get(key)
        if number is None:
            number = self._number[key] = len(self._held)
            self._held.append(obj)  # keeps obj alive, so id(obj) cannot be reused while the index lives
        return number

    def __len__(self) -> int:
        return len(self._held)


def identity_groups(objs) -> tuple[np.ndarray, np.ndarray]:
    """(index of the first occurrence of each distinct object (G,), group of every entry (len(objs),)), objects
    told apart by identity (``None`` is one object too), in one ``np.unique``; groups in order of ``id``.

    >>> a, b = [1], [1]
    >>> first, group = identity_groups([a, b, a, None])
    >>> len(first), bool(group[0] == group[2]), bool(group[0] != group[1])
    (3, True, True)
    """
    ids = np.fromiter((id(o) for o in objs), np.int64, count=len(objs))
    _, first, group = np.unique(ids, return_index=True, return_inverse=True)
    return first, group.reshape(-1)


def near_pairs(points, radius: float, balanced_tree: bool = True) -> np.ndarray:
    """Index pairs (i < j), shape (K, 2), of the points (N, k) closer than ``radius``, sorted by (i, j).

    SciPy's KD-tree returns its pairs in the order of its own tree, which depends on the points' last bits
    (median splits with ties): a caller that handles the pairs one after another (collisions resolved in
    turn, a bridge moved by an earlier pair) would then decide differently on another CPU kernel.  Sorted,
    the order depends only on which pairs there are.  ``balanced_tree=False``: midpoint splits, faster to
    build on 10^5 points; the pairs are the same.

    >>> near_pairs(np.array([[0.0, 0, 0], [5, 0, 0], [0.5, 0, 0], [5.2, 0, 0]]), 1.0).tolist()
    [[0, 2], [1, 3]]
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(points, float)
    if not len(pts):
        return np.zeros((0, 2), np.int64)
    pairs = cKDTree(pts, balanced_tree=balanced_tree).query_pairs(radius, output_type="ndarray")
    if not len(pairs):
        return np.zeros((0, 2), np.int64)
    return pairs[np.lexsort(pairs.T[::-1])]
