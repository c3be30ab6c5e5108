"""Sealed boundary tiles: caps and shells as trivariate plates conforming to the tiles (Elber 2017, Sections 2-3;
Massarwi et al. 2018, Section 6.2).

A tile placed against D's boundary is sealed on the sides it touches: the
tile is scaled into the cell minus a layer of ``thickness`` on each sealed
side, and the layer is filled by box-shaped trivariate plates.  The plates
come from one grid of the cell: its lines are the layer's inner planes and
the edges of every planar boundary face of the tile (on all six sides,
scaled with the tile).  A tile face on a cell wall is taken piece by piece
between its discontinuities (knots of full multiplicity), and every piece
must be an axis-aligned rectangle parametrised affinely.

* Along each grid interval all plates share one spline space: the union of
  the knots of the face pieces over that interval (restricted to it), or
  linear where no piece lies; so plates meet plates in identity interfaces,
  also across cells (neighbouring cells use the same lines).
* A plate meeting a whole face piece with the piece's own space is glued to
  it by an identity interface; a plate meeting part of a piece, or a
  refinement of its space, by a refinement (``branch``) interface whose
  matrix restricts the piece's space to the plate's face (Massarwi et al.
  2018, Eqs. 11-12).  Hierarchies, where a base face and its children's
  faces meet one wall, are sealed this way.

The heat model therefore includes the seal: a cap is material, analysed
with the tiles.  Plates are tagged ``cap`` (or ``shell``).  Layouts are
built once per (tile, sealed sides) and cached: a paving of 10^4 cells
builds at most 27 (3^3 positions; with one cell in a direction both sides
are sealed).  Surface tiles are capped by trimmed planes instead
(:mod:`tiling.sealing.caps`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline
from geometry import knots as kn
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES

from tiling.errors import TilingError
from tiling.tile import Tile
from geometry.tolerances import COINCIDENT, ON_DOMAIN, SAME_KNOT
from geometry.numbers import is_real

__all__ = ["sealed_variant", "seal_layout", "inner_box", "SealedTile", "SealLayout"]

_TOL = COINCIDENT  # unit-cell tiles: plates on a plane


class SealedTile(Tile):
    """A :class:`Tile` with seal plates (``seal_patches``: a cap or shell, named ``seal``), its refinement links
    ``seal_links`` (tile patch, face, box, plate patch, plate face) and trimmed ``caps`` (surface tiles)."""

    seal_patches: tuple = ()
    seal_links: tuple = ()
    caps: tuple = ()
    seal: str = "cap"


@dataclass
class SealLayout:
    """Plates sealing a set of patches in the unit cell: the box ``inner`` (3, 2) the patches are squeezed into,
    the ``plates`` (trivariates in cell coordinates) and ``links`` (patch, face, box, plate, plate face) where a
    plate meets part of a patch face (refinement interfaces)."""

    inner: np.ndarray
    plates: list
    links: list

    def squeeze(self) -> np.ndarray:
        """(4, 4) affine map of the unit cell onto ``inner``."""
        out = np.eye(4)
        out[:3, :3] = np.diag(self.inner[:, 1] - self.inner[:, 0])
        out[:3, 3] = self.inner[:, 0]
        return out


@dataclass
class _Piece:
    """A piece of a patch face on a cell wall: axis ``k``, side ``s``, extent ``rect`` (2, 2) along the other
    axes (in order), the face's parameter ``box`` of the piece, its knots (normalised to [0, 1]) and degrees."""

    patch: int
    face: str
    k: int
    s: int
    rect: np.ndarray
    box: np.ndarray
    knots: list
    degs: tuple
    whole: bool  # the piece is the whole face (no discontinuity splits it)
    affine: bool  # the rectangle [lo, hi] parametrised affinely along the axes (box plates can meet it)


def _cuts(U, p):
    """Breakpoints of a knot vector where the space is discontinuous (multiplicity p + 1), ends included."""
    vals, mult = kn.breakpoints(U)
    return np.r_[vals[0], vals[1:-1][mult[1:-1] >= p + 1], vals[-1]]


