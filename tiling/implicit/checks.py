"""Connectivity checks of sampled implicit faces and cells, many at once (the halving rounds of
:mod:`tiling.branching.implicit`; Massarwi et al. 2018, Section 5.1).

* a face (2-D samples) passes when its inside samples (f > 0) are one
  component holding the face's centre sample and its outside samples
  (f <= 0) one component;
* a cell (3-D samples) passes when its inside samples are one component and
  every outside component reaches the cell's boundary (no pocket).

Neighbours are samples across an edge (2-D) or a face (3-D), as
``scipy.ndimage.label``'s default.  Blocks of one shape are stacked into one
array whose extra first axis the neighbourhood does not cross, so one
``label`` call per shape and mask checks them all: a few calls a round
instead of two per face or cell (a cold Fig. 16(c) duck made about 590
calls, 20-30 ms).  Padding blocks of different shapes to one measured 2-3x
slower than the calls saved: the cells of a subdivision differ up to 8x in
samples.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["faces_ok", "cells_ok"]


def _links(ndim: int) -> np.ndarray:
    """Neighbourhood of ndim-D samples inside one block of a stack (nothing across the stack's first axis)."""
    s = np.zeros((3,) * (ndim + 1), bool)
    s[1] = ndimage.generate_binary_structure(ndim, 1)
    s.setflags(write=False)
    return s


_LINKS = {2: _links(2), 3: _links(3)}


def _by_shape(values) -> list:
    """Index arrays of ``values`` grouped by array shape."""
    groups = {}
    for b, v in enumerate(values):
        groups.setdefault(v.shape, []).append(b)
    return [np.array(g) for g in groups.values()]


def _components(mask: np.ndarray):
    """Labels of the True samples of a stack ``mask`` (0 elsewhere) and each label's block (label 0: -1)."""
    label, n = ndimage.label(mask, _LINKS[mask.ndim - 1])
    block = np.full(n + 1, -1, np.int64)
    blocks = np.broadcast_to(np.arange(len(mask)).reshape((-1,) + (1,) * (mask.ndim - 1)), mask.shape)
    block[label[mask]] = blocks[mask]  # (all samples of a component lie in one block)
    return label, block


def _count(block: np.ndarray, n_blocks: int) -> np.ndarray:
    """Components per block, from the blocks of the labels 1, 2, ..."""
    return np.bincount(block[1:], minlength=n_blocks)


def faces_ok(values, centres) -> np.ndarray:
    """Per face of ``values`` (2-D sample arrays), whether it passes (module notes); ``centres[b]`` the (row,
    column) of face b's centre sample.  Returns a bool array (len(values),)."""
    ok = np.array([v[i, j] > 0 for v, (i, j) in zip(values, centres)], bool)
    for group in _by_shape(values):
        V = np.stack([values[b] for b in group])
        inside, outside = _components(V > 0)[1], _components(V <= 0)[1]
        ok[group] &= (_count(inside, len(group)) == 1) & (_count(outside, len(group)) == 1)
    return ok


def cells_ok(values) -> np.ndarray:
    """Per cell of ``values`` (3-D sample arrays), whether it passes (module notes): a bool array."""
    ok = np.zeros(len(values), bool)
    for group in _by_shape(values):
        V = np.stack([values[b] for b in group])
        one = _count(_components(V > 0)[1], len(group)) == 1
        label, block = _components(V <= 0)
        touched = np.zeros(len(block), bool)  # the outside components with a sample on a boundary layer
        touched[0] = True
        for k in range(1, 4):
            touched[np.take(label, [0, -1], axis=k)] = True
        pockets = np.bincount(block[~touched], minlength=len(group))  # outside components not reaching it
        ok[group] = one & (pockets == 0)
    return ok
