"""The Microstructure: placed tile patches, the interfaces that glue them, boundary tags.

A :class:`Microstructure` is a :class:`geometry.MultiPatch` (the model
protocol shared with the analysis) built by a paving: every placed patch keeps
its tile patch (analysed in its own parameter space; Massarwi et al. 2018,
Remark 2), its placement ``[A | b]`` into the deformation map's domain, its
level and tile index, and its composed image ``D(A T + b)`` (exact, computed
lazily and cached; :meth:`Microstructure.compose_all` batches it per tile
patch with :func:`geometry.compose_many`).

Interfaces: ``identity`` between faces that coincide in space (known by
construction in regular and hierarchical pavings, :mod:`tiling.topology`,
periodic maps glued across their seam; found by
:func:`geometry.detect_interfaces` through D for the other builders);
``branch`` between a child's branch-in face and a sub-rectangle
``box`` of its parent's branch-out face, with ``R`` (sparse) such that child
face coefficients = R @ parent face coefficients (Massarwi et al. 2018, Eqs. 11-12).

Tags: every free face (no interface) of every trivariate is tagged with the
boundary of D's domain it lies on (``umin`` .. ``wmax``) or ``internal``;
``boundary`` holds every free face; ``branch-in`` the root faces of a
hierarchy; ``branch-out`` the free branch-out faces of its last level;
``exterior`` every free face except the ``branch-in`` ones.  Free parts of
discontinuity planes are slot faces (``u=0.5-``), tagged ``internal``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry import BSpline
from geometry.errors import SplineError
from geometry.faces import FACE_NAMES, discontinuity_slots, face_knots, nested_refinement
from geometry.patches.contact import unglued_contacts
from geometry.patches.multipatch import (Interface, MultiPatch, PlacedPatch, detect_interfaces, free_face_mask, free_faces,
                                 tile_corners)

from . import export, pictures
from .errors import TilingError
from geometry.errors import show
from geometry.grouping import ObjectIndex
from geometry.io.files import window_plotter
from geometry.maps.scale import scale_bounds
from geometry.tolerances import COINCIDENT

__all__ = ["Microstructure", "PlacedPatch", "Interface", "branch_refinement"]

TOL = COINCIDENT  # tile walls on a cell face, relative to the tile's size


class Microstructure(MultiPatch):
    """Result of a paving: patches, interfaces, tags (see module docs), plus the map, tiles and a name.

    ``caps``: the trimmed planar caps of capped surface tiles (:class:`tiling.sealing.caps.PlacedCap`), part of the
    boundary surface and of the IGES export.  ``trimmed``: the placed trimmed members of the tiles
    (:class:`tiling.members.trimmed.PlacedTrimmed`), likewise.  ``info``: what the builder chose (a graded
    paving's parameter per layer, a bifurcation's levels); ``struts``: the sweeps of :func:`tiling.round_struts`.
    """

    def __init__(self, outer: BSpline, patches: list, interfaces: list, tags: dict, tiles: list, name: str = "",
                 face_regions: dict | None = None):
        super().__init__(patches, interfaces, tags, face_regions or {})
        self.outer = outer
        self.tiles = tiles
        self.name = name
        self.caps: list = []  # set by pavings that cap surface tiles
        self.trimmed: list = []  # set by pavings of tiles with trimmed members
        #: what the builder chose, for reports: ``graded`` the parameter per layer; ``bifurcation`` the levels,
        #: layers, tile and growth direction
        self.info: dict = {}
        self.struts = None  # round_struts: the tiling.members.struts.StrutReport of its sweeps
        #: field_graded: the tiling.graded_layers.FaceGrading (family, field, wall values) its tiles came from
        self.grading = None

    def __repr__(self):
        return (f"Microstructure({show(self.name)}: {len(self.patches)} patches, {self.n_tiles} tiles, "
                f"{len(self.interfaces)} interfaces, levels {self.levels})")

    @property
    def n_tiles(self) -> int:
        """Number of placed tiles (seal plates placed on their own are not tiles: they close the paving)."""
        return len({p.tile for p in self._placed() if not self._plates_only(p.tile)})

    def _placed(self) -> list:
        """The placed patches and the placed surfaces of the trimmed members."""
        return list(self.patches) + [m.placed for m in self.trimmed]

    def _plates_only(self, t: int) -> bool:
        tile = self.tiles[t] if 0 <= t < len(self.tiles) else None
        plates = getattr(tile, "seal_patches", ())
        return bool(plates) and len(plates) == len(tile.patches)

    @property
    def levels(self) -> int:
        """Number of hierarchy levels (1 for a regular paving)."""
        return 1 + max((p.level for p in self._placed()), default=0)

    def tiles_per_level(self) -> list[int]:
        """Tiles on each hierarchy level, from the base."""
        out = [0] * self.levels
        seen = set()
        for p in self._placed():
            if p.tile not in seen and not self._plates_only(p.tile):
                seen.add(p.tile)
                out[p.level] += 1
        return out

    def surface(self, tolerance: float | None = None, samples: int = 4):
        """The boundary as one welded triangle mesh (:func:`tiling.export.surface`).

        ``tolerance`` (model units): subdivide elements until every triangle
        lies within it of the exact surface (:func:`tiling.export.samples_for_tolerance`);
        otherwise ``samples`` subdivisions per element and direction.
        """
        if tolerance is not None:
            samples = export.samples_for_tolerance(self, tolerance)
        return export.surface(self, samples)

    def plot(self, screenshot=None, samples: int = 6, color_by: str = "level", title: str | None = None, mesh=None):
        """Draw the boundary coloured by ``level``, ``tile`` or ``patch``, titled with the name, tiles, patches
        and levels (:func:`tiling.pictures.render_png`); ``screenshot``: a ``.png`` written off screen (returned), else
        the window is shown. ``mesh``: the boundary :meth:`surface` already gave, drawn as it is (not computed
        again)."""
        if screenshot is not None:
            return pictures.render_png(self, screenshot, samples, color_by, title=title, mesh=mesh)
        pl = pictures.draw(self, window_plotter(), samples, color_by, title, mesh)
        pl.set_background("white")
        pl.show()
        return None

    def tile_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """Each placed tile's box in the map's parameter domain: ``(tiles (K,), boxes (K, 3, 2))``.

        The box holds the images of the tile's patches' control points (the patches lie in
        their hull), so it is the cell the tile was paved into, or less for a tile that does
        not fill its cell; seal plates placed on their own are left out.
        """
        keep = [p for p in self._placed() if not self._plates_only(p.tile) and p.outer is not None]
        if not keep:
            raise TilingError(f"{self.name or 'this micro-structure'} has no patches placed in a map (e.g. swept "
                              "struts, already in physical space); ask the paving they were swept from")
        ident = np.hstack([np.eye(3), np.zeros((3, 1))])
        pts = [p.spline.points.reshape(-1, 3) @ A[:, :3].T + A[:, 3] for p in keep
               for A in [ident if p.placement is None else p.placement]]
        tiles, row = np.unique([p.tile for p in keep], return_inverse=True)
        row = np.repeat(row, [len(x) for x in pts])
        lo = np.full((len(tiles), 3), np.inf)
        hi = np.full((len(tiles), 3), -np.inf)
        x = np.concatenate(pts)
        np.minimum.at(lo, row, x)
        np.maximum.at(hi, row, x)
        dom = self.outer.domain
        return tiles, np.stack([np.maximum(lo, dom[:, 0]), np.minimum(hi, dom[:, 1])], -1)

    def scale_bounds(self, subdivide: int = 2):
        """Guaranteed bounds on how much the map stretches each placed tile
        (:func:`geometry.maps.scale.scale_bounds` over :meth:`tile_boxes`; ``.tiles`` names the tile of each row).

        ``lower`` / ``upper``: the smallest and largest scale factor (singular value of
        the map's Jacobian, model units per parameter unit) on each tile's box,
        ``axis_lower`` / ``axis_upper``: the stretch of each parametric direction.
        """
        tiles, boxes = self.tile_boxes()
        out = scale_bounds(self.outer, boxes, subdivide)
        out.tiles = tiles
        return out

    # ------------------------------------------------------------- assembly
    @classmethod
    def build(cls, outer, placed: list, tiles: list, branch_links: list, name: str = "", root_faces=(), leaf_faces=(),
              identity=None):
        """Identity interfaces (``identity``: ``(interfaces, mismatched)`` known by construction,
        :func:`tiling.topology.grid_interfaces`; else found in space), branch interfaces, tags of free faces."""
        linked = {frozenset([(p, pf), (c, cf)]) for p, pf, _, c, cf in branch_links}
        corners = tile_corners(placed)  # for the interface search and the tags
        try:
            found, mismatched = detect_interfaces(placed, placed_corners=corners) if identity is None else identity
        except SplineError as exc:
            raise TilingError(f"{exc}; overlapping tiles or patches") from None
        for a, b, why in mismatched:
            if frozenset([a, b]) not in linked:
                raise TilingError(f"faces patch {a[0]} {a[1]} and patch {b[0]} {b[1]} meet corner to corner, but {why}; "
                                  "use tiles whose opposite faces have matching knot vectors and control points")
        # a branch-out face that coincides with the child's branch-in face is glued by the branch constraint
        interfaces = [itf for itf in found if frozenset([itf.a, itf.b]) not in linked]
        same = {}  # branch faces of equal knots and box share one refinement matrix (read-only)
        for parent, pface, pbox, child, cface in branch_links:
            interfaces.append(_branch_interface(placed, parent, pface, pbox, child, cface, same))
        mask = free_face_mask(placed, interfaces, corners[0])  # for the contact search and the tags
        touching = unglued_contacts(placed, interfaces, mask=mask)
        if touching:
            (a, fa), (b, fb) = touching[0]
            raise TilingError(f"face {fa} of patch {a} (tile {placed[a].tile}) and face {fb} of patch {b} (tile "
                              f"{placed[b].tile}) touch but no interface glues them ({len(touching)}"
                              f"{'+' if len(touching) == 5 else ''} such pairs); their tile patches do not meet "
                              "face to face: use tiles whose faces on opposite cell walls match corner to corner")
        tags = _tags(outer, placed, interfaces, root_faces, leaf_faces, mask, corners)
        regions = _slot_faces(placed)
        for key in regions:
            tags["internal"].append(key)
            tags["boundary"].append(key)
        roots = set(tags["branch-in"])
        tags["exterior"] = [f for f in tags["boundary"] if f not in roots]  # e.g. convection everywhere but the heated base
        return cls(outer, placed, interfaces, tags, tiles, name, regions)


def branch_refinement(parent_knots, box, child_knots) -> sp.csr_matrix:
    """:func:`geometry.faces.nested_refinement`, raising :class:`TilingError` for spaces that are not nested."""
    try:
        return nested_refinement(parent_knots, box, child_knots)
    except SplineError as exc:
        raise TilingError(f"branch faces: {exc}") from None


def _branch_interface(placed, parent, pface, pbox, child, cface, same: dict | None = None) -> Interface:
    """The branch interface of a link; ``same``: the refinement matrices made so far in this build, by their
    knots and box (a hierarchy repeats a handful of configurations thousands of times: its 5,376 links took
    8-11 s to refine one by one)."""
    pk = face_knots(placed[parent].spline, pface)
    if pbox is None:
        pbox = tuple((float(U[0]), float(U[-1])) for U, _ in pk)
    pbox = tuple(tuple(float(x) for x in side) for side in pbox)
    ck = face_knots(placed[child].spline, cface)
    key = (tuple((np.asarray(U, float).tobytes(), p) for U, p in pk), pbox,
           tuple((np.asarray(U, float).tobytes(), p) for U, p in ck))
    R = None if same is None else same.get(key)
    if R is None:
        R = branch_refinement(pk, pbox, ck)
        for a in (R.data, R.indices, R.indptr):  # shared between interfaces: nothing may write into it
            a.flags.writeable = False
        if same is not None:
            same[key] = R
    return Interface("branch", (parent, pface), (child, cface), box=pbox, R=R)


def _tags(outer, placed, interfaces, root_faces, leaf_faces=(), mask=None, corners=None) -> dict:
    """Tags of the free faces (module notes): every trivariate face no interface glues, by the domain face
    all its corners lie on (``internal`` if none), in patch then face order; one array pass over the faces
    instead of a set lookup per face (the 65k patches of a 21^3 cross lattice: 0.36 -> 0.21 s).  ``corners``:
    the :func:`geometry.patches.placed_points.tile_corners` of ``placed``, when the caller has them."""
    dom = outer.domain
    scale = float(np.abs(dom).max()) + 1.0
    pidx, fc = tile_corners(placed) if corners is None else corners
    # a parent's branch-out face is covered by its children's
    _, free = free_face_mask(placed, interfaces) if mask is None else mask
    # where[t, f]: index of the domain face all 4 corners lie on (the last match wins), 6 = internal
    where = np.full(fc.shape[:2], 6)
    for k in range(3):
        for side in (0, 1):
            on = np.all(np.abs(fc[..., k] - dom[k, side]) < TOL * scale, axis=-1)
            where[on] = 2 * k + side
    # one tuple per free face in every list that holds it (a million free faces on large lattices), in patch
    # then face order, the order of ``where[free]``
    keys = free_faces(placed, interfaces, (pidx, free))
    names = FACE_NAMES + ("internal",)
    kind = where[free]
    tags = {name: [keys[j] for j in np.flatnonzero(kind == n).tolist()] for n, name in enumerate(names)}
    tags.update({"boundary": keys, "branch-in": [], "branch-out": []})
    # root and leaf faces a seal plate covers are glued, not free
    glued = {e for itf in interfaces for e in (itf.a, itf.b)} if len(root_faces) or len(leaf_faces) else set()
    tags["branch-in"] = [x for x in root_faces if x not in glued]
    tags["branch-out"] = [x for x in leaf_faces if x not in glued]  # free branch-out faces of the last level
    return tags


def _slot_faces(placed) -> dict:
    same = ObjectIndex()  # patches share splines and maps: group by object
    cache, out = {}, {}
    for i, P in enumerate(placed):
        if P.spline.dim != 3:
            continue
        key = same(P.spline)
        if key not in cache:
            cache[key] = discontinuity_slots(P.spline)
        for fid, rects in cache[key].items():
            out[(i, fid)] = rects
    return out
