"""Graded pavings: a tile family whose parameter varies along w, each layer of cells its own member
(:func:`graded`), or whose parameters belong to the cell's six faces, taken from a field on every shared face
(:func:`field_graded`: grading in all three directions).

A lattice graded in density (arms thickening from one face to the other,
Massarwi et al. 2018, Section 6.1: heterogeneous micro-structures) needs tiles
that still meet face to face where the parameter changes.  ``family(lower,
upper)`` returns the tile whose bottom face (z = 0) has the parameter's value
``lower`` and its top face ``upper`` (:func:`tiling.library.graded_cross`);
:func:`graded` gives every layer of D's cell grid along w the member between
the values at its two boundaries, so neighbouring layers share their face's
value and conform.  The interfaces come by construction, as in a regular paving
(:mod:`tiling.topology`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline, SplineFunction
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.numbers import is_real

from .errors import TilingError
from .microstructure import Microstructure, PlacedPatch
from .checks import check_budget, check_counts, check_map, check_spans, parameter_cells
from .paving import grid_identity
from .tile import Tile, refuse_trimmed

__all__ = ["graded", "field_graded", "leaf_graded", "FaceGrading", "LeafGrading"]


def _values(D: BSpline, values, w: np.ndarray) -> np.ndarray:
    """The family's parameter at the layer boundaries ``w`` (D's parameters): a channel of D read on the axis
    through the middle of D's (u, v) domain, or a callable of the normalised w in [0, 1]."""
    dom = D.domain
    if isinstance(values, str):
        if values not in D.channels:
            raise TilingError(f"graded: {show(values)} is not a channel of the map (its channels: "
                              f"{list(D.channels)}); give a channel name or a callable of the normalised w")
        x = np.column_stack([np.full(len(w), dom[0].mean()), np.full(len(w), dom[1].mean()), w])
        out = D.evaluate(x)[:, 3 + list(D.channels).index(values)]
    elif callable(values):
        out = np.asarray(values((w - dom[2, 0]) / (dom[2, 1] - dom[2, 0])), float).reshape(-1)
    else:
        raise TilingError(f"graded: values must be a channel name of the map or a callable of the normalised w, "
                          f"got {show(values)}")
    if out.shape != w.shape or not np.all(np.isfinite(out)):
        raise TilingError(f"graded: the parameter must be finite at the {len(w)} layer boundaries, got "
                          f"{show(out)}")
    return out


def graded(D: BSpline, family, counts, values, name: str = "graded") -> Microstructure:
    """Regular paving of D by ``counts`` = (cx, cy, cz) cells per knot span, layer k along w holding
    ``family(p_k, p_k+1)`` with p the parameter at the layer boundaries (``values``: a channel of D or a callable
    of the normalised w; module notes).  ``ms.info["parameter"]`` holds p.

    >>> from geometry import primitives
    >>> from tiling import library
    >>> ms = graded(primitives.box(), library.graded_cross, (2, 2, 4), lambda s: 0.2 + 0.2 * s)
    >>> ms.n_tiles, [round(p, 2) for p in ms.info["parameter"]]
    (16, [0.2, 0.25, 0.3, 0.35, 0.4])
    """
    cells = _cell_grid(D, family, counts, "graded", "a callable (lower, upper) -> Tile, e.g. "
                       "tiling.library.graded_cross")
    w = np.append(cells[2][:, 0], cells[2][-1, 1])
    p = _values(D, values, w)
    layers = [_member(family, (float(p[k]), float(p[k + 1])), {}, "graded", f"layer {k} (parameter {p[k]:g} to "
                      f"{p[k + 1]:g})") for k in range(len(w) - 1)]
    placed, tiles, shape = _paved(D, cells, lambda i, j, k: layers[k], "the graded paving")
    ms = Microstructure.build(D, placed, tiles, [], name=name, identity=grid_identity(D, tiles, shape))
    ms.info = {"parameter": [float(v) for v in p]}
    return ms


