"""Parametric caps of surface tiles: planar trimmed surfaces over the tile's boundary curves on the cell walls
(Massarwi et al. 2018, Section 6.2 item 1, Fig. 9(a, b)).

The boundary curves of a surface tile that lie on a wall of the unit cell
(x = 0, ..., z = 1) are chained end to start into closed loops; loops nest
by containment (even depth: an outer boundary, odd: a hole of the loop
around it) and every outer loop with its holes bounds one planar
:class:`geometry.TrimmedSurface` on that wall, its loops the joined curves
in the wall's two coordinates.  The cap becomes part of the tile and is
composed with it: the wall plane exactly through D, the loops unaltered
(Elber 2017, Fig. 7), so the cap's boundary is exactly the image of the
tile's boundary curves.  In :func:`tiling.export.surface` a cap is
triangulated with the very sample points of the tile's edges on its loops
(:func:`geometry.shapes.triangulate.fill_rings` keeps them), so caps weld to the
tile into a watertight surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline, TrimmedSurface
from geometry.errors import SplineError, show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.patches.multipatch import PlacedPatch
from geometry.shapes.trimmed import inside_polyline, join_curves, loop_polyline

from tiling.errors import TilingError
from tiling.sealing.plates import SealedTile
from tiling.tile import Tile
from geometry.tolerances import COINCIDENT

__all__ = ["Cap", "PlacedCap", "surface_caps", "capped_variant", "wall_loops", "trimmed_regions"]

EDGES = ("umin", "umax", "vmin", "vmax")  # the four boundary curves of a surface patch
_TOL = COINCIDENT  # unit-cell tiles: plates on a plane, chained curve ends


@dataclass
class Cap:
    """A cap on the cell wall ``side``: ``trimmed`` is the wall plane (tile coordinates, parameters = the wall's
    two axes in order) with its loops; ``segments[i]`` lists, for loop i, the tile's boundary curves it joins
    as (patch in tile, edge name, reversed), curve j running over the loop's parameters [j, j + 1], or is
    None for a loop that is no tile edge (a shell's cell rectangle, :mod:`tiling.sealing.shells`)."""

    side: str
    trimmed: TrimmedSurface
    segments: list


@dataclass
class PlacedCap:
    """A cap of a placed tile: ``placed`` is its wall plane placed and composed like the tile's patches;
    ``first`` the index of the tile's patch 0 in the micro-structure (its patches follow in order)."""

    cap: Cap
    placed: PlacedPatch
    first: int

    def composed(self) -> TrimmedSurface:
        """The cap in physical space, exact: the composed plane with the loops unaltered."""
        return TrimmedSurface.with_loops_of(self.cap.trimmed, self.placed.composed)


def wall_plane(k: int, s: int) -> BSpline:
    """The wall x_k = s of the unit cell as a bilinear surface, parameters = the other two axes in order."""
    rest = [j for j in range(3) if j != k]
    cp = np.zeros((2, 2, 3))
    cp[..., k] = s
    cp[..., rest[0]] = np.array([0.0, 1.0])[:, None]
    cp[..., rest[1]] = np.array([0.0, 1.0])[None, :]
    return BSpline((1, 1), [np.array([0.0, 0.0, 1.0, 1.0])] * 2, cp)


def _chain(segs, side: str, name: str) -> list:
    """Closed loops of segments [(patch, edge, curve)]: lists of (segment index, reversed)."""
    ends = [(c.evaluate(c.domain[:, :1].T)[0, :3], c.evaluate(c.domain[:, 1:].T)[0, :3]) for _, _, c in segs]
    unused, loops = set(range(len(segs))), []
    while unused:
        i = min(unused)
        unused.discard(i)
        loop, start, cur = [(i, False)], ends[i][0], ends[i][1]
        while np.linalg.norm(cur - start) > _TOL:
            nxt = next(((j, r) for j in sorted(unused) for r in (False, True)
                        if np.linalg.norm(ends[j][int(r)] - cur) <= _TOL), None)
            if nxt is None:
                p, e, _ = segs[loop[-1][0]]
                raise TilingError(f"tile {show(name)}: its boundary curves on the wall {side} do not close (the "
                                  f"{e} curve of patch {p} ends at {np.round(cur, 9).tolist()} and no curve "
                                  "continues it); a cap needs closed loops of boundary curves")
            unused.discard(nxt[0])
            loop.append(nxt)
            cur = ends[nxt[0]][1 - int(nxt[1])]
        loops.append(loop)
    return loops


def _loop_curve(segs, loop, rest) -> BSpline:
    """The loop as one curve (a(t), b(t), 0) in the wall's coordinates."""
    parts = []
    for j, rev in loop:
        c = segs[j][2]
        cp = np.zeros(c.control_points.shape[:-1] + (3,))
        cp[..., :2] = c.control_points[..., rest]
        w = None if c.weights is None else c.weights
        part = BSpline(c.degrees, c.knots, cp, w)
        if rev:
            part = part.reverse(0)
        parts.append(part)
    return join_curves(parts)


def surface_caps(tile: Tile, sides) -> list[Cap]:
    """The caps of ``tile`` (its 2-variate patches) on the cell walls ``sides``; see the module notes.

    A wall that one of the tile's surfaces already covers (lies in) gets no cap.
    """
    surfaces = surface_patches(tile, "cap")
    caps, touched = [], False
    for side in sorted(set(sides), key=FACE_NAMES.index):
        k, s = FACE_AXIS[side]
        if wall_covered(tile, surfaces, k, s):
            touched = True
            continue  # a tile surface lies in this wall: it is closed there already
        curves, seglists = wall_loops(tile, surfaces, side)
        touched |= bool(curves)
        caps += trimmed_regions(tile, side, wall_plane(k, s), curves, seglists)
    if not touched and sides and not _on_a_wall(tile, surfaces):
        raise TilingError(f"tile {show(tile.name)} has no boundary curves on the walls {sorted(set(sides))}: there is "
                          "nothing to cap (a cap closes the openings of a tile's surfaces on the cell walls)")
    return caps  # (none where the tile has no opening on these walls but has some on others: closed there)


def surface_patches(tile: Tile, what: str) -> list[int]:
    """Indices of the tile's surface patches; a tile without any cannot be given a ``what``."""
    surfaces = [i for i, p in enumerate(tile.patches) if p.dim == 2]
    if not surfaces:
        raise TilingError(f"tile {show(tile.name)} has no surface patches to {what}; trimmed caps and shells close "
                          "surface tiles (volumetric tiles are sealed by plates, curves cannot be capped)")
    return surfaces


def wall_covered(tile: Tile, surfaces: list, k: int, s: int) -> bool:
    """Whether one of the tile's surfaces lies in the wall x_k = s."""
    return any(np.abs(tile.patches[i].points.reshape(-1, 3)[:, k] - s).max() < _TOL for i in surfaces)


def _on_a_wall(tile: Tile, surfaces: list) -> bool:
    """Whether a boundary curve of one of the tile's surfaces lies on any wall of the cell."""
    for i in surfaces:
        for e in EDGES:
            pts = tile.patches[i].boundary(e).points.reshape(-1, 3)
            if np.any((np.abs(pts).max(axis=0) < _TOL) | (np.abs(pts - 1).max(axis=0) < _TOL)):
                return True
    return False


def wall_loops(tile: Tile, surfaces: list, side: str):
    """The boundary curves of the tile's ``surfaces`` on the wall ``side``, chained into closed loops:
    (loops as curves (a(t), b(t), 0) in the wall's two coordinates, per loop its segments [(patch, edge,
    reversed)]); empty lists where no curve lies on the wall."""
    k, s = FACE_AXIS[side]
    segs = []
    for i in surfaces:
        for e in EDGES:
            c = tile.patches[i].boundary(e)
            pts = c.points.reshape(-1, 3)
            if np.abs(pts[:, k] - s).max() < _TOL and np.ptp(pts, axis=0).max() > _TOL:  # (not a collapsed edge)
                segs.append((i, e, c))
    if not segs:
        return [], []
    rest = [j for j in range(3) if j != k]
    loops = _chain(segs, side, tile.name)
    return ([_loop_curve(segs, lp, rest) for lp in loops],
            [[(segs[q][0], segs[q][1], r) for q, r in lp] for lp in loops])


def trimmed_regions(tile: Tile, side: str, plane: BSpline, curves: list, seglists: list) -> list[Cap]:
    """The planar regions bounded by nested loops: every loop at even depth (inside an even number of the
    others) with the loops directly inside it as holes, one :class:`Cap` on ``plane`` each.  A loop's
    segments may be None (a loop that is not made of tile edges, such as a shell's cell rectangle)."""
    polys = [loop_polyline(c) for c in curves]
    inside = [[j for j in range(len(polys)) if j != i and inside_polyline(polys[j], polys[i][:1])[0]]
              for i in range(len(polys))]
    caps = []
    for i in range(len(polys)):
        if len(inside[i]) % 2:
            continue  # a hole
        holes = [j for j in range(len(polys)) if i in inside[j] and len(inside[j]) == len(inside[i]) + 1]
        order = [i] + holes
        try:
            ts = TrimmedSurface(plane, [curves[j] for j in order])
        except SplineError as exc:
            raise TilingError(f"tile {show(tile.name)}: the trimmed plane on wall {side}: {exc}") from None
        segments = []
        for j in order:
            lp = seglists[j]
            if lp is not None and ts.loops[len(segments)] is not curves[j]:  # the trimmed surface reversed it
                lp = [(q, e, not r) for q, e, r in reversed(lp)]
            segments.append(lp)
        caps.append(Cap(side, ts, segments))
    return caps


def capped_variant(tile: Tile, sides):
    """``tile`` with trimmed caps on ``sides`` (a :class:`tiling.sealing.plates.SealedTile` whose ``caps`` are set)."""
    caps = surface_caps(tile, sides)
    out = SealedTile(list(tile.patches), name=f"{tile.name} (cap {'+'.join(sorted(frozenset(sides)))})")
    out.caps = tuple(caps)
    out.seal = "cap"
    return out
