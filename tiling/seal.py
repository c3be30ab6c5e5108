"""Sealed boundary tiles: caps and shells as trivariate plates conforming to the tiles (Elber 2017, Sections 2-3;
Massarwi et al. 2018, Section 6.2).

A tile placed against D's boundary is sealed on the sides it touches: the
tile is scaled into the cell minus a layer of ``thickness`` on each sealed
side, and the layer is filled by box-shaped trivariate plates.  The plates
come from one grid of the cell per tile: its lines are the layer's inner
planes and the edges of every planar boundary face of the tile (on all six
sides, scaled with the tile), so

* a plate lying on a tile's boundary face has that face's degrees and knots
  in the two in-face directions: tile and plate meet in identity interfaces;
* plates meet each other on whole grid faces with equal spaces (the knots
  of a grid interval are the tile's where a tile face spans it, linear
  elsewhere): identity interfaces again;
* neighbouring cells use the same lines in the directions they share, so
  their plates and tiles conform across cell faces as well.

The heat model therefore includes the seal: a cap is no longer a surface
but material, analysed with the tiles.  Plates are tagged ``cap`` (or
``shell``) through :attr:`SealedTile.seal_patches`.  Variants are built
once per (tile, sealed sides) and cached: a paving of 10^4 cells builds at
most 27 (3^3 positions; with one cell in a direction both sides are sealed).
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry import knots as kn
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES

from .errors import TilingError
from .tile import Tile

__all__ = ["sealed_variant", "SealedTile"]

_TOL = 1e-9


class SealedTile(Tile):
    """A :class:`Tile` whose patches ``seal_patches`` are seal plates (a cap or a shell, named ``seal``)."""

    seal_patches: tuple = ()
    seal: str = "cap"


def _boundary_faces(tile: Tile) -> list:
    """Planar, axis-aligned faces of the tile's trivariates on the cell walls: (axis, side, rect (2, 2), knots, degs).

    rect[j] is the face's extent along its j-th in-face axis (increasing axis order); knots/degs are the
    face's knot vectors and degrees along those axes (normalised to the extent).
    """
    out = []
    for p in tile.patches:
        if p.dim != 3:
            continue
        for f in FACE_NAMES:
            k, s = FACE_AXIS[f]
            pts = p.boundary(f).control_points[..., :3].reshape(-1, 3)
            if np.abs(pts[:, k] - s).max() > _TOL:
                continue  # not on the cell wall
            rest = [j for j in range(3) if j != k]
            lo, hi = pts[:, rest].min(0), pts[:, rest].max(0)
            face = p.boundary(f)
            # the face must be the axis-aligned rectangle, parametrised along the axes in order
            c00 = face.evaluate(face.domain[:, :1].T)[0, :3]
            c10 = face.evaluate(np.array([[face.domain[0, 1], face.domain[1, 0]]]))[0, :3]
            c01 = face.evaluate(np.array([[face.domain[0, 0], face.domain[1, 1]]]))[0, :3]
            if not (np.allclose(c00[rest], lo, atol=_TOL) and np.isclose(c10[rest[0]], hi[0], atol=_TOL)
                    and np.isclose(c01[rest[1]], hi[1], atol=_TOL)):
                raise TilingError(f"tile {show(tile.name)}: a boundary face on {f} is not an axis-aligned rectangle "
                                  "parametrised along the axes; sealing needs such faces")
            knots = [(U - U[0]) / (U[-1] - U[0]) for U in face.knots]
            out.append((k, s, np.stack([lo, hi], 1), knots, face.degrees))
    return out


def _grid(tile: Tile, faces, inner) -> list:
    """Per axis the grid lines of the cell: 0, 1, the inner box and every boundary face's edges (scaled)."""
    lines = []
    for a in range(3):
        v = [0.0, 1.0, inner[a, 0], inner[a, 1]]
        for k, _, rect, _, _ in faces:
            if k == a:
                continue
            j = [x for x in range(3) if x != k].index(a)
            v += list(inner[a, 0] + rect[j] * (inner[a, 1] - inner[a, 0]))
        lines.append(np.unique(np.round(v, 12)))
    return lines


def _interval_space(a, lo, hi, faces, inner):
    """Knots (normalised) and degree of the plates along axis ``a`` over [lo, hi]: a tile face's, or linear."""
    found = None
    for k, _, rect, knots, degs in faces:
        if k == a:
            continue
        j = [x for x in range(3) if x != k].index(a)
        f_lo = inner[a, 0] + rect[j, 0] * (inner[a, 1] - inner[a, 0])
        f_hi = inner[a, 0] + rect[j, 1] * (inner[a, 1] - inner[a, 0])
        if abs(f_lo - lo) < _TOL and abs(f_hi - hi) < _TOL:
            space = (tuple(np.round(knots[j], 12)), degs[j])
            if found is not None and found != space:
                raise TilingError(f"tile faces spanning [{lo:g}, {hi:g}] along axis {a} have different knots "
                                  "or degrees; sealing needs them equal")
            found = space
    if found is None:
        return np.array([0.0, 0.0, 1.0, 1.0]), 1
    return np.array(found[0]), found[1]