def _cell_grid(D: BSpline, family, counts, what: str, family_is: str) -> list:
    """The checked map, family and counts of a graded paving: D's cells per direction (:func:`parameter_cells`)."""
    check_map(D)
    if not callable(family):
        raise TilingError(f"{what}: family must be {family_is}; got {show(family)}")
    counts = check_counts(counts, 3, "counts")
    return [parameter_cells(D, k, counts[k]) for k in range(3)]


def _member(family, args: tuple, kwargs: dict, what: str, where: str) -> Tile:
    """``family(*args, **kwargs)``, a plain tile, or the family's refusal naming ``where``."""
    try:
        t = family(*args, **kwargs)
    except TilingError as exc:
        raise TilingError(f"{what}: {where}: {exc}") from None
    if not isinstance(t, Tile):
        raise TilingError(f"{what}: family must return a tiling.Tile, got {show(t)} for {where}")
    refuse_trimmed(t, f"the {what} paving")
    return t


def _paved(D: BSpline, cells: list, tile_of, what: str) -> tuple[list, list, tuple]:
    """Every cell (i, j, k) of D's grid ``cells`` holding ``tile_of(i, j, k)``, its patches placed:
    (placed patches, tiles, grid shape); the size checked against the memory budget on the first tile."""
    shape = tuple(len(c) for c in cells)
    placed, tiles = [], []
    for i, j, k in np.ndindex(shape):
        t = tile_of(i, j, k)
        if not tiles:  # the first cell's tile stands for the others' size
            check_budget(float(np.prod(shape)), t, what)
        lo = np.array([cells[0][i, 0], cells[1][j, 0], cells[2][k, 0]])
        hi = np.array([cells[0][i, 1], cells[1][j, 1], cells[2][k, 1]])
        M = np.column_stack([np.diag(hi - lo), lo])
        tiles.append(t)
        placed += [PlacedPatch(patch, M, D, len(tiles) - 1, 0, pi) for pi, patch in enumerate(t.patches)]
    check_spans(D, placed)
    return placed, tiles, shape