def _wall_pieces(patches) -> list:
    """Every continuous piece of every trivariate face that lies on a cell wall (see :class:`_Piece`)."""
    out = []
    for pi, p in enumerate(patches):
        if p.dim != 3:
            continue
        for f in FACE_NAMES:
            k, s = FACE_AXIS[f]
            if np.abs(p.boundary(f).points.reshape(-1, 3)[:, k] - s).max() > _TOL:
                continue  # not on the cell wall
            face = p.boundary(f)
            rest = [j for j in range(3) if j != k]
            c0, c1 = (_cuts(U, d) for U, d in zip(face.knots, face.degrees))
            for a0, a1 in zip(c0[:-1], c0[1:]):
                for b0, b1 in zip(c1[:-1], c1[1:]):
                    box = np.array([[a0, a1], [b0, b1]])
                    piece = face.extract(box)
                    pts = piece.points.reshape(-1, 3)[:, rest]
                    lo, hi = pts.min(0), pts.max(0)
                    if np.any(hi - lo < _TOL):
                        continue  # a degenerate piece (a slot of zero width) has no area to seal
                    knots = [(U - U[0]) / (U[-1] - U[0]) for U in piece.knots]
                    # the piece must be the rectangle [lo, hi] parametrised affinely along the axes in order
                    g = np.meshgrid(*[kn.greville(U, d) for U, d in zip(knots, piece.degrees)], indexing="ij")
                    want = np.stack([lo[j] + g[j] * (hi[j] - lo[j]) for j in range(2)], -1)
                    w = piece.weights
                    affine = not (np.abs(piece.control_points[..., rest] - want).max() > 1e-7
                                  or (w is not None and np.ptp(w) > ON_DOMAIN))
                    out.append(_Piece(pi, f, k, s, np.stack([lo, hi], 1), box, knots, piece.degrees,
                                      len(c0) + len(c1) == 4, affine))
    return out


def _extent(piece: _Piece, a: int, inner) -> np.ndarray:
    """The piece's extent along axis ``a`` (!= its normal) in cell coordinates, after the squeeze."""
    j = [x for x in range(3) if x != piece.k].index(a)
    return inner[a, 0] + piece.rect[j] * (inner[a, 1] - inner[a, 0])


def _grid(pieces, inner) -> list:
    """Per axis the grid lines of the cell: 0, 1, the inner box and every wall piece's edges (scaled)."""
    lines = []
    for a in range(3):
        v = [0.0, 1.0, inner[a, 0], inner[a, 1]]
        for pc in pieces:
            if pc.k != a:
                v += list(_extent(pc, a, inner))
        lines.append(np.unique(np.round(v, 12)))
    return lines


def _interval_space(a, lo, hi, pieces, inner):
    """Knots (on [0, 1]) and degree of the plates along axis ``a`` over [lo, hi]: the union of the overlapping
    pieces' knots restricted to the interval, or linear where no piece lies."""
    deg, mult = None, {}
    for pc in pieces:
        if pc.k == a or not pc.affine:  # other pieces give grid lines only (their side cannot be sealed)
            continue
        f_lo, f_hi = _extent(pc, a, inner)
        if f_hi <= lo + _TOL or f_lo >= hi - _TOL:
            continue
        j = [x for x in range(3) if x != pc.k].index(a)
        d = pc.degs[j]
        if deg is not None and d != deg:
            raise TilingError(f"tile faces over [{lo:g}, {hi:g}] along axis {'xyz'[a]} have degrees {deg} and {d}; "
                              "sealing needs equal degrees there")
        deg = d
        vals, m = kn.breakpoints(f_lo + pc.knots[j] * (f_hi - f_lo))
        for v, c in zip(vals, m):
            if lo + _TOL < v < hi - _TOL:
                key = round((v - lo) / (hi - lo), 12)
                mult[key] = max(mult.get(key, 0), int(c))
    if deg is None:
        return np.array([0.0, 0.0, 1.0, 1.0]), 1
    inner_knots = [v for v in sorted(mult) for _ in range(mult[v])]
    return np.array([0.0] * (deg + 1) + inner_knots + [1.0] * (deg + 1)), deg


def _box(lo, hi, spaces) -> BSpline:
    """The box [lo, hi] as a trivariate with the given (knots on [0, 1], degree) per axis (identity-like map)."""
    degs = tuple(d for _, d in spaces)
    knots = [U for U, _ in spaces]
    g = [kn.greville(U, d) for U, d in spaces]  # linear functions have Greville coefficients
    X = np.stack(np.meshgrid(*[lo[a] + g[a] * (hi[a] - lo[a]) for a in range(3)], indexing="ij"), -1)
    return BSpline(degs, knots, X)


def _same_space(U, p, V, q) -> bool:
    return p == q and len(U) == len(V) and bool(np.abs(np.asarray(U) - np.asarray(V)).max() <= SAME_KNOT)


def inner_box(sides, thickness: float, seal: str = "cap") -> np.ndarray:
    """(3, 2) box the tile is squeezed into: the unit cell less a layer of ``thickness`` (a fraction of the
    cell, 0 < t < 0.5) on each of ``sides``; :class:`TilingError` for another thickness."""
    if not (is_real(thickness) and 0 < thickness < 0.5):
        raise TilingError(f"the {seal} thickness must be in (0, 0.5) of a cell, got {show(thickness)}")
    return np.array([[thickness if FACE_NAMES[2 * a] in sides else 0.0,
                      1.0 - thickness if FACE_NAMES[2 * a + 1] in sides else 1.0] for a in range(3)])


