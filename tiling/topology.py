"""Interfaces of a paving by construction: a grid of cells, each filled with a known layout of patches.

A paving knows its neighbours.  Every cell of a regular or hierarchical
paving holds one of a few *layouts* (the tile, a sealed variant, a whole
hierarchy with its plates), placed by an axis-aligned affine map of the
unit cell.  Which faces of one layout glue to which (the tile's own
interfaces), and which faces on a cell wall glue to the neighbouring layout's
faces on the same wall, is a property of the layouts alone: it is found once
per layout and once per (layout, neighbour layout, direction), in the unit
cell, by :func:`geometry.detect_interfaces` on those few patches.  The
interfaces of the whole paving then follow by index arithmetic over the cell
grid, with no search through the model and no tolerance between placed
patches.  Neighbouring cells share the map of their common wall (their
placements differ only along the wall's normal), so faces that meet in the
unit cell meet in D's domain, and in space.

A map that closes on itself (D's faces at ``d = min`` and ``d = max``
coincide point for point, as a full annulus does along its angle) glues
the last cell along ``d`` to the first one in the same way (:func:`seams`).
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry.patches.multipatch import Interface, PlacedPatch, detect_interfaces
from geometry.tolerances import COINCIDENT, model_size

__all__ = ["seams", "grid_interfaces", "layout_pairs"]


def seams(D: BSpline) -> tuple[bool, bool, bool]:
    """Per direction, whether D's min and max faces coincide point for point (a periodic map, e.g. the angle of
    a full annulus): equal boundary control points and weights, to :data:`COINCIDENT` of the map's size."""
    cp = D.control_points[..., :3]
    scale = model_size(cp)
    out = []
    for d in range(3):
        same = np.abs(np.take(cp, 0, axis=d) - np.take(cp, -1, axis=d)).max() <= COINCIDENT * scale
        if same and D.weights is not None:
            same = np.abs(np.take(D.weights, 0, axis=d) - np.take(D.weights, -1, axis=d)).max() <= COINCIDENT
        out.append(bool(same) and D.shape[d] > 1)
    return tuple(out)


def _placed(layout, shift=None) -> list:
    """The layout [(spline, placement (3, 4) in the unit cell)] as placed patches, optionally shifted."""
    out = []
    for spline, M in layout:
        M = np.array(M, float)
        if shift is not None:
            M[:, 3] += shift
        out.append(PlacedPatch(spline, M))
    return out


def layout_pairs(a, b=None, direction: int | None = None):
    """Interfaces among the patches of layout ``a`` (``b`` None), or between ``a`` and ``b`` shifted by one cell
    along ``direction`` (faces of ``a`` on the wall x_d = 1 against faces of ``b`` on x_d = 0).

    Returns ``(pairs, mismatched)``: pairs [(i, face, j, face, swap, flip)] with i in ``a`` and j in ``b`` (or
    in ``a``), and the faces that meet corner to corner without conforming [(i, face, j, face, why)]."""
    if b is None:
        found, bad = detect_interfaces(_placed(a))
        return ([(i.a[0], i.a[1], i.b[0], i.b[1], i.swap, i.flip) for i in found],
                [(x[0], x[1], y[0], y[1], why) for x, y, why in bad])
    n = len(a)
    found, bad = detect_interfaces(_placed(a) + _placed(b, np.eye(3)[direction]))
    pairs = []
    for itf in found:
        if (itf.a[0] < n) == (itf.b[0] < n):
            continue  # a layout's own interface, counted by the layout
        # keep a's patch first; the orientation of (a, b) read the other way round is its inverse
        (pa, fa), (pb, fb), swap, flip = (itf.a, itf.b, itf.swap, itf.flip) if itf.a[0] < n else \
            (itf.b, itf.a, itf.swap, itf.flip[::-1] if itf.swap else itf.flip)
        pairs.append((pa, fa, pb - n, fb, swap, flip))
    cross = [(x, y, why) for x, y, why in bad if (x[0] < n) != (y[0] < n)]
    return pairs, [(x[0], x[1], y[0] - n, y[1], why) if x[0] < n else (y[0], y[1], x[0] - n, x[1], why)
                   for x, y, why in cross]


def grid_interfaces(grid: np.ndarray, first: np.ndarray, layouts: dict, periodic=(False, False, False)):
    """Identity interfaces of a paving whose cell ``c`` (an index of the array ``grid``, (N0, N1, N2)) holds the
    layout ``layouts[grid[c]]`` [(spline, unit-cell placement)] as the placed patches from ``first[c]`` on.

    Returns ``(interfaces, mismatched)`` in the placed patches' numbering: :class:`geometry.Interface` objects,
    and [((patch, face), (patch, face), why)] for faces that meet corner to corner without conforming.
    """
    own, walls = {}, {}
    interfaces, bad = [], []

    def add(pairs, mism, fa, fb):
        for i, f, j, g, swap, flip in pairs:
            if fa + i != fb + j:  # (one cell around a closed map: a patch is not glued to itself)
                interfaces.append(Interface("identity", (int(fa + i), f), (int(fb + j), g), swap, tuple(flip)))
        bad.extend(((int(fa + i), f), (int(fb + j), g), why) for i, f, j, g, why in mism)

    for c in np.ndindex(grid.shape):
        key = grid[c]
        if key not in own:
            own[key] = layout_pairs(layouts[key])
        add(*own[key], first[c], first[c])
        for d in range(3):
            nb = list(c)
            nb[d] += 1
            if nb[d] == grid.shape[d]:  # the last cell along d: glued to the first one across a seam
                if not periodic[d]:
                    continue
                nb[d] = 0
            other = grid[tuple(nb)]
            wk = (key, other, d)
            if wk not in walls:
                walls[wk] = layout_pairs(layouts[key], layouts[other], d)
            add(*walls[wk], first[c], first[tuple(nb)])
    return interfaces, bad
