"""Layered bifurcation tilings with parametric tiles (Massarwi et al. 2018, Section 5.2, Figs. 8, 15, 17).

D's parameter domain is cut into layers along the growth ``direction``
(Algorithm 1 restricted to that direction, :func:`tiling.branching.subdivision.topo_subdiv`);
every layer is a grid of cells across it whose size is halved (1-2 along the
first cross direction; 1-4a along both; 1-4b quartered along the first) per
*level*, the smallest level whose cells' edge images stay below ``epsilon``.
Neighbouring layers differ by at most one level and a layer is never finer
than both neighbours (smoothing raises it), so every transition is one
bifurcation: the coarse cell below a finer layer holds a *split* tile that
feeds its 2 or 4 finer neighbours; the coarse cell above a finer layer holds
the mirrored *join* tile.  Other cells hold the *straight* tile.

Tiles (:func:`bifurcation_tiles`) are volumetric: a column of square
cross-section ``[c, 1 - c]^2`` along the growth axis (straight); a split tile
is a trunk of 2 or 4 blocks (the footprint cut into strips) and as many
sheared arms, each from one strip on the trunk's top to the column footprint
of one finer cell at the tile's top (parallelepipeds: exact under an affine
map), so the split is one closed 2-manifold.  Across a layer plane a block's
strip face meets a whole column face: the smaller face is constrained to the
larger one's restriction by refinement matrices (a ``branch`` interface,
Massarwi et al. 2018, Eqs. 11-12), exactly as in the hierarchical tiling;
equal faces are glued by identity.  The result is a :class:`Microstructure`,
a heat model.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline, knots as kn
from geometry.patches.sampling import sample_axes
from geometry.errors import show

from tiling.errors import TilingError
from tiling.microstructure import Microstructure, PlacedPatch
from tiling.checks import check_budget, check_map, check_spans
from tiling.tile import Tile, refuse_trimmed
from tiling.branching.subdivision import edge_lengths, topo_subdiv
from geometry.tolerances import ON_DOMAIN, SNAP
from geometry.numbers import is_flag, is_integer, is_real

__all__ = ["bifurcation", "bifurcation_tiles", "smooth_levels", "SPLITS"]

#: cells of the finer layer per coarse cell along the two cross directions
SPLITS = {"1-2": (2, 1), "1-4a": (2, 2), "1-4b": (4, 1)}
_MAX_LEVEL = 12


def _block(bottom, top, z0: float = 0.0, z1: float = 1.0) -> BSpline:
    """Trilinear block from an axis-aligned bottom rectangle (z = z0) to a top one (z = z1): ((x0, x1), (y0, y1))
    each."""
    cp = np.zeros((2, 2, 2, 3))
    for k, (rx, ry) in enumerate((bottom, top)):
        for i in range(2):
            for j in range(2):
                cp[i, j, k] = (rx[i], ry[j], (z0, z1)[k])
    U = kn.uniform_knots(1, 1)
    return BSpline((1, 1, 1), [U, U, U], cp)


def bifurcation_tiles(kind: str = "1-2", margin: float = 0.3, surfaces: bool = False, trunk: float = 0.25) -> dict:
    """The straight, split and join tiles of one bifurcation kind (tile coordinates, growth along z).

    ``margin``: the column's footprint is ``[margin, 1 - margin]^2``.  The
    split tile is a trunk and its arms (Massarwi et al. 2018, Fig. 15: a
    branching tube): the footprint cut into strips, one block per strip from
    z = 0 to ``trunk`` (blocks glued to each other by their shared faces, so
    the trunk is one solid), then one sheared block per strip from there to the
    footprint of finer cell i at the top (cells ordered x fastest).  The arms
    part along the trunk's top: between two arms the surface folds along a
    line of the trunk's top face, one closed 2-manifold (arms that started at
    z = 0 would meet the free bottom of a boundary layer in an edge of four
    faces).  The join tile is the split tile upside down.  ``surfaces``: the
    tiles of bicubic surfaces instead (as the paper's Fig. 8): the side walls
    of every block that no other block of the tile shares, degree raised to 3,
    an open branching tube for surface micro-structures and printing (not a
    heat model).
    """
    if kind not in SPLITS:
        raise TilingError(f"tile must be one of {list(SPLITS)} (bifurcation kinds), got {show(kind)}")
    if not is_real(margin) or not 0 < margin < 0.5:
        raise TilingError(f"margin must be in (0, 0.5) (the column's distance from the cell's sides), got "
                          f"{show(margin)}")
    if not is_real(trunk) or not 0 < trunk < 1:
        raise TilingError(f"trunk must be in (0, 1) (the height of the split tile's common part), got {show(trunk)}")
    sx, sy = SPLITS[kind]
    c0, c1 = margin, 1.0 - margin
    w = c1 - c0
    strips, tops = [], []
    for j in range(sy):
        for i in range(sx):
            strips.append(((c0 + i * w / sx, c0 + (i + 1) * w / sx), (c0 + j * w / sy, c0 + (j + 1) * w / sy)))
            tops.append((((i + c0) / sx, (i + c1) / sx), ((j + c0) / sy, (j + c1) / sy)))
    foot = ((c0, c1), (c0, c1))
    split = [_block(s, s, 0.0, trunk) for s in strips] + [_block(s, t, trunk, 1.0) for s, t in zip(strips, tops)]
    join = [_block(t, s, 0.0, 1.0 - trunk) for s, t in zip(strips, tops)] + [_block(s, s, 1.0 - trunk, 1.0)
                                                                           for s in strips]
    blocks = {"straight": [_block(foot, foot)], "split": split, "join": join}
    if surfaces:
        blocks = {k: [b.boundary(f).elevate_to((3, 3)) for b, f in _outer_walls(v)] for k, v in blocks.items()}
    names = {"straight": "column", "split": f"bifurcation {kind}", "join": f"bifurcation {kind} (join)"}
    return {k: Tile(v, name=names[k] + (" (surfaces)" if surfaces else "")) for k, v in blocks.items()}


def _outer_walls(blocks) -> list:
    """(block, face) of the side walls that no other block of the tile shares (the trunk's inner walls are
    interior)."""
    walls = []
    for b in blocks:
        for f in ("umin", "umax", "vmin", "vmax"):
            walls.append((b, f, np.round(b.boundary(f).control_points[..., :3].reshape(-1, 3), 12)))
    out = []
    for b, f, pts in walls:
        key = sorted(map(tuple, pts))
        if sum(sorted(map(tuple, q)) == key for _, _, q in walls) == 1:
            out.append((b, f))
    return out


def _user_tiles(given: dict) -> dict:
    """Check user bifurcation tiles: every tile has branch faces on z = 0 and z = 1 (planar, axis-aligned)."""
    if given.get("kind") not in SPLITS:
        raise TilingError(f"tile['kind'] must be one of {list(SPLITS)}, got {show(given.get('kind'))}")
    out = {}
    for name in ("straight", "split", "join"):
        t = given.get(name)
        if not isinstance(t, Tile) or not all(p.dim == 3 for p in t.patches):
            raise TilingError(f"tile[{name!r}] must be a tiling.Tile of trivariates, got {type(t).__name__}")
        refuse_trimmed(t, "the bifurcation tiling")
        for z, face, what in ((0, "wmin", "branch-in"), (1, "wmax", "branch-out")):
            flat = [p for p in t.patches if np.allclose(p.boundary(face).control_points[..., 2], z, atol=ON_DOMAIN)]
            if not flat:
                raise TilingError(f"tile[{name!r}] ({t.name}) has no {what} face: no patch's {face} face lies "
                                  f"on z = {z}; bifurcation tiles connect to the layers below and above there")
        out[name] = t
    return out


def _breaks(breaks, n) -> np.ndarray:
    """Breakpoints with every span cut into ``n`` equal parts."""
    return sample_axes([breaks], n)[0]


def _layers(D, g, epsilon, levels):
    """Layer intervals (L, 2) along direction g, and their levels (L,) before smoothing."""
    if levels is not None:
        if not isinstance(levels, (list, tuple, np.ndarray)) or not len(levels) or not all(
                is_integer(v) and 0 <= v <= _MAX_LEVEL for v in levels):
            raise TilingError(f"levels must be a list of integers in [0, {_MAX_LEVEL}], one per layer, got "
                              f"{show(levels)}")
        if min(int(v) for v in levels) > 0:
            # no layer of one column joins the columns of the finer ones: the structure would be separate pieces
            raise TilingError(f"levels {show([int(v) for v in levels])} have no layer at level 0, so nothing joins "
                              f"the columns of level {min(int(v) for v in levels)}: the structure would fall apart "
                              "into separate pieces; start (or end) the layers at level 0, e.g. [0, 1, 2, 1, 0]")
        b = D.breakpoints(g)
        if len(levels) % (len(b) - 1):
            raise TilingError(f"{len(levels)} levels do not split D's {len(b) - 1} knot spans along direction {g} "
                              f"into equal layers; give a multiple of {len(b) - 1}")
        cuts = _breaks(b, len(levels) // (len(b) - 1))
        return np.stack([cuts[:-1], cuts[1:]], 1), np.asarray(levels, int)
    layers = topo_subdiv(D, epsilon, directions=(g,))
    iv = np.unique(layers.boxes[:, g, :], axis=0)
    return iv, None


def _level_of(D, g, cross, splits, layer, epsilon):
    """Smallest level whose cells in ``layer`` have every edge image below epsilon along the split directions."""
    spans = [D.breakpoints(k) for k in cross]
    for lev in range(_MAX_LEVEL + 1):
        cuts = [_breaks(b, s ** lev) for b, s in zip(spans, splits)]
        boxes = np.zeros(((len(cuts[0]) - 1) * (len(cuts[1]) - 1), 3, 2))
        ii, jj = np.meshgrid(np.arange(len(cuts[0]) - 1), np.arange(len(cuts[1]) - 1), indexing="ij")
        for k, cut, idx in ((cross[0], cuts[0], ii.ravel()), (cross[1], cuts[1], jj.ravel())):
            boxes[:, k, 0], boxes[:, k, 1] = cut[idx], cut[idx + 1]
        boxes[:, g] = layer
        split_dirs = [k for k, s in zip(cross, splits) if s > 1]  # 1-2, 1-4b refine one cross direction only
        if np.all(edge_lengths(D, boxes)[:, split_dirs] < epsilon):
            return lev
    raise TilingError(f"a layer needs more than {_MAX_LEVEL} bifurcation levels for epsilon={show(epsilon)}; "
                      "raise epsilon")


def smooth_levels(levels) -> np.ndarray:
    """Raise levels until neighbours differ by at most one and no layer is coarser than both neighbours.

    A layer coarser than both neighbours would need a join and a split tile at once.
    """
    lev = np.array(levels, int)
    for _ in range(4 * len(lev) * (_MAX_LEVEL + 1)):
        new = lev.copy()
        new[1:] = np.maximum(new[1:], lev[:-1] - 1)
        new[:-1] = np.maximum(new[:-1], lev[1:] - 1)
        valley = np.zeros(len(lev), bool)
        valley[1:-1] = (new[:-2] > new[1:-1]) & (new[2:] > new[1:-1])
        new[valley] += 1
        if np.array_equal(new, lev):
            return lev
        lev = new
    return lev


def bifurcation(D: BSpline, epsilon: float | None = None, tile: str = "1-2", *, direction: int = 2,
                levels=None, margin: float = 0.3, surfaces: bool = False, name: str = "bifurcation") -> Microstructure:
    """Layered bifurcation micro-structure of D (module notes): a heat model with branch constraints.

    Parameters
    ----------
    D : trivariate deformation map
    epsilon : largest image of a cell edge (model units): sets the layers (Algorithm 1 along
        ``direction``) and each layer's level; or None with ``levels``
    tile : "1-2", "1-4a" (2 x 2) or "1-4b" (1 x 4); or your own tiles as
        {"kind": one of those, "straight": Tile, "split": Tile, "join": Tile} (tile coordinates,
        growth along z; see :func:`bifurcation_tiles` for the layout they must follow)
    direction : growth direction (0, 1 or 2); layers are stacked along it
    levels : explicit level per layer (layers split D's knot spans along ``direction`` equally);
        smoothed like computed ones
    margin : the columns' distance from their cell's sides (fraction of the cell)
    surfaces : pave the bicubic surface tiles instead (open branching tubes for printing; no heat model)

    >>> from geometry import primitives
    >>> ms = bifurcation(primitives.box((1.0, 1.0, 6.0)), levels=[0, 0, 1, 1, 0, 0], tile="1-4a")
    >>> ms.n_tiles, sum(i.kind == "branch" for i in ms.interfaces)   # strips of a split/join on whole column faces
    (12, 8)
    """
    _check_arguments(D, epsilon, levels, direction, surfaces)
    if isinstance(tile, dict):
        tiles, tile = _user_tiles(tile), tile.get("kind")
    else:
        tiles = bifurcation_tiles(tile, margin, bool(surfaces))
    g = int(direction)
    cross = ((g + 1) % 3, (g + 2) % 3)  # cyclic: tile (x, y, z) -> D directions (cross[0], cross[1], g), det > 0
    if epsilon is not None:  # a lower bound of the cells before anything is built: domain chords / epsilon
        whole = edge_lengths(D, D.domain[None].astype(float))[0]
        dirs = [g] + [k for k, s in zip(cross, SPLITS[tile]) if s > 1]
        check_budget(float(np.prod([max(whole[k] / epsilon, 1.0) for k in dirs])), tiles["split"],
                      f"the bifurcation tiling for epsilon={show(epsilon)}", "raise epsilon")
    layers, lev = _layers(D, g, epsilon, levels)
    if lev is None:
        lev = np.array([_level_of(D, g, cross, SPLITS[tile], iv, epsilon) for iv in layers])
    lev = smooth_levels(lev)
    sx, sy = SPLITS[tile]
    spans = [D.breakpoints(k) for k in cross]
    n_cells = sum(int(np.prod([(len(b) - 1) * s ** int(v) for b, s in zip(spans, (sx, sy))])) for v in lev)
    check_budget(n_cells, tiles["split"], f"the bifurcation tiling ({len(lev)} layers)", "raise epsilon or lower "
                  "the levels")
    placed, tile_list, faces = _place_layers(D, tiles, layers, lev, spans, cross, g, (sx, sy))
    check_spans(D, placed)
    links = _links(faces)
    ms = Microstructure.build(D, placed, tile_list, links, name=name)
    ms.info = {"levels": [int(x) for x in lev], "layers": layers.tolist(), "tile": tile, "direction": g,
               "cells": n_cells}
    return ms


def _check_arguments(D, epsilon, levels, direction, surfaces) -> None:
    check_map(D)
    if direction not in (0, 1, 2) or isinstance(direction, bool):
        raise TilingError(f"direction must be 0, 1 or 2 (the growth direction), got {show(direction)}")
    if not is_flag(surfaces):
        raise TilingError(f"surfaces must be true or false, got {show(surfaces)}")
    if (epsilon is None) == (levels is None):
        raise TilingError("give epsilon (model units) or levels (one per layer), not both and not neither")
    if epsilon is not None and not (is_real(epsilon)
                                    and np.isfinite(epsilon) and epsilon > 0):
        raise TilingError(f"epsilon must be a positive length (model units), got {show(epsilon)}")


def _place_layers(D, tiles: dict, layers, lev, spans, cross, g: int, splits):
    """Place every layer's tiles (a split below a finer layer, a join above one, else straight) in its cells;
    returns (placed patches, tile per cell, faces (patch, face name, plane coordinate, rect in D params))."""
    P = np.zeros((3, 3))
    P[cross[0], 0] = P[cross[1], 1] = P[g, 2] = 1.0  # tile axes -> D's directions
    placed, tile_list, faces = [], [], []
    for li, (iv, v) in enumerate(zip(layers, lev)):
        finer_above = li + 1 < len(lev) and lev[li + 1] > v
        finer_below = li > 0 and lev[li - 1] > v
        kind = "split" if finer_above else ("join" if finer_below else "straight")
        t = tiles[kind]
        cuts = [_breaks(b, s ** int(v)) for b, s in zip(spans, splits)]
        for i in range(len(cuts[0]) - 1):
            for j in range(len(cuts[1]) - 1):
                lo = np.array([cuts[0][i], cuts[1][j], iv[0]])
                size = np.array([cuts[0][i + 1] - cuts[0][i], cuts[1][j + 1] - cuts[1][j], iv[1] - iv[0]])
                M = np.column_stack([P @ np.diag(size), P @ lo])
                tid = len(tile_list)
                tile_list.append(t)
                for pi, patch in enumerate(t.patches):
                    idx = len(placed)
                    placed.append(PlacedPatch(patch, M, D, tid, int(v), pi))
                    if patch.dim != 3:
                        continue
                    for face, z in (("wmin", 0), ("wmax", 1)):  # the faces on the layer planes (not a trunk's)
                        pts = patch.boundary(face).control_points[..., :3].reshape(-1, 3)
                        if np.abs(pts[:, 2] - z).max() > SNAP:
                            continue
                        rect = np.stack([pts.min(0)[:2], pts.max(0)[:2]], 1) * size[:2, None] + lo[:2, None]
                        faces.append((idx, face, float(lo[2] + z * size[2]), rect))
    return placed, tile_list, faces


def _links(faces) -> list:
    """Branch links (parent, face, box, child, face) between nested unequal faces on the same layer plane."""
    tol = SNAP
    by_plane: dict = {}
    for f in faces:
        by_plane.setdefault(round(f[2] / tol) * tol, []).append(f)
    links = []
    for group in by_plane.values():
        below = [f for f in group if f[1] == "wmax"]
        above = [f for f in group if f[1] == "wmin"]
        for a in below:
            for b in above:
                lo = np.maximum(a[3][:, 0], b[3][:, 0])
                hi = np.minimum(a[3][:, 1], b[3][:, 1])
                if np.any(hi - lo <= tol):
                    continue  # no common area
                ra, rb = a[3], b[3]
                if np.allclose(ra, rb, atol=tol):
                    continue  # equal faces: identity, found by the model
                big, small = (a, b) if np.all(ra[:, 0] <= rb[:, 0] + tol) and np.all(ra[:, 1] >= rb[:, 1] - tol) \
                    else (b, a)
                R, r = big[3], small[3]
                if not (np.all(R[:, 0] <= r[:, 0] + tol) and np.all(R[:, 1] >= r[:, 1] - tol)):
                    raise TilingError("bifurcation faces overlap without nesting; this is a bug in the layering")
                box = tuple((float((r[k, 0] - R[k, 0]) / (R[k, 1] - R[k, 0])),
                             float((r[k, 1] - R[k, 0]) / (R[k, 1] - R[k, 0]))) for k in range(2))
                links.append((big[0], big[1], box, small[0], small[1]))
    return links
