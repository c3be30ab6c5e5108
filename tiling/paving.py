"""Paving schemes: regular (Elber 2017, Sections 2-3) and hierarchical (Massarwi et al. 2018, Section 3).

Placements are affine maps ``[A | b]`` of tile coordinates into the
deformation map's parameter domain.  Tiles are placed per knot span of ``D``
so that no placed patch crosses a knot line (exact composition works per
Bezier piece of ``D``).  A singular ``D`` is refused up front with the
parameter box where its Jacobian vanishes (:func:`geometry.check_regular`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from geometry import BSpline, progress
from geometry.resources import bulk_build

from .checks import check_budget, check_counts, check_map, check_spans, parameter_cells
from .errors import TilingError
from .microstructure import Microstructure, PlacedPatch
from tiling.sealing.caps import PlacedCap, capped_variant
from tiling.sealing.shells import shelled_variant
from tiling.members.trimmed import place_trimmed
from tiling.sealing.plates import SealedTile, seal_layout, sealed_variant
from .tile import Tile, refuse_trimmed
from .topology import grid_interfaces, seams
from geometry.errors import SplineError
from geometry.faces import FACE_NAMES
from geometry.errors import show
from geometry.grouping import ObjectIndex
from geometry.patches.placed_points import IDENTITY
from geometry.numbers import is_integer, is_real


#: default thickness of seal plates (a fraction of the cell); a different one without ``seal`` is refused
SEAL_THICKNESS = 0.1


def _affine(M: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3] = M
    return out


@bulk_build
def regular(D: BSpline, tile: Tile, counts, variants: dict | None = None, name: str = "regular",
            seal: str | None = None, thickness: float = SEAL_THICKNESS, seal_sides=None, *,
            built: dict | None = None) -> Microstructure:
    """Regular paving: ``counts`` = (cx, cy, cz) copies of ``tile`` per knot span of D.

    ``variants`` optionally maps a position key ``(ku, kv, kw)`` with entries
    -1 (at the min boundary of D's domain), 0 (interior), +1 (at the max
    boundary) to a sealed boundary tile (Elber 2017, Sections 2-3); tiles whose key is
    missing use ``tile``.  ``seal="cap"`` builds those variants itself
    (:func:`tiling.sealing.plates.sealed_variant`: trivariate plates of ``thickness``, a
    fraction of a cell, conforming to the tiles) on ``seal_sides`` of D's
    domain (default all six; a cell alone in a direction is sealed on both
    sides); ``seal="shell"`` seals all six.  The plates' free faces are tagged
    ``cap`` (or ``shell``), and the heat model includes the plates.  A
    surface tile is capped by planar trimmed surfaces over its boundary
    curves instead (:mod:`tiling.sealing.caps`; ``Microstructure.caps``).  ``built``: a dict of sealed
    variants built by earlier pavings, (tile, variant) by (seal, thickness, sides), filled here: pavings of
    one tile in many maps (:func:`tiling.compose_levels`) build each variant once.

    >>> from geometry import primitives
    >>> from tiling import library
    >>> lattice = regular(primitives.box((2.0, 1.0, 1.0)), library.cross(), (4, 2, 2))
    >>> lattice.n_tiles, len(lattice.patches), len(lattice.tags["umin"])   # 7 blocks per tile; 4 arm ends at u = 0
    (16, 112, 4)
    """
    placed, tiles, links, caps, sealed, trimmed = regular_placements(D, tile, counts, variants, seal, thickness,
                                                                     seal_sides, built)
    shape = tuple(len(parameter_cells(D, k, c)) for k, c in enumerate(counts))  # (counts checked by the placements)
    ms = Microstructure.build(D, placed, tiles, links, name=name, identity=grid_identity(D, tiles, shape))
    ms.caps = caps
    ms.trimmed = trimmed
    if seal is not None:
        _tag_seal(ms, seal, [(t, i) for t in sealed.values() for i in t.seal_patches])
    return ms


class Placements(NamedTuple):
    """What :func:`regular_placements` places: the placed patches, the tiles (C order over the cells), the seal
    links between plates and tiles, the placed caps, the sealed variants by the sides they seal, and the
    placed trimmed members."""

    placed: list
    tiles: list
    links: list
    caps: list
    sealed: dict
    trimmed: list


def regular_placements(D: BSpline, tile: Tile, counts, variants: dict | None = None, seal: str | None = None,
                       thickness: float = SEAL_THICKNESS, seal_sides=None, built: dict | None = None) -> Placements:
    """The placements of :func:`regular` without the interface search (:class:`Placements`).  Tiles are
    numbered in C order over the cells; for callers that keep a subset of them and build one micro-structure
    from several pavings (:mod:`tiling.vrep`).  ``built``: as :func:`regular`'s."""
    check_map(D)
    if not isinstance(tile, Tile):
        raise TilingError(f"tile must be a tiling.Tile, got {type(tile).__name__}")
    counts = check_counts(counts, 3, "counts")
    if seal is not None and variants:
        raise TilingError("give variants or seal, not both")
    allowed = _seal_sides(seal, seal_sides, thickness)
    variants = dict(variants or {})
    for key, t in variants.items():
        if not isinstance(t, Tile) or len(key) != 3 or any(v not in (-1, 0, 1) for v in key):
            raise TilingError(f"variants keys must be (ku, kv, kw) with entries -1/0/1 and values Tiles; got {show(key)}")
    spans = [len(D.breakpoints(k)) - 1 for k in range(3)]
    check_budget(float(np.prod([c * s for c, s in zip(counts, spans)], dtype=float)), tile, "the regular paving")
    cells = [parameter_cells(D, k, counts[k]) for k in range(3)]
    N = [len(c) for c in cells]
    placed, tiles, links, caps, trimmed = [], [], [], [], []
    sealed: dict = {}  # sealed variants, built once per set of sides
    if built is not None and not isinstance(built, dict):
        raise TilingError(f"built must be a dict (of sealed variants, filled by the paving), got {show(built)}")
    built = {} if built is None else built
    for i in range(N[0]):
        for j in range(N[1]):
            for k in range(N[2]):
                key = tuple(0 if N[d] == 1 else (-1 if n == 0 else (1 if n == N[d] - 1 else 0))
                            for d, n in enumerate((i, j, k)))
                t = variants.get(key, tile)
                if seal is not None:
                    sides = frozenset(f for d, n in enumerate((i, j, k)) for f, at in
                                      ((FACE_NAMES[2 * d], n == 0), (FACE_NAMES[2 * d + 1], n == N[d] - 1))
                                      if at and f in allowed)
                    if sides:
                        if sides not in sealed:
                            made = (seal, float(thickness), sides)
                            if made not in built or built[made][0] is not tile:  # another tile's: built again
                                built[made] = (tile, variant_for(tile, sides, thickness, seal))
                            sealed[sides] = built[made][1]
                        t = sealed[sides]
                lo = np.array([cells[0][i, 0], cells[1][j, 0], cells[2][k, 0]])
                hi = np.array([cells[0][i, 1], cells[1][j, 1], cells[2][k, 1]])
                M = np.column_stack([np.diag(hi - lo), lo])
                tid, first = len(tiles), len(placed)
                tiles.append(t)
                for pi, patch in enumerate(t.patches):
                    placed.append(PlacedPatch(patch, M, D, tid, 0, pi))
                links += [(first + a, f, box, first + b, g) for a, f, box, b, g in getattr(t, "seal_links", ())]
                caps += [PlacedCap(c, PlacedPatch(c.trimmed.surface, M, D, tid, 0, -1), first)
                         for c in getattr(t, "caps", ())]
                trimmed += place_trimmed(t, M, D, tid)
    check_spans(D, placed + [m.placed for m in trimmed])
    return Placements(placed, tiles, links, caps, sealed, trimmed)


