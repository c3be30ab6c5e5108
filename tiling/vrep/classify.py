"""Tile classification in a V-model (Hong and Elber 2021, Section 3.1).

The tiles of a positive primitive P sit on the cells of its regular paving.
Each tile is sampled on an s^3 grid of its cell (parameters mapped through
P's map) and every sample is tested for P's territory (in the V-model and in
no positive primitive of higher priority: :meth:`VModel.territory`).  All
samples in: *inside*; none: *outside*; both: *intersecting* (the tile
crosses a trimming surface).  Sampling misses a trimming surface that passes
between samples, so tiles next to an intersecting one are sampled again with
two more points per direction (refinement) before they are called inside or outside:
the trimming surfaces here are smooth primitive boundaries whose features
are larger than a tile, which is what makes sampling plus refinement a firm
answer in practice, and it needs no surface-surface intersection.  Inside
tiles with an intersecting neighbour become *to-be-bridged*; their faces
towards a purged neighbour are *anchoring faces*.  A ``margin`` (model
units) purges to-be-bridged tiles closer than that to the boundary of a
primitive that bounds the territory from outside (Section 4, winged duck); the
inside tiles that this exposes are bridged in turn (or purged, if also too close).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.resources import check_memory

from geometry.faces import FACE_NAMES

from ..errors import TilingError
from ..checks import parameter_cells
from .model import Primitive, VModel

__all__ = ["Classification", "classify", "OUTSIDE", "INTERSECTING", "INSIDE", "TO_BE_BRIDGED", "MARGIN"]

OUTSIDE, INTERSECTING, INSIDE, TO_BE_BRIDGED, MARGIN = range(5)
STATES = ("outside", "intersecting", "inside", "to-be-bridged", "purged by margin")


@dataclass
class Classification:
    """Per tile of ``primitive`` (C order over its cell grid ``shape``): ``state`` (codes above), ``cells``
    (N, 3, 2) parameter boxes, and the ``anchors``: (tile, face name) of to-be-bridged tiles."""

    primitive: Primitive
    shape: tuple
    cells: np.ndarray
    state: np.ndarray
    anchors: list

    def counts(self) -> dict:
        """Number of tiles per state."""
        return {name: int(np.sum(self.state == code)) for code, name in enumerate(STATES)}

    @property
    def kept(self) -> np.ndarray:
        """Indices of the tiles kept: inside and to-be-bridged."""
        return np.flatnonzero((self.state == INSIDE) | (self.state == TO_BE_BRIDGED))


def _cell_boxes(prim: Primitive):
    cells = [parameter_cells(prim.D, k, prim.counts[k]) for k in range(3)]
    shape = tuple(len(c) for c in cells)
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1).reshape(-1, 3)
    boxes = np.stack([cells[k][idx[:, k]] for k in range(3)], 1)  # (N, 3, 2)
    return shape, boxes


def _tile_samples(D, boxes: np.ndarray, s: int) -> np.ndarray:
    """(N, s^3, 3) physical sample points of every cell box (s per direction, ends included)."""
    t = np.linspace(0.0, 1.0, s)
    g = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)  # (s^3, 3)
    params = boxes[:, None, :, 0] + g[None] * (boxes[:, None, :, 1] - boxes[:, None, :, 0])
    return D.evaluate(params.reshape(-1, 3))[:, :3].reshape(len(boxes), -1, 3)


def _states(model: VModel, prim: Primitive, boxes: np.ndarray, s: int) -> np.ndarray:
    pts = _tile_samples(prim.D, boxes, s)
    inside = model.territory(prim, pts.reshape(-1, 3)).reshape(len(boxes), -1)
    state = np.full(len(boxes), INTERSECTING)
    state[inside.all(axis=1)] = INSIDE
    state[~inside.any(axis=1)] = OUTSIDE
    return state


def _neighbours(shape) -> np.ndarray:
    """(N, 6) index of the face neighbour of every cell in FACE_NAMES order (-1 at the grid's boundary)."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    out = np.full(idx.shape + (6,), -1)
    for k in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[k], hi[k] = slice(1, None), slice(None, -1)
        out[tuple(lo) + (2 * k,)] = idx[tuple(hi)]      # the min-side neighbour
        out[tuple(hi) + (2 * k + 1,)] = idx[tuple(lo)]  # the max-side neighbour
    return out.reshape(-1, 6)


def classify(model: VModel, prim: Primitive, samples: int = 4, margin: float = 0.0) -> Classification:
    """Classify every tile of ``prim`` in ``model`` (see the module notes)."""
    n = int(np.prod(prim.counts)) * int(np.prod([len(prim.D.breakpoints(k)) - 1 for k in range(3)]))
    # the samples of every tile (s + 2 per direction for the second look), their images and inversions:
    # about 30 doubles per sample point alive at once
    check_memory(n * (samples + 2) ** 3 * 30 * 8.0, f"classifying the {n:,} tiles of primitive {prim.name!r} at "
                 f"{samples} samples per direction", TilingError, "lower samples (4 is the default) or the counts")
    shape, boxes = _cell_boxes(prim)
    state = _states(model, prim, boxes, samples)
    nb = _neighbours(shape)
    # refinement: uniform tiles next to an intersecting one are sampled again, twice as densely
    near = np.flatnonzero((state != INTERSECTING) & np.any((nb >= 0) & (state[nb] == INTERSECTING), axis=1))
    if len(near):
        again = _states(model, prim, boxes[near], samples + 2)
        state[near] = np.where(again == state[near], state[near], INTERSECTING)
    bridged = (state == INSIDE) & np.any((nb >= 0) & (state[nb] == INTERSECTING), axis=1)
    state[bridged] = TO_BE_BRIDGED
    while margin > 0 and bridged.any():  # purged tiles expose the next layer, which is bridged (or purged) in turn
        close = _near_boundary(model, prim, boxes[bridged], samples, margin)
        if not close.any():
            break
        state[np.flatnonzero(bridged)[close]] = MARGIN
        bridged = (state == INSIDE) & np.any((nb >= 0) & (state[nb] == MARGIN), axis=1)
        state[bridged] = TO_BE_BRIDGED
    purged = (state == OUTSIDE) | (state == INTERSECTING) | (state == MARGIN)
    anchors = [(int(i), FACE_NAMES[f]) for i in np.flatnonzero(state == TO_BE_BRIDGED)
               for f in range(6) if nb[i, f] >= 0 and purged[nb[i, f]]]
    return Classification(prim, shape, boxes, state, anchors)


def _near_boundary(model: VModel, prim: Primitive, boxes: np.ndarray, s: int, margin: float) -> np.ndarray:
    """Per tile: whether a sample lies nearer than ``margin`` to a primitive that bounds ``prim``'s territory
    from outside (a subtracted or higher-priority primitive the tile lies outside of)."""
    flat = _tile_samples(prim.D, boxes, s).reshape(-1, 3)
    near = np.zeros(len(flat), bool)
    for q in model.primitives():
        if q is prim or (q in model.positive() and q.priority <= prim.priority):
            continue
        rest = np.flatnonzero(~near)
        near[rest] = q.within(flat[rest], margin)
    return near.reshape(len(boxes), -1).any(axis=1)
