"""Planar walls cut by the six planes of the cell: Boolean sealing of surface tiles with oblique walls
(Elber 2017, Section 2).

Elber 2017 closes boundary tiles by "Boolean set operations with the six
planes u = u_min, ..., w = w_max"; squeezing a tile into the cell minus a
layer (:mod:`tiling.sealing.plates`, :mod:`tiling.sealing.shells`) changes the angles of
walls that cross the cell boundary obliquely.  :func:`clip_walls` takes the
walls of a periodic pattern as planar patches of any extent (parallelograms
that may reach far beyond the cell) and intersects each with the cell: the
plane's part inside the cube is a convex polygon, computed exactly
(Sutherland-Hodgman against the six half-spaces), cut into bilinear patches
by a fan from its first vertex (pairs of fan triangles as convex quads; an
odd triangle as a quad with one collapsed edge, the pole a sphere also has).
The polygon's edges stay whole, so the pieces of one wall, of neighbouring
walls and of neighbouring cells meet edge to edge and weld.  The result is
an ordinary surface tile inside the cell: its boundary curves on a wall are
the cut segments, which the caps (:mod:`tiling.sealing.caps`, ``seal="cap"``) chain
into the loops of the planar trimmed surfaces that close the cut, the other
half of the Boolean operation.

Curved walls are refused: their cuts are curves without an exact
representation in the surface's parameters, which this module does not
approximate.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry.errors import show
from geometry.tolerances import COINCIDENT

from tiling.errors import TilingError
from tiling.tile import Tile

__all__ = ["clip_walls", "clip_polygon"]

_FLAT = 1e-9  # relative: coplanarity of a wall's corners, and areas below which a cut piece is dropped


def _corners(wall: BSpline, i: int) -> np.ndarray:
    """The four corners of a planar parallelogram wall, in order around it (4, 3)."""
    if not isinstance(wall, BSpline) or wall.dim != 2 or wall.degrees != (1, 1) or wall.shape != (2, 2) \
            or wall.is_rational:
        raise TilingError(f"clip_walls: wall {i} must be a bilinear surface (degrees (1, 1), 2 x 2 control points, "
                          f"not rational), got {show(wall)}; curved walls have no exact cut (not built)")
    P = wall.control_points[..., :3]
    c = np.array([P[0, 0], P[1, 0], P[1, 1], P[0, 1]])
    size = float(np.ptp(c, axis=0).max())
    normal = np.cross(c[1] - c[0], c[3] - c[0])
    if np.linalg.norm(normal) < _FLAT * size ** 2 or abs(np.dot(c[2] - c[0], normal)) > \
            _FLAT * size * np.linalg.norm(normal):
        raise TilingError(f"clip_walls: wall {i} is not planar (or is degenerate): its corners "
                          f"{c.round(6).tolist()} do not span a plane; curved walls have no exact cut (not built)")
    return c


def clip_polygon(poly: np.ndarray) -> np.ndarray:
    """The convex polygon ``poly`` (n, 3), vertices in order, intersected with the unit cube (Sutherland-Hodgman,
    one half-space at a time); (m, 3), m = 0 where nothing is left."""
    for k in range(3):
        for bound, sign in ((0.0, 1.0), (1.0, -1.0)):
            if len(poly) == 0:
                return poly
            d = sign * (poly[:, k] - bound)  # >= 0: inside this half-space
            nxt = np.roll(np.arange(len(poly)), -1)
            out = []
            for a, b in zip(range(len(poly)), nxt):  # <= 8 vertices: the loop is over a polygon's corners
                if d[a] >= 0:
                    out.append(poly[a])
                if (d[a] >= 0) != (d[b] >= 0):
                    t = d[a] / (d[a] - d[b])
                    x = poly[a] + t * (poly[b] - poly[a])
                    x[k] = bound  # exactly on the plane
                    out.append(x)
            poly = np.array(out).reshape(-1, 3)
    if len(poly):  # drop repeated vertices (a corner of the polygon on a plane)
        keep = np.linalg.norm(poly - np.roll(poly, 1, axis=0), axis=1) > COINCIDENT
        poly = poly[keep] if keep.any() else poly[:1]
    return poly


def _bilinear(a, b, c, d) -> BSpline:
    """The bilinear patch with corners a (0, 0), b (1, 0), c (1, 1), d (0, 1)."""
    return BSpline((1, 1), [np.array([0.0, 0.0, 1.0, 1.0])] * 2, np.array([[a, d], [b, c]], float))


def _pieces(poly: np.ndarray) -> list[BSpline]:
    """A convex polygon as bilinear patches: fan triangles from vertex 0 paired into quads, an odd one left as a
    quad with its last edge collapsed (the polygon's edges stay whole)."""
    out = []
    i = 1
    while i + 1 < len(poly):
        if i + 2 < len(poly):
            out.append(_bilinear(poly[0], poly[i], poly[i + 1], poly[i + 2]))
            i += 2
        else:
            out.append(_bilinear(poly[0], poly[i], poly[i + 1], poly[i + 1]))
            i += 1
    return out


def clip_walls(walls, name: str = "clipped walls") -> Tile:
    """The planar ``walls`` (bilinear parallelograms of any extent, in cell coordinates) cut by the unit cell:
    a surface tile of the pieces inside (see the module notes).  Walls wholly outside the cell are dropped;
    the normal of every piece is its wall's."""
    if isinstance(walls, BSpline) or not isinstance(walls, (list, tuple)):
        raise TilingError(f"clip_walls needs a list of walls (bilinear geometry.BSpline surfaces), got {show(walls)}")
    walls = list(walls)
    if not walls:
        raise TilingError("clip_walls needs at least one wall (a bilinear surface)")
    patches = []
    for i, wall in enumerate(walls):
        c = _corners(wall, i)
        poly = clip_polygon(c)
        if len(poly) < 3:
            continue
        normal = np.cross(c[1] - c[0], c[3] - c[0])
        area = 0.5 * np.dot(np.sum(np.cross(poly, np.roll(poly, -1, axis=0)), axis=0), normal / np.linalg.norm(normal))
        if abs(area) < _FLAT:
            continue  # the wall only touches the cell (an edge or a corner)
        patches += _pieces(poly if area > 0 else poly[::-1])  # keep the wall's orientation
    if not patches:
        raise TilingError(f"clip_walls: none of the {len(walls)} walls passes through the unit cell [0, 1]^3; "
                          "give the walls in cell coordinates")
    return Tile(patches, name=name)