def grid_identity(D: BSpline, tiles: list, shape: tuple):
    """The identity interfaces, by construction (:mod:`tiling.topology`), of a grid of cells of the shape
    ``shape`` holding ``tiles`` in C order, each tile's patches placed in turn; (interfaces, mismatched)."""
    same = ObjectIndex()
    keys = np.array([same(t) for t in tiles]).reshape(shape)
    first = np.cumsum([0] + [len(t.patches) for t in tiles])[:-1].reshape(shape)
    layouts = {}
    for t in tiles:
        if same(t) not in layouts:
            layouts[same(t)] = [(p, IDENTITY) for p in t.patches]
    return _grid_interfaces(keys, first, layouts, seams(D))


def _grid_interfaces(keys, first, layouts, periodic):
    """:func:`tiling.topology.grid_interfaces`, with a tile whose own patches overlap refused as a tiling error."""
    try:
        return grid_interfaces(keys, first, layouts, periodic)
    except SplineError as exc:
        raise TilingError(f"{exc}; overlapping tiles or patches") from None


def variant_for(tile: Tile, sides, thickness: float, seal: str) -> Tile:
    """The sealed variant of ``tile`` on ``sides``: plates for volumetric tiles, trimmed caps for surface tiles."""
    refuse_trimmed(tile, f"seal={seal!r} (caps and shells close the openings of a tile's patches)")
    if tile.trivariates:
        return sealed_variant(tile, sides, thickness, seal)
    if seal == "shell":
        return shelled_variant(tile, sides, thickness)
    return capped_variant(tile, sides)


