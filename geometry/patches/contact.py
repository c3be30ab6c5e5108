"""Contact without an interface: faces of different patches that lie on each other but are not glued.

A missing interface leaves two touching faces free, so the model falls
apart there without a word; these checks find such pairs.
:func:`unglued_contacts` is the cheap, vectorised test every paving runs
(coinciding sample points of free faces, one KD-tree); user lists of patches
get the thorough one of :meth:`geometry.MultiPatch.from_splines` (a free
face's samples inverted into every other patch).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from geometry.faces import FACE_NAMES
from geometry.patches.multipatch import FACE_SAMPLES, TOL, face_points, free_face_mask
from geometry.tolerances import model_size

__all__ = ["unglued_contacts"]

#: free faces sampled per batch: the whole 222k free faces of a 21^3 cross lattice at once took 120 MiB of
#: transients (placements, placed points, the map's basis), more than the model they check
_CHUNK = 2**14


def unglued_contacts(patches, interfaces, limit: int = 5, mask=None) -> list[tuple[tuple, tuple]]:
    """Pairs of free faces of different patches that touch: a sample point of one lies on a sample of the other.

    Every free face is sampled at its centre (which every orientation maps
    onto the other face's centre) and four interior points; two free faces
    sharing one of these points (within the coupling tolerance) lie on each
    other, so an interface is missing or the faces do not conform.  One batched evaluation and one KD-tree; returns at
    most ``limit`` pairs [((patch, face), (patch, face))].  ``mask``: the free faces'
    :func:`geometry.patches.multipatch.free_face_mask`, when the caller has it.
    """
    pidx, free_mask = free_face_mask(patches, interfaces) if mask is None else mask
    t, f = np.nonzero(free_mask)  # patch then face order, as free_faces; arrays, not a tuple per face
    free = np.stack([pidx[t], f], axis=1)
    if len(free) < 2:
        return []
    pts = np.empty((len(free), len(FACE_SAMPLES), 3))  # (F, n, 3)
    for a in range(0, len(free), _CHUNK):  # in chunks: the evaluation's transients stay a few MiB
        pts[a:a + _CHUNK] = face_points(patches, free[a:a + _CHUNK], FACE_SAMPLES)
    scale = model_size(pts)
    flat = pts.reshape(-1, 3)
    owner = np.repeat(np.arange(len(free)), pts.shape[1])
    # midpoint splits (balanced_tree=False) build faster on these 10^5-10^6 points; the pairs are the same
    pairs = cKDTree(flat, balanced_tree=False).query_pairs(TOL * scale, output_type="ndarray")
    if not len(pairs):
        return []
    fa, fb = owner[pairs[:, 0]], owner[pairs[:, 1]]
    hit = np.unique(np.sort(np.stack([fa, fb], 1)[free[fa, 0] != free[fb, 0]], axis=1), axis=0)
    return [tuple((int(free[i, 0]), FACE_NAMES[free[i, 1]]) for i in (a, b)) for a, b in hit[:limit]]