def _box(lo, hi, spaces) -> BSpline:
    """The box [lo, hi] as a trivariate with the given (knots on [0, 1], degree) per axis (identity-like map)."""
    degs = tuple(d for _, d in spaces)
    knots = [U for U, _ in spaces]
    g = [kn.greville(U, d) for U, d in spaces]  # linear functions have Greville coefficients
    X = np.stack(np.meshgrid(*[lo[a] + g[a] * (hi[a] - lo[a]) for a in range(3)], indexing="ij"), -1)
    return BSpline(degs, knots, X)


def sealed_variant(tile: Tile, sides, thickness: float = 0.1, seal: str = "cap") -> SealedTile:
    """``tile`` sealed on ``sides`` (face names of the cell): scaled inside, plates of ``thickness`` outside.

    ``thickness`` is a fraction of the cell (0 < t < 0.5).  See the module notes.
    """
    sides = frozenset(sides)
    if not sides <= set(FACE_NAMES):
        raise TilingError(f"sides must be cell face names from {list(FACE_NAMES)}, got {sorted(sides)}")
    if not (isinstance(thickness, (int, float)) and 0 < thickness < 0.5):
        raise TilingError(f"the {seal} thickness must be in (0, 0.5) of a cell, got {show(thickness)}")
    if not tile.trivariates:
        raise TilingError(f"tile {show(tile.name)} has no trivariate patches to seal: volumetric caps need a "
                          "volumetric tile (surface tiles are capped by trimmed surfaces)")
    faces = _boundary_faces(tile)
    if not faces:
        raise TilingError(f"tile {show(tile.name)} has no boundary faces on the cell walls: nothing to seal to")
    inner = np.array([[thickness if FACE_NAMES[2 * a] in sides else 0.0,
                       1.0 - thickness if FACE_NAMES[2 * a + 1] in sides else 1.0] for a in range(3)])
    scale, shift = inner[:, 1] - inner[:, 0], inner[:, 0]
    patches = []
    for p in tile.patches:
        cp = p.control_points.copy()
        cp[..., :3] = shift + cp[..., :3] * scale
        patches.append(BSpline(p.degrees, p.knots, cp, p.weights, p.channels))
    lines = _grid(tile, faces, inner)
    spaces = [[_interval_space(a, x0, x1, faces, inner) for x0, x1 in zip(lines[a][:-1], lines[a][1:])]
              for a in range(3)]
    plates = []
    for i in range(len(lines[0]) - 1):
        for j in range(len(lines[1]) - 1):
            for k in range(len(lines[2]) - 1):
                lo = np.array([lines[0][i], lines[1][j], lines[2][k]])
                hi = np.array([lines[0][i + 1], lines[1][j + 1], lines[2][k + 1]])
                centre = 0.5 * (lo + hi)
                if np.all((centre > inner[:, 0]) & (centre < inner[:, 1])):
                    continue  # inside the tile's box
                # along the layer's normal the plate is linear (one element through the thickness)
                sp = [spaces[0][i], spaces[1][j], spaces[2][k]]
                for a in range(3):
                    if centre[a] < inner[a, 0] or centre[a] > inner[a, 1]:
                        sp[a] = (np.array([0.0, 0.0, 1.0, 1.0]), 1)
                plates.append(_box(lo, hi, sp))
    for k, s, rect, _, _ in faces:  # a sealed face must meet one plate face, not several
        if FACE_NAMES[2 * k + s] not in sides:
            continue
        for j, a in enumerate(x for x in range(3) if x != k):
            f_lo, f_hi = inner[a, 0] + rect[j] * scale[a]
            if np.any((lines[a] > f_lo + _TOL) & (lines[a] < f_hi - _TOL)):
                raise TilingError(f"tile {show(tile.name)}: its face on {FACE_NAMES[2 * k + s]} is crossed by "
                                  "edges of its other boundary faces, so no single plate can meet it; sealing "
                                  "needs boundary faces whose edges line up")
    out = SealedTile(patches + plates, name=f"{tile.name} ({seal} {'+'.join(sorted(sides))})")
    out.seal_patches = tuple(range(len(patches), len(patches) + len(plates)))
    out.seal = seal
    return out