def _tag_seal(ms: Microstructure, seal: str, plates: set) -> None:
    """Tag ``seal`` ('cap' / 'shell'): the free faces of the plates, given as [(tile, patch in tile)]."""
    same = ObjectIndex()
    wanted = {(same(t), q) for t, q in plates}
    ms.tags[seal] = [(p, f) for p, f in ms.tags["boundary"]
                     if (same(ms.tiles[ms.patches[p].tile]), ms.patches[p].patch_in_tile) in wanted]


def _seal_sides(seal, seal_sides, thickness) -> set:
    """The sides of D's domain to seal; refuses options that would be ignored or seal nothing."""
    if seal not in (None, "cap", "shell"):
        raise TilingError(f"seal must be 'cap', 'shell' or None, got {show(seal)}")
    if seal is None and (seal_sides is not None or thickness != SEAL_THICKNESS):
        given = "seal_sides" if seal_sides is not None else "thickness"
        raise TilingError(f"{given} is given but seal is None, so nothing is sealed; pass seal='cap' or 'shell', "
                          f"or leave {given} out")
    if seal == "shell" and seal_sides is not None:
        raise TilingError("seal='shell' seals every side of the cell; seal_sides applies to seal='cap' only")
    if seal == "cap" and seal_sides is not None and not len(list(seal_sides)):
        raise TilingError("seal='cap' with seal_sides=() seals nothing; name the sides to cap, or pass seal=None")
    allowed = set(FACE_NAMES) if seal == "shell" or seal_sides is None else set(seal_sides)
    if not allowed <= set(FACE_NAMES):
        raise TilingError(f"seal_sides must be face names of D's domain from {list(FACE_NAMES)}, got "
                          f"{show(seal_sides)}")
    return allowed


@dataclass
class _Paving:
    """What a hierarchical paving accumulates: placed patches, a tile per copy, branch links, root and leaf
    faces."""

    placed: list = field(default_factory=list)
    tiles: list = field(default_factory=list)
    links: list = field(default_factory=list)
    roots: list = field(default_factory=list)
    leaves: list = field(default_factory=list)


