"""Index arithmetic on runs: many ranges ``[start, start + count)`` concatenated without a loop.

CSR rows, candidate lists per box and graph fronts all ask for "the positions
of these runs, one after the other"; the answer is one ``arange`` shifted run
by run.
"""

from __future__ import annotations

import numpy as np

__all__ = ["concatenated_ranges"]


def concatenated_ranges(starts, counts) -> np.ndarray:
    """``np.concatenate([np.arange(s, s + c) for s, c in zip(starts, counts)])`` (int64) in one pass.

    ``starts``: (R,) or a scalar; ``counts``: (R,) non-negative run lengths.

    >>> concatenated_ranges([10, 0, 5], [2, 0, 3]).tolist()
    [10, 11, 5, 6, 7]
    """
    counts = np.asarray(counts, np.int64)
    starts = np.broadcast_to(np.asarray(starts, np.int64), counts.shape)
    return np.arange(int(counts.sum()), dtype=np.int64) + np.repeat(starts - (np.cumsum(counts) - counts), counts)