def _field_values(D: BSpline, field, points: np.ndarray) -> np.ndarray:
    """The field at D's parameters ``points`` (N, 3): a number, a channel of D, a parameter spline (a scalar
    trivariate :class:`geometry.SplineFunction`, its domain standing for D's, linearly) or a callable of the
    normalised parameters (N, 3) in [0, 1]^3 returning (N,)."""
    dom = D.domain
    if is_real(field):
        out = np.full(len(points), float(field))
    elif isinstance(field, str):
        if field not in D.channels:
            raise TilingError(f"field_graded: {show(field)} is not a channel of the map (its channels: "
                              f"{list(D.channels)}); give a number, a channel name or a callable of the normalised "
                              "parameters")
        out = D.evaluate(points)[:, 3 + list(D.channels).index(field)]
    elif isinstance(field, SplineFunction):
        if field.dim != 3 or field.coefficients.shape[-1] != 1:
            raise TilingError(f"field_graded: a parameter spline must be a scalar trivariate SplineFunction "
                              f"(coefficients (n1, n2, n3, 1)), got {show(field)}")
        out = field.evaluate(spline_parameters(field, (points - dom[:, 0]) / (dom[:, 1] - dom[:, 0])))[:, 0]
    elif callable(field):
        try:
            out = np.asarray(field((points - dom[:, 0]) / (dom[:, 1] - dom[:, 0])), float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise TilingError(f"field_graded: the field callable failed on the face centres (N, 3): {exc}") from None
    else:
        raise TilingError(f"field_graded: field must be a number, a channel name of the map, a parameter spline "
                          f"(geometry.SplineFunction) or a callable of the normalised parameters (N, 3), got "
                          f"{show(field)}")
    if out.shape != (len(points),) or not np.all(np.isfinite(out)):
        raise TilingError(f"field_graded: the field must give one finite value per face centre ({len(points)}), "
                          f"got {show(out)}")
    return out


def spline_parameters(spline: SplineFunction, s: np.ndarray) -> np.ndarray:
    """The parameters of ``spline`` at normalised parameters ``s`` (N, 3) in [0, 1]^3 (its domain linearly)."""
    dom = np.array([[U[0], U[-1]] for U in spline.knots])
    return np.clip(dom[:, 0] + s * (dom[:, 1] - dom[:, 0]), dom[:, 0], dom[:, 1])


@dataclass(frozen=True)
class FaceGrading:
    """What a field-graded paving chose, for its derivatives: the ``family`` of the six face values, the ``field``
    as given, its values on the cell walls ``faces`` per direction (arrays (nu + 1, nv, nw), (nu, nv + 1, nw),
    (nu, nv, nw + 1)) at the wall centres ``centres`` (the same shapes + (3,), D's parameters), the cell grid
    ``shape`` and the ``counts`` per knot span it was paved with; tile t sits in cell
    ``np.unravel_index(t, shape)``."""

    family: object
    field: object
    faces: tuple
    centres: tuple
    shape: tuple
    counts: tuple

    def walls(self, t: int) -> dict:
        """{face name: (direction, wall index (i, j, k))}: the six walls of tile t's cell."""
        i, j, k = (int(v) for v in np.unravel_index(t, self.shape))
        return {"umin": (0, (i, j, k)), "umax": (0, (i + 1, j, k)), "vmin": (1, (i, j, k)),
                "vmax": (1, (i, j + 1, k)), "wmin": (2, (i, j, k)), "wmax": (2, (i, j, k + 1))}

    def values(self, t: int) -> dict:
        """{face name: value}: the family's arguments of tile t."""
        return {f: float(self.faces[d][w]) for f, (d, w) in self.walls(t).items()}

    # the protocol the parameter sensitivities and designs read (shared with LeafGrading): walls as flat sites
    def graded_tiles(self) -> range:
        """The tiles the field grades: every cell's."""
        return range(int(np.prod(self.shape)))

    def sites(self, t: int) -> dict:
        """{face name: site}: tile t's walls as indices into :attr:`site_centres`."""
        offsets = np.cumsum([0] + [f.size for f in self.faces])
        return {f: int(offsets[d] + np.ravel_multi_index(w, self.faces[d].shape)) for f, (d, w) in
                self.walls(t).items()}

    @property
    def site_centres(self) -> np.ndarray:
        """The wall centres (n, 3) in D's parameters, the three directions' walls one after the other."""
        return np.concatenate([c.reshape(-1, 3) for c in self.centres])

    def unflatten(self, g: np.ndarray) -> tuple:
        """Per-site numbers (n,) as three arrays shaped like :attr:`faces`."""
        cuts = np.cumsum([f.size for f in self.faces])[:-1]
        return tuple(part.reshape(f.shape) for part, f in zip(np.split(np.asarray(g), cuts), self.faces))

    def rebuild(self, D: BSpline, field, name: str) -> Microstructure:
        """The same paving of ``D`` with another ``field``."""
        return field_graded(D, self.family, self.counts, field, name=name)


#: walls of two leaves closer than this (relative to D's parameter domain) are one site: a shared wall
SITE_MARGIN = 1e-9
def _face_centres() -> np.ndarray:
    """The centres (6, 3) of the unit cell's faces, in :data:`geometry.faces.FACE_NAMES` order (tile coordinates)."""
    out = np.full((len(FACE_NAMES), 3), 0.5)
    for i, face in enumerate(FACE_NAMES):
        k, side = FACE_AXIS[face]
        out[i, k] = side
    return out


@dataclass(frozen=True)
class LeafGrading:
    """What :func:`leaf_graded` chose, for the derivatives: the ``family`` and the ``field``, the field's values
    ``site_values`` (n,) at the leaves' wall centres ``site_centres`` (n, 3) (D's parameters; a wall two leaves
    share is one site), each leaf tile's walls ``tile_sites`` {tile: {face: site}}, and the hierarchical paving's
    arguments ``paving`` (tile, counts, levels, scale)."""

    family: object
    field: object
    site_values: np.ndarray
    site_centres: np.ndarray
    tile_sites: dict
    paving: tuple

    def graded_tiles(self) -> list:
        return sorted(self.tile_sites)

    def sites(self, t: int) -> dict:
        return self.tile_sites[t]

    def values(self, t: int) -> dict:
        return {f: float(self.site_values[s]) for f, s in self.tile_sites[t].items()}

    def unflatten(self, g: np.ndarray) -> np.ndarray:
        return np.asarray(g)

    def rebuild(self, D: BSpline, field, name: str) -> Microstructure:
        tile, counts, levels, scale = self.paving
        return leaf_graded(D, tile, counts, levels, self.family, field, scale=scale, name=name)


def leaf_graded(D: BSpline, tile: Tile, counts, levels: int, family, field, scale: float | None = None,
                name: str = "leaf-graded") -> Microstructure:
    """The hierarchical paving of :func:`tiling.hierarchical` whose last level's tiles are
    ``family(umin=, umax=, vmin=, vmax=, wmin=, wmax=)`` with the ``field`` (as :func:`field_graded` takes it) at the
    centres of their six walls: a heat sink whose finest pins are graded across it.  The leaves carry no children,
    so their shapes move no branch face; a wall two leaves share (closer than :data:`SITE_MARGIN` of the domain)
    reads one value, so they meet face to face (the interfaces are found in space and a mismatch is refused).  The
    family's members must have the tile's patches (count, degrees, knots) and its branch-in face (the bottom the
    parent's pin carries).  ``ms.grading`` is the :class:`LeafGrading` the parameter sensitivities read.

    >>> from geometry import primitives
    >>> from tiling import library
    >>> sink = leaf_graded(primitives.box((0.06, 0.06, 0.03), degrees=(2, 2, 2)), library.heat_sink_t2(), (2, 2), 2,
    ...                    library.face_graded_heat_sink, lambda s: 0.3 + 0.15 * s[:, 0])
    >>> sink.tiles_per_level(), sum(i.kind == "branch" for i in sink.interfaces)
    ([4, 16], 16)
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    from .paving import hierarchical

    if not callable(family):
        raise TilingError(f"leaf_graded: family must be a callable of the six wall values (umin=..., wmax=...) "
                          f"returning a Tile, e.g. tiling.library.face_graded_heat_sink, got {show(family)}")
    first = hierarchical(D, tile, counts, levels, scale=scale, name=name)
    last = max(p.level for p in first.patches)
    leaves = sorted({p.tile for p in first.patches if p.level == last})
    at = {p.tile: p.placement for p in first.patches if p.level == last}  # (3, 4): tile coordinates -> D's
    local = _face_centres()
    centres = np.concatenate([local @ at[t][:, :3].T + at[t][:, 3] for t in leaves])  # (6 L, 3)
    extent = float(np.max(D.domain[:, 1] - D.domain[:, 0]))
    pairs = cKDTree(centres).query_pairs(SITE_MARGIN * extent, output_type="ndarray")
    n = len(centres)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, site = connected_components(graph, directed=False)  # coincident walls: one site
    site_centres = np.zeros((site.max() + 1, 3))
    site_centres[site] = centres
    values = _field_values(D, field, site_centres)
    faces = FACE_NAMES
    tile_sites = {t: {f: int(site[6 * j + m]) for m, f in enumerate(faces)} for j, t in enumerate(leaves)}
    tiles = list(first.tiles)
    for t in leaves:
        member = _member(family, (), {f: float(values[s]) for f, s in tile_sites[t].items()}, "leaf_graded",
                         f"leaf tile {t}")
        _same_structure(member, tile, t)
        tiles[t] = member
    placed = [PlacedPatch(tiles[p.tile].patches[p.patch_in_tile], p.placement, p.outer, p.tile, p.level,
                          p.patch_in_tile) if p.level == last else p for p in first.patches]
    links = [(i.a[0], i.a[1], i.box, i.b[0], i.b[1]) for i in first.interfaces if i.kind == "branch"]
    ms = Microstructure.build(D, placed, tiles, links, name=name, root_faces=first.tags["branch-in"],
                              leaf_faces=first.tags["branch-out"])
    ms.grading = LeafGrading(family, field, values, site_centres, tile_sites, (tile, counts, levels, scale))
    return ms


def _same_structure(member: Tile, tile: Tile, t: int) -> None:
    """Refuse a leaf whose patches or branch-in face differ from the tile's (the parent's pin carries it)."""
    same = len(member.patches) == len(tile.patches) and all(
        a.degrees == b.degrees and all(np.array_equal(u, w) for u, w in zip(a.knots, b.knots))
        for a, b in zip(member.patches, tile.patches))
    bi, ti = member.branch_in, tile.branch_in
    if not same or bi is None or (bi.patch, bi.face) != (ti.patch, ti.face):
        raise TilingError(f"leaf_graded: leaf tile {t}'s family member {show(member.name)} does not have the tile's "
                          f"patches (count, degrees, knots) and its branch-in face (patch {ti.patch} {ti.face}); the "
                          "family must vary the tile's shape alone")


def field_graded(D: BSpline, family, counts, field, name: str = "field-graded") -> Microstructure:
    """Regular paving of D by ``counts`` cells per knot span whose every cell holds
    ``family(umin=, umax=, vmin=, vmax=, wmin=, wmax=)`` with the ``field`` taken at the centres of its six faces
    (:func:`_field_values`: a number, a channel of D, a parameter spline or a callable of the normalised
    parameters).  The values
    live on the faces of the cell grid, so two cells sharing a face read the same value and their tiles meet face
    to face there (:func:`tiling.library.face_graded_cross`): the interfaces come by construction, as in a regular
    paving, and a lattice is graded in all three directions.  ``ms.info["faces"]`` holds the values per direction,
    arrays of shapes (nu + 1, nv, nw), (nu, nv + 1, nw) and (nu, nv, nw + 1); ``ms.grading`` the
    :class:`FaceGrading` (family, field, wall values and centres) that the parameter sensitivities read
    (``Solution.gradient(output, wrt="parameters")``).

    >>> from geometry import primitives
    >>> from tiling import library
    >>> ms = field_graded(primitives.box(), library.face_graded_cross, (3, 2, 2), lambda s: 0.2 + 0.2 * s[:, 0])
    >>> ms.n_tiles, [round(float(v), 3) for v in ms.info["faces"][0][:, 0, 0]]
    (12, [0.2, 0.267, 0.333, 0.4])
    """
    cells = _cell_grid(D, family, counts, "field_graded", "a callable of the six face values (umin=..., wmax=...) "
                       "returning a Tile, e.g. tiling.library.face_graded_cross")
    bounds = [np.append(c[:, 0], c[-1, 1]) for c in cells]  # the cell walls along each direction
    centres = [c.mean(1) for c in cells]
    faces, walls = [], []
    for d in range(3):  # the field at the centre of every wall normal to d
        axes = [bounds[j] if j == d else centres[j] for j in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
        walls.append(grid)
        faces.append(_field_values(D, field, grid.reshape(-1, 3)).reshape(grid.shape[:3]))
    grading = FaceGrading(family, field, tuple(faces), tuple(walls), tuple(len(c) for c in cells),
                          tuple(int(c) for c in counts))

    def tile_of(i, j, k):
        t = int(np.ravel_multi_index((i, j, k), grading.shape))
        return _member(family, (), grading.values(t), "field_graded", f"cell ({i}, {j}, {k})")

    placed, tiles, shape = _paved(D, cells, tile_of, "the field-graded paving")
    interfaces, mismatched = grid_identity(D, tiles, shape)
    if mismatched:
        (pa, fa), (pb, fb), why = mismatched[0]
        raise TilingError(f"field_graded: the tiles of neighbouring cells do not meet face to face (patch {pa} "
                          f"{fa} against patch {pb} {fb}: {why}); the family must shape each face by that face's "
                          "value alone")
    ms = Microstructure.build(D, placed, tiles, [], name=name, identity=(interfaces, mismatched))
    ms.info = {"faces": faces}
    ms.grading = grading
    return ms