def _hierarchical_arguments(D, tile, counts, levels, scale, seal, thickness, seal_sides):
    """Checked arguments of :func:`hierarchical`: (tile with the scale applied, cx, cy, sealable sides)."""
    check_map(D)
    if not isinstance(tile, Tile) or not tile.hierarchical:
        raise TilingError("hierarchical paving needs a Tile with a branch-in face and branch-out faces")
    refuse_trimmed(tile, "the hierarchical paving")
    cx, cy = check_counts(counts, 2, "counts")
    allowed = _seal_sides(seal, seal_sides, thickness)
    if not is_integer(levels) or levels < 1:
        raise TilingError(f"levels must be a positive integer, got {show(levels)}")
    b = len(tile.branch_outs)
    per_cell = float(levels) if b == 1 else (float(b) ** int(levels) - 1) / (b - 1)  # 1 + b + ... + b^(levels - 1)
    spans = [len(D.breakpoints(k)) - 1 for k in range(2)]
    check_budget(per_cell * cx * cy * spans[0] * spans[1], tile, f"the {levels}-level hierarchical paving")
    if scale is not None and not (is_real(scale) and np.isfinite(scale) and scale > 0):
        raise TilingError(f"scale must be a positive number (a child's height relative to its parent), got "
                          f"{show(scale)} ({type(scale).__name__})")
    if scale is not None and scale != tile.scale:
        tile = Tile(tile.patches, tile.branch_in, [(b.patch, b.face, b.box) for b in tile.branch_outs],
                    scale=scale, name=tile.name)
    return tile, cx, cy, allowed


def _hierarchy(tile: Tile, levels: int):
    """The hierarchy in tile coordinates, (nodes [(placement 4x4, level, parent node, branch-out index)], the
    4x4 map of its bounding box onto the unit cube)."""
    nodes = [(np.eye(4), 0, -1, -1)]
    frontier = [0]
    for lev in range(1, levels):
        nxt = []
        for n in frontier:
            M = nodes[n][0]
            for j, bf in enumerate(tile.branch_outs):
                nodes.append((M @ _affine(bf.map), lev, n, j))
                nxt.append(len(nodes) - 1)
        frontier = nxt
    pts = np.concatenate([np.concatenate([p.points.reshape(-1, 3) for p in tile.patches]) @ M[:3, :3].T + M[:3, 3]
                          for M, *_ in nodes])
    lo, hi = pts.min(0), pts.max(0)
    return nodes, _affine(np.column_stack([np.diag(1.0 / (hi - lo)), -lo / (hi - lo)]))


def _place_hierarchy(out: _Paving, D, tile: Tile, nodes, cell, levels: int) -> None:
    """Place one cell's hierarchy (``cell``: the 4x4 map of the unit cube into it) with its branch links."""
    node_first = []
    for M, lev, parent, bj in nodes:
        tid = len(out.tiles)
        out.tiles.append(tile)
        G = (cell @ M)[:3]
        first = len(out.placed)
        node_first.append(first)
        for pi, patch in enumerate(tile.patches):
            out.placed.append(PlacedPatch(patch, G, D, tid, lev, pi))
        if parent >= 0:
            bf = tile.branch_outs[bj]
            out.links.append((node_first[parent] + bf.patch, bf.face, bf.box, first + tile.branch_in.patch,
                              tile.branch_in.face))
        else:
            out.roots.append((first + tile.branch_in.patch, tile.branch_in.face))
        if lev == levels - 1:
            out.leaves += [(first + bf.patch, bf.face) for bf in tile.branch_outs]


