"""Index sets of unknowns."""

from __future__ import annotations

import numpy as np

from .errors import SolverError

__all__ = ["complement"]


def complement(n: int, indices) -> np.ndarray:
    """The sorted integers of [0, n) not in ``indices`` (int64), by a boolean mask in O(n).

    ``np.setdiff1d(np.arange(n), indices)`` gives the same but sorts or hashes both: 0.25 s at 1M
    unknowns, four times per solve, where this takes a few ms.

    >>> complement(6, [4, 1, 1]).tolist()
    [0, 2, 3, 5]
    """
    idx = np.asarray(indices, np.int64).ravel()
    if len(idx) and (idx.min() < 0 or idx.max() >= n):  # (a negative index would silently wrap)
        raise SolverError(f"unknown numbers must lie in [0, {n}), got {int(idx.min())} .. {int(idx.max())}")
    keep = np.ones(int(n), bool)
    keep[idx] = False
    return np.flatnonzero(keep)
