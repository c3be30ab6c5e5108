"""Shells of surface tiles: a closed skin of ``thickness`` over D's boundary (Massarwi et al. 2018, Section 6.2
item 2, Fig. 9(c, d)).

A surface tile placed against D's boundary is squeezed into the cell minus a
layer of ``thickness`` (a fraction of the cell) on each sealed side, as the
volumetric seal does (:mod:`tiling.sealing.plates`).  On each sealed side the layer is
bounded by two planes with opposite orientations: the outer plane, the whole
cell wall (a bilinear surface patch, normal pointing out of D), and the
inner plane, the layer's inner face, trimmed by the squeezed tile's boundary
curves on that wall with reversed orientation: its loops are the cell's
rectangle and the tile's openings as holes (and, where openings nest, the
islands between them), built like caps (:func:`tiling.sealing.caps.trimmed_regions`)
with the rectangle as the outermost loop.  The paper closes each tile's
shell by four planar side strips into a box; in a paving those strips would
stand between neighbouring shells as double inner walls, so they are left
out and the shells of neighbouring cells continue each other: the outer
planes tile D's boundary, the inner planes the boundary of the core (D's
domain less the layer), and the tiles' openings open into the layer.  The
result is one closed surface: the boundary of the layer united with the
tiles' tubes (:func:`tiling.export.watertightness`).

In :func:`tiling.export.surface` the rectangle of an inner plane is sampled
with ``2 * samples`` points per side, as the rectangles of the neighbouring
cells sample their shared sides, and its holes with the tile's own edge
samples, so the whole skin welds.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.shapes.trimmed import join_curves

from tiling.sealing.caps import wall_covered, surface_patches, wall_plane, trimmed_regions, wall_loops
from tiling.errors import TilingError
from tiling.sealing.plates import SealedTile, inner_box
from tiling.tile import Tile

__all__ = ["shelled_variant"]

_RECT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])


def _rectangle() -> BSpline:
    """The unit square of the wall's parameters as one closed degree-1 loop, counter-clockwise."""
    sides = [BSpline((1,), [[0.0, 0.0, 1.0, 1.0]], np.c_[_RECT[i:i + 2], np.zeros(2)]) for i in range(4)]
    return join_curves(sides)


def _outward_wall(k: int, s: int) -> BSpline:
    """The wall x_k = s of the unit cell, its normal (S_u x S_v) pointing out of the cell."""
    plane = wall_plane(k, s)
    cp = plane.control_points
    normal = np.cross(cp[1, 0] - cp[0, 0], cp[0, 1] - cp[0, 0])
    return plane if normal[k] * (2 * s - 1) > 0 else plane.reverse(0)


def shelled_variant(tile: Tile, sides, thickness: float) -> SealedTile:
    """``tile`` (a surface tile) squeezed away from ``sides`` by ``thickness`` and shelled there (see the
    module notes): its patches squeezed, then one outer wall patch per side; ``caps`` the trimmed inner
    planes; ``seal`` is ``"shell"``."""
    surfaces = surface_patches(tile, "shell")
    sides = sorted(set(sides), key=FACE_NAMES.index)
    inner = inner_box(sides, thickness, "shell")
    for side in sides:
        if wall_covered(tile, surfaces, *FACE_AXIS[side]):
            raise TilingError(f"tile {show(tile.name)}: one of its surfaces lies in the wall {side}, so a shell there "
                              "would double it; shell a tile whose surfaces open onto the cell walls (e.g. "
                              "library.hollow_cross())")
    A, b = np.diag(inner[:, 1] - inner[:, 0]), inner[:, 0]
    patches = [p.affine(A, b) for p in tile.patches]
    walls = [_outward_wall(*FACE_AXIS[side]) for side in sides]
    caps = []
    for side in sides:
        curves, seglists = wall_loops(tile, surfaces, side)
        inner = wall_plane(*FACE_AXIS[side]).affine(A, b)  # the squeezed wall: the layer's inner face
        caps += trimmed_regions(tile, side, inner, [_rectangle()] + curves, [None] + seglists)
    out = SealedTile(patches + walls, name=f"{tile.name} (shell {'+'.join(sides)})")
    out.seal_patches = tuple(range(len(patches), len(patches) + len(walls)))
    out.caps = tuple(caps)
    out.seal = "shell"
    return out