@bulk_build
def hierarchical(D: BSpline, tile: Tile, counts, levels: int, scale: float | None = None,
                 name: str = "hierarchical", seal: str | None = None, thickness: float = SEAL_THICKNESS,
                 seal_sides=None) -> Microstructure:
    """Hierarchical paving (Massarwi et al. 2018, Section 3): base copies, then a child on every branch-out face, recursively.

    ``counts`` = (cx, cy) base copies per knot span of D along u, v; ``levels``
    counts the base level; ``scale`` (default: the tile's) is the height of a
    child relative to its parent along the growth direction.  The whole
    hierarchy is scaled (axis-aligned) into each base cell of D's domain.

    ``seal="cap"`` / ``"shell"`` seals every base cell on the sides of D's
    domain it touches (``seal_sides``, default all six; every cell spans D's
    w range, so ``wmin`` is under the base and ``wmax`` over the last level)
    with plates of ``thickness`` (a fraction of the cell) that conform to the
    tiles of every level (:func:`tiling.sealing.plates.seal_layout`; refinement
    interfaces where a plate meets part of a face).  The hierarchy of a
    sealed cell is squeezed out of the layers.  Faces on a sealed wall must
    be axis-aligned rectangles per continuous piece: the tapered fins of the
    heat-sink tiles can be capped on ``wmin`` / ``wmax``, not on their sides.

    >>> from geometry import primitives
    >>> from tiling import library
    >>> sink = hierarchical(primitives.box((0.06, 0.06, 0.03)), library.heat_sink_t2(), (2, 2), levels=2)
    >>> sink.tiles_per_level(), sum(i.kind == "branch" for i in sink.interfaces)   # 4 pins on every base tile
    ([4, 16], 16)
    """
    tile, cx, cy, allowed = _hierarchical_arguments(D, tile, counts, levels, scale, seal, thickness, seal_sides)
    nodes, Nrm = _hierarchy(tile, int(levels))
    cu, cv = parameter_cells(D, 0, cx), parameter_cells(D, 1, cy)
    dw = D.domain[2]
    out = _Paving()
    layouts: dict = {}  # seal plates per set of sealed sides, built once
    keys = np.zeros((len(cu), len(cv), 1), dtype=object)  # the layout of every cell (its sealed sides) and its
    first = np.zeros((len(cu), len(cv), 1), dtype=np.int64)  # first placed patch: interfaces by construction
    cell_layouts: dict = {}
    flat = [p.affine(G[:3, :3], G[:3, 3]) for M, *_ in nodes for G in [Nrm @ M] for p in tile.patches] if seal else []
    for i in progress.bar(range(len(cu)), desc="hierarchical paving", unit="column"):
        for j in range(len(cv)):
            lo_c = np.array([cu[i, 0], cv[j, 0], dw[0]])
            hi_c = np.array([cu[i, 1], cv[j, 1], dw[1]])
            cell = _affine(np.column_stack([np.diag(hi_c - lo_c), lo_c]))
            at = {"umin": i == 0, "umax": i == len(cu) - 1, "vmin": j == 0, "vmax": j == len(cv) - 1,
                  "wmin": True, "wmax": True}
            sides = frozenset(f for f in FACE_NAMES if at[f] and f in allowed) if seal else frozenset()
            squeeze = np.eye(4)
            if sides:
                if sides not in layouts:
                    lay = seal_layout(flat, sides, thickness, seal, tile.name)
                    plates = SealedTile(lay.plates, name=f"{tile.name} {seal} ({'+'.join(sorted(sides))})")
                    plates.seal_patches, plates.seal = tuple(range(len(lay.plates))), seal  # plates only: no tile
                    layouts[sides] = (lay, plates)
                squeeze = layouts[sides][0].squeeze()
            cell_first = len(out.placed)
            _place_hierarchy(out, D, tile, nodes, (cell @ squeeze @ Nrm), int(levels))
            keys[i, j, 0], first[i, j, 0] = sides, cell_first
            if sides not in cell_layouts:  # the cell's patches in the unit cell: the hierarchy, then the plates
                cell_layouts[sides] = [(p, (squeeze @ Nrm @ M)[:3]) for M, *_ in nodes for p in tile.patches]
                cell_layouts[sides] += [(p, IDENTITY) for p in (layouts[sides][1].patches if sides else ())]
            if sides:
                lay, plates = layouts[sides]
                tid, pfirst = len(out.tiles), len(out.placed)
                out.tiles.append(plates)
                out.placed += [PlacedPatch(p, cell[:3], D, tid, 0, q) for q, p in enumerate(plates.patches)]
                out.links += [(cell_first + a, f, box, pfirst + q, g) for a, f, box, q, g in lay.links]
    placed, tiles, links, roots, leaves = out.placed, out.tiles, out.links, out.roots, out.leaves
    check_spans(D, placed)
    periodic = seams(D)[:2] + (False,)  # every cell spans D's w range: no neighbour along w
    ms = Microstructure.build(D, placed, tiles, links, name=name, root_faces=roots, leaf_faces=sorted(set(leaves)),
                              identity=_grid_interfaces(keys, first, cell_layouts, periodic))
    if layouts:
        _tag_seal(ms, seal, [(t, q) for _, t in layouts.values() for q in range(len(t.patches))])
    return ms