def seal_layout(patches, sides, thickness: float = 0.1, seal: str = "cap", name: str = "tile") -> SealLayout:
    """Plates sealing ``patches`` (unit-cell coordinates) on ``sides`` (cell face names); see the module notes.

    ``thickness`` is a fraction of the cell (0 < t < 0.5).
    """
    sides = frozenset(sides)
    if not sides <= set(FACE_NAMES):
        raise TilingError(f"sides must be cell face names from {list(FACE_NAMES)}, got {sorted(sides)}")
    inner = inner_box(sides, thickness, seal)
    if not any(p.dim == 3 for p in patches):
        raise TilingError(f"tile {show(name)} has no trivariate patches to seal with plates: volumetric {seal}s "
                          "need a volumetric tile (surface tiles are capped by trimmed planes, seal='cap')")
    pieces = _wall_pieces(patches)
    if not pieces:
        raise TilingError(f"tile {show(name)} has no boundary faces on the cell walls: nothing to seal to")
    for pc in pieces:
        f = FACE_NAMES[2 * pc.k + pc.s]
        if f in sides and not pc.affine:
            where = f"patch {pc.patch} face {pc.face}" + ("" if pc.whole else f" piece {pc.box.tolist()}")
            raise TilingError(f"tile {show(name)}: {where} lies on the cell wall {f} but is not an axis-aligned "
                              "rectangle parametrised affinely along the axes (e.g. a tapered fin); box plates "
                              f"cannot seal it: leave {f} out of seal_sides")
    lines = _grid(pieces, inner)
    spaces = [[_interval_space(a, x0, x1, pieces, inner) for x0, x1 in zip(lines[a][:-1], lines[a][1:])]
              for a in range(3)]
    plates, spans = [], []
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
                spans.append((lo, hi, sp))
    return SealLayout(inner, plates, _links(pieces, sides, inner, spans))


def _links(pieces, sides, inner, spans) -> list:
    """Refinement links from sealed wall pieces to the plates meeting them (identity where they match exactly)."""
    links = []
    for pc in pieces:
        if FACE_NAMES[2 * pc.k + pc.s] not in sides:
            continue
        rest = [x for x in range(3) if x != pc.k]
        plane = inner[pc.k, pc.s]
        ext = [_extent(pc, a, inner) for a in rest]
        for q, (lo, hi, sp) in enumerate(spans):
            if abs((hi if pc.s == 0 else lo)[pc.k] - plane) > _TOL:
                continue  # not in the layer against this wall
            if any(lo[a] < e[0] - _TOL or hi[a] > e[1] + _TOL for a, e in zip(rest, ext)):
                continue  # not against this piece
            whole = all(abs(lo[a] - e[0]) < _TOL and abs(hi[a] - e[1]) < _TOL for a, e in zip(rest, ext))
            if whole and pc.whole and all(_same_space(sp[a][0], sp[a][1], pc.knots[j], pc.degs[j]) for j, a in enumerate(rest)):
                continue  # the whole face with its own space: an identity interface, found by detection
            box = tuple((float(b0 + (lo[a] - e[0]) / (e[1] - e[0]) * (b1 - b0)),
                         float(b0 + (hi[a] - e[0]) / (e[1] - e[0]) * (b1 - b0)))
                        for (b0, b1), a, e in zip(pc.box, rest, ext))
            links.append((pc.patch, pc.face, box, q, FACE_NAMES[2 * pc.k + (1 - pc.s)]))
    return links


def sealed_variant(tile: Tile, sides, thickness: float = 0.1, seal: str = "cap") -> SealedTile:
    """``tile`` sealed on ``sides`` (face names of the cell): scaled inside, plates of ``thickness`` outside.

    ``thickness`` is a fraction of the cell (0 < t < 0.5).  See the module notes.
    """
    lay = seal_layout(tile.patches, sides, thickness, seal, tile.name)
    S = lay.squeeze()
    patches = [p.affine(S[:3, :3], S[:3, 3]) for p in tile.patches]
    n = len(patches)
    out = SealedTile(patches + lay.plates, name=f"{tile.name} ({seal} {'+'.join(sorted(frozenset(sides)))})")
    out.seal_patches = tuple(range(n, n + len(lay.plates)))
    out.seal_links = tuple((a, f, box, n + q, g) for a, f, box, q, g in lay.links)
    out.seal = seal
    return out
