"""Polygonal tiles: polygons and polylines paved by vertex mapping (Elber 2017, Section 2, Eq. 3).

A :class:`PolygonTile` holds vertices in the unit cube with polygons and/or
polylines over them (a lattice of beams for printing, a faceted shell).
:func:`pave_polygons` places a copy in every cell of D's parameter grid and
maps each vertex through D (:func:`geometry.map_points`): the vertices are
exact images, the edges and facets stay straight in space (the approximate
mode of Elber 2017; refine the tile to lower the error).  Vertices that
coincide in parameter space (on shared cell faces) are mapped once, and an
edge or facet lying on a shared cell face is kept once, so the result is one
welded ``pyvista.PolyData`` with D's channels as point data,
ready for :func:`tiling.export.write_mesh` (STL, OBJ, PLY, VTP, VTU).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry import BSpline, map_points
from geometry.errors import show
from geometry.shapes.orientation import orient_outward
from geometry.resources import check_memory

from tiling.errors import TilingError
from tiling.checks import check_counts, check_map
from geometry.tolerances import COINCIDENT, ON_DOMAIN
from geometry.numbers import is_integer

__all__ = ["PolygonTile", "pave_polygons", "beam_lattice"]


@dataclass
class PolygonTile:
    """Vertices (N, 3) in [0, 1]^3, ``polygons`` (lists of vertex indices, >= 3 each) and ``lines`` (>= 2 each)."""

    points: np.ndarray
    polygons: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    name: str = "polygon tile"

    def __post_init__(self):
        P = np.asarray(self.points, float)
        if P.ndim != 2 or P.shape[1] != 3 or not len(P) or not np.all(np.isfinite(P)):
            raise TilingError(f"polygon tile {show(self.name)}: points must be a finite (N, 3) array, got shape "
                              f"{np.shape(self.points)}")
        if P.min() < -ON_DOMAIN or P.max() > 1 + ON_DOMAIN:
            raise TilingError(f"polygon tile {show(self.name)}: points leave the unit cube "
                              f"({P.min(0).round(6).tolist()}..{P.max(0).round(6).tolist()})")
        if not self.polygons and not self.lines:
            raise TilingError(f"polygon tile {show(self.name)} has neither polygons nor lines")
        for kind, items, least in (("polygon", self.polygons, 3), ("line", self.lines, 2)):
            for i, c in enumerate(items):
                c = list(c)
                if len(c) < least or any(not is_integer(v)
                                         or not 0 <= v < len(P) for v in c):
                    raise TilingError(f"polygon tile {show(self.name)}: {kind} {i} must list >= {least} vertex "
                                      f"indices in [0, {len(P) - 1}], got {show(c)}")
                # a vertex named twice in a row (or a polygon closing on its first vertex) is a zero-length edge;
                # a polygon's vertices at one place are a degenerate face
                ring = c + [c[0]] if kind == "polygon" else c
                same = next((j for j in range(len(ring) - 1)
                             if np.linalg.norm(P[ring[j]] - P[ring[j + 1]]) <= COINCIDENT), None)
                if same is not None:
                    raise TilingError(f"polygon tile {show(self.name)}: {kind} {i} repeats a vertex ({show(c)}: "
                                      f"vertices {ring[same]} and {ring[same + 1]} at one place, a zero-length "
                                      "edge); list each corner once")
        self.points = P


def beam_lattice() -> PolygonTile:
    """The twelve edges of the cell and its four body diagonals, as polylines (a printable beam lattice)."""
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.abs(corners[a] - corners[b]).sum() == 1]
    diagonals = [(a, 7 - a) for a in range(4)]
    return PolygonTile(corners, lines=[list(e) for e in edges + diagonals], name="beam lattice")


def pave_polygons(D: BSpline, tile: PolygonTile, counts):
    """``counts`` = (cx, cy, cz) copies of ``tile`` over D's parameter domain, vertices mapped through D.

    Returns a welded ``pyvista.PolyData`` (polygons as faces, polylines as lines) with D's channels and the
    parameters ``u``, ``v``, ``w`` as point data.
    """
    import pyvista as pv

    check_map(D)  # the check every builder shares: a trivariate, not folded
    if not isinstance(tile, PolygonTile):
        raise TilingError(f"tile must be a tiling.members.polygons.PolygonTile, got {type(tile).__name__}")
    counts = check_counts(counts, 3, "counts")
    n_cells = int(np.prod(counts))
    check_memory(n_cells * len(tile.points) * 200.0, f"the polygonal paving ({n_cells:,} cells)", TilingError,
                 "lower the counts")
    dom = D.domain
    size = (dom[:, 1] - dom[:, 0]) / np.asarray(counts)
    cells = np.stack(np.unravel_index(np.arange(n_cells), tuple(counts)), 1)
    params = dom[:, 0] + (cells[:, None, :] + tile.points[None]) * size  # (C, N, 3)
    # weld: vertices of neighbouring copies on a shared cell face coincide in parameter space exactly
    key = np.round((params - dom[:, 0]) / size * (1 << 20)).astype(np.int64).reshape(-1, 3)
    uniq, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    flat = params.reshape(-1, 3)[first]
    mapped = map_points(D, flat)
    offsets = (np.arange(n_cells) * len(tile.points))[:, None]

    def cells_of(items):
        if not items:
            return None
        out = []
        for c in items:
            idx = inverse[(offsets + np.asarray(c)[None]).ravel()].reshape(n_cells, len(c))
            out.append(idx)
        by_len: dict = {}
        for idx in out:
            by_len.setdefault(idx.shape[1], []).append(idx)
        flat = []
        for n, group in by_len.items():  # an edge or facet on a shared cell face is kept once
            rows = np.concatenate(group)
            _, keep = np.unique(np.sort(rows, axis=1), axis=0, return_index=True)
            rows = rows[np.sort(keep)]
            flat.append(np.hstack([np.full((len(rows), 1), n), rows]).ravel())
        return np.concatenate(flat)

    faces = cells_of(tile.polygons)
    if faces is not None:  # facets mapped through D (det J < 0 turns them inside out): consistent, outward
        faces = orient_outward(pv.PolyData(mapped[:, :3], faces)).faces
    mesh = pv.PolyData(mapped[:, :3], faces=faces, lines=cells_of(tile.lines))
    for i, c in enumerate(D.channels):
        mesh.point_data[c] = mapped[:, 3 + i]
    mesh.point_data["u"], mesh.point_data["v"], mesh.point_data["w"] = flat.T
    return mesh
