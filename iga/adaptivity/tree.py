"""Refinement by tiles: every patch of a model the root of an octree of patches.

A *leaf* is a box of a root patch's parameter domain at a dyadic position, ``depth`` halvings deep, indexed by
three integers (the box is ``[i / 2^depth, (i + 1) / 2^depth]`` of the root's normalised domain, per direction),
whose solution space is the root's own basis with every knot span bisected ``depth + extra`` times: a split
leaf keeps the number of elements of its parent on half the width (h halves), a leaf refined *in place*
(``extra``) keeps its box.  Integer positions make every geometric decision here (which leaves touch, which
face lies inside which) exact.

Splitting follows a singular edge the way an octree does.  Patches with interior discontinuity planes (the slots
of the heat-sink tiles) or faces named by slot ids are refined in place only: a split along a discontinuity plane
would part the two walls' coinciding material, which no interface kind expresses.

:meth:`TileRefinement.model` builds the analysis model: each leaf a :class:`geometry.PlacedPatch` with its
root's tile, level and tags; identity interfaces between equal leaf faces, and branch interfaces (the finer face
= refinement matrix @ the coarser face, Massarwi et al. 2018, Eqs. 11-12, with the orientation of the root
interface) where a leaf face lies inside a larger or coarser one.  :meth:`TileRefinement.closed` makes every
such pair nested (the smaller face at least as fine as the larger one) by refining the smaller leaf in place.
The model is a ``tiling.Microstructure`` when the roots were one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline
from geometry import knots as kn
from geometry.errors import show
from geometry.errors import SplineError
from geometry.faces import FACE_AXIS, face_knots, nested_refinement, oriented_face_knots
from geometry.grouping import ObjectIndex
from geometry.patches.multipatch import PlacedPatch

from iga.adaptivity.gluing import (MAX_DEPTH, bisected, branch_pairs, identity_pairs, inner_pairs,
                                  interface)
from iga.errors import ProblemError
from iga.model import as_model, same_kind

__all__ = ["Leaves", "TileRefinement", "MAX_DEPTH", "MAX_ELEVATION"]

#: degree elevations of a leaf beyond its root's (p-refinement): a degree-2 tile goes to degree 8 at most
MAX_ELEVATION = 6


@dataclass(frozen=True)
class Leaves:
    """The leaves of all roots: ``root`` (L,), ``depth`` (L,), ``index`` (L, 3) position at that depth,
    ``extra`` (L,) in-place bisections beyond the depth, ``elevation`` (L,) degree elevations beyond the root's
    (p-refinement, the same in every direction)."""

    root: np.ndarray
    depth: np.ndarray
    index: np.ndarray
    extra: np.ndarray
    elevation: np.ndarray

    def __len__(self) -> int:
        return len(self.root)

    @property
    def level(self) -> np.ndarray:
        """Knot-span bisections of each leaf's space relative to its root's (L,)."""
        return self.depth + self.extra

    def take(self, keep) -> "Leaves":
        return Leaves(self.root[keep], self.depth[keep], self.index[keep], self.extra[keep], self.elevation[keep])

    def but(self, extra=None, elevation=None) -> "Leaves":
        """The same leaves with other in-place bisections or degree elevations."""
        return Leaves(self.root, self.depth, self.index, self.extra if extra is None else extra,
                      self.elevation if elevation is None else elevation)

    @staticmethod
    def concat(parts) -> "Leaves":
        return Leaves(*(np.concatenate([getattr(p, f) for p in parts])
                        for f in ("root", "depth", "index", "extra", "elevation")))


def _splittable(model) -> np.ndarray:
    """Per root: may it be split?  Not with interior full-multiplicity knots (discontinuity planes) nor with a
    slot face in a tag or an interface."""
    ok = np.ones(len(model.patches), bool)
    for i, p in enumerate(model.patches):
        for U, deg in zip(p.spline.knots, p.spline.degrees):
            _, m = np.unique(U, return_counts=True)
            if np.any(m[1:-1] >= deg + 1):
                ok[i] = False
    slot_users = [pi for faces in model.tags.values() for pi, f in faces if f not in FACE_AXIS]
    slot_users += [e[0] for itf in model.interfaces for e in (itf.a, itf.b) if e[1] not in FACE_AXIS]
    slot_users += [pi for pi, _ in getattr(model, "face_regions", {})]
    ok[np.asarray(slot_users, np.int64)] = False
    return ok


class TileRefinement:
    """The leaves of every patch of a model (initially one per patch) and the model they make.

    ``model``: anything :func:`iga.model.as_model` accepts; a ``tiling.Microstructure`` stays one.
    """

    def __init__(self, model, leaves: Leaves | None = None):
        self.source = model
        self.roots = as_model(model)
        n = len(self.roots.patches)
        self.splittable = _splittable(self.roots)
        self.leaves = leaves if leaves is not None else Leaves(np.arange(n), np.zeros(n, np.int64),
                                                               np.zeros((n, 3), np.int64), np.zeros(n, np.int64),
                                                               np.zeros(n, np.int64))
        self._tiles: dict = {}
        self._same = ObjectIndex()
        #: marked leaves that :meth:`refined` left unrefined (their branch children could not follow)
        self.held: list = []

    def _with(self, leaves: Leaves) -> "TileRefinement":
        """The same roots with other leaves (the roots' model, splittability and restricted tiles shared)."""
        out = object.__new__(TileRefinement)
        out.source, out.roots, out.splittable, out.leaves = self.source, self.roots, self.splittable, leaves
        out._tiles, out._same, out.held = self._tiles, self._same, []
        return out

    # ------------------------------------------------------------------ refinement
    def refined(self, marked, how: str = "h", analysis_refine: int = 0) -> "TileRefinement":
        """A new refinement with the ``marked`` leaves (indices) refined: ``how="h"`` splits each splittable leaf
        into 2 x 2 x 2 children at its parametric midpoints and bisects the others' knot spans in place;
        ``"h-in-place"`` bisects in place only; ``"p"`` raises each marked leaf's degree by one (in every
        direction, keeping its continuity: the same geometry, :data:`MAX_ELEVATION` at most).  The result is
        :meth:`closed`.

        A branch child whose face lies on its parent's face at a box that is not dyadic in the parent (a seal plate
        on part of a tile's face) cannot follow every refinement of the parent: its bisected knots miss the
        parent's new ones.  Marked leaves whose refinement would leave such a pair not nested (checked on the
        analysis spaces, ``analysis_refine`` further bisections) are left as they are, as are marked leaves at
        :data:`MAX_ELEVATION` under ``"p"``; :attr:`held` lists them.
        """
        marked = np.unique(np.asarray(marked, np.int64))
        held: list = []
        if how == "p" and len(marked) and 0 <= marked.min() and marked.max() < len(self.leaves):
            top = self.leaves.elevation[marked] >= MAX_ELEVATION  # at the highest degree: held
            held, marked = marked[top].tolist(), marked[~top]
        while True:
            out = self._refined(marked, how).closed()
            bad = out._unnested_roots(analysis_refine)
            drop = np.isin(self.leaves.root[marked], list(bad))
            if not bad or not drop.any():
                break
            held += marked[drop].tolist()
            marked = marked[~drop]
        if bad:
            raise ProblemError(f"the refinement leaves branch faces of patches {sorted(bad)[:5]} of the model with "
                               "child face spaces that do not contain their parent's; refine fewer patches")
        out.held = sorted(held)
        return out

    def _refined(self, marked, how: str) -> "TileRefinement":
        """The marked leaves refined, not closed (:meth:`refined`)."""
        L = self.leaves
        if len(marked) and (marked.min() < 0 or marked.max() >= len(L)):
            raise ProblemError(f"marked patches must be indices below {len(L)}, got {show(marked.tolist()[:5])}")
        split = np.zeros(len(L), bool)
        if how == "p":
            elevation = L.elevation.copy()
            elevation[marked] += 1  # :meth:`refined` holds the leaves already at MAX_ELEVATION
            return self._with(L.but(elevation=elevation))
        if how == "h":
            split[marked] = self.splittable[L.root[marked]]
        elif how != "h-in-place":
            raise ProblemError(f"how must be 'h', 'h-in-place' or 'p', got {show(how)}")
        if np.any(L.depth[split] >= MAX_DEPTH):
            raise ProblemError(f"a patch would be split more than {MAX_DEPTH} times; stop the refinement earlier "
                               "(a larger tolerance or a smaller budget)")
        extra = L.extra.copy()
        inplace = np.setdiff1d(marked, np.flatnonzero(split))
        extra[inplace] += 1
        kept = L.but(extra=extra).take(~split)
        s = np.flatnonzero(split)
        octs = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], np.int64)
        kids = Leaves(np.repeat(L.root[s], 8), np.repeat(L.depth[s] + 1, 8),
                      (2 * L.index[s][:, None, :] + octs[None]).reshape(-1, 3), np.repeat(L.extra[s], 8),
                      np.repeat(L.elevation[s], 8))
        return self._with(Leaves.concat([kept, kids]))

    def closed(self) -> "TileRefinement":
        """Every glued pair nested: the smaller (or equal) face's leaf at least as fine as the larger one's, in
        bisections and in degree (in-place bisections and elevations added where not), and a root child's face
        inside one leaf of its parent (the child split where not)."""
        out = self
        for _ in range(4 * (MAX_DEPTH + MAX_ELEVATION) + 8):
            L = out.leaves
            need, degree = L.level.copy(), L.elevation.copy()
            split = np.zeros(len(L), bool)
            for p in out._pairs():
                if p.a[0] < 0:  # a root child's face over several parent leaves
                    split[p.b[0]] = True
                    continue
                need[p.b[0]] = max(need[p.b[0]], L.level[p.a[0]])
                degree[p.b[0]] = max(degree[p.b[0]], L.elevation[p.a[0]])
            if split.any():
                if not out.splittable[L.root[split]].all():
                    bad = int(L.root[np.flatnonzero(split & ~out.splittable[L.root])[0]])
                    raise ProblemError(f"patch {bad} of the model is a branch child whose face would meet several "
                                       "refined parent patches, and it cannot be split (it has discontinuity planes); "
                                       "refine its parent in place (how='h-in-place')")
                out = out._refined(np.flatnonzero(split), "h")
                continue
            if np.array_equal(need, L.level) and np.array_equal(degree, L.elevation):
                return out
            out = out._with(L.but(extra=need - L.depth, elevation=degree))
        raise ProblemError("the refinement did not close (a cycle of branch faces); check the model's interfaces")

    # ---------------------------------------------------------------- geometry
    def _root_domain(self, r) -> np.ndarray:
        return self.roots.patches[r].spline.domain

    def _leaf_box(self, i) -> np.ndarray:
        """The leaf's box (3, 2) in its root spline's parameters."""
        L = self.leaves
        dom = self._root_domain(L.root[i])
        t = np.stack([L.index[i], L.index[i] + 1], axis=1) / float(1 << int(L.depth[i]))
        return dom[:, :1] + t * (dom[:, 1:] - dom[:, :1])

    def _leaf_patch(self, i) -> PlacedPatch:
        """The leaf as a placed patch (exact: a restriction of its root)."""
        L = self.leaves
        root = self.roots.patches[int(L.root[i])]
        level, box, up = int(L.level[i]), self._leaf_box(i), int(L.elevation[i])
        T = root.spline
        whole = bool(L.depth[i] == 0)
        if root.outer is not None or T.is_rational or not self.splittable[L.root[i]]:
            # the tile restricted (shared by the copies of one tile at one position, level and degree)
            key = ("tile", self._same(T), level, tuple(map(int, L.index[i])), int(L.depth[i]), up)
            if key not in self._tiles:
                S = T.refine(level)[0] if level else T
                S = S if whole else S.extract(box)
                self._tiles[key] = S.elevate_to(tuple(p + up for p in T.degrees)) if up else S
            return PlacedPatch(self._tiles[key], root.placement, root.outer, root.tile, root.level,
                               root.patch_in_tile, refinement=level)
        # a plain polynomial root: the leaf is the root placed on its box, x = root(A xi + b), over a reference
        # tile (the identity on [0, 1]^3 in the leaf's basis) that all leaves with equal bases share
        knots = [self._leaf_knots(T, k, level, box[k]) for k in range(3)]
        degrees = tuple(p + up for p in T.degrees)
        if up:  # the same knots, each multiplicity raised with the degree (the continuity kept)
            knots = [kn.elevation_matrix(U, p, up)[0] for U, p in zip(knots, T.degrees)]
        key = ("reference", degrees, tuple(U.tobytes() for U in knots))
        if key not in self._tiles:
            self._tiles[key] = _identity_tile(degrees, knots)
        okey = ("outer", int(L.root[i]))
        if okey not in self._tiles:
            self._tiles[okey] = T if root.placement is None else T.affine(root.placement[:, :3], root.placement[:, 3])
        outer = self._tiles[okey]
        A = np.zeros((3, 4))
        A[:, :3] = np.diag(box[:, 1] - box[:, 0])
        A[:, 3] = box[:, 0]
        return PlacedPatch(self._tiles[key], A, outer, root.tile, root.level, root.patch_in_tile, refinement=level)

    def _leaf_knots(self, T, k: int, level: int, interval) -> np.ndarray:
        """The knot vector of direction ``k`` of a leaf of the plain root T: T's bisected ``level`` times,
        restricted to ``interval`` (end knots repeated p + 1 times) and normalised to [0, 1]; cached (leaves of one
        root and level share few distinct ones)."""
        key = ("knots", self._same(T), k, level, float(interval[0]), float(interval[1]))
        if key not in self._tiles:
            U, p = bisected([(T.knots[k], T.degrees[k])], level)[0]
            a, b = float(interval[0]), float(interval[1])
            inner = U[(U > a) & (U < b)]
            U = np.r_[np.full(p + 1, a), inner, np.full(p + 1, b)]
            self._tiles[key] = (U - a) / (b - a)
        return self._tiles[key]

    # ------------------------------------------------------------------- faces
    def _face_leaves(self, r: int, face: str):
        """Leaves of root ``r`` on its face ``face``: (leaf ids, depth, (n, 2) position in the face's two
        directions); a slot face (unsplittable roots) is the one leaf's whole face."""
        L = self.leaves
        ids = np.flatnonzero(L.root == r)
        if face not in FACE_AXIS:
            return ids, L.depth[ids], np.zeros((len(ids), 2), np.int64)
        k, side = FACE_AXIS[face]
        on = L.index[ids, k] == (0 if side == 0 else (1 << L.depth[ids]) - 1)
        ids = ids[on]
        rest = [d for d in range(3) if d != k]
        return ids, L.depth[ids], L.index[ids][:, rest]

    def _pairs(self) -> list:
        """Every pair of glued leaf faces (see :class:`iga.adaptivity.gluing.Pair`)."""
        return inner_pairs(self.leaves) + self._root_pairs()

    def _root_pairs(self) -> list:
        """Pairs across the roots' interfaces."""
        out = []
        L = self.leaves
        for itf in self.roots.interfaces:
            (ra, fa), (rb, fb) = itf.a, itf.b
            ia, da, pa = self._face_leaves(ra, fa)
            ib, db, pb = self._face_leaves(rb, fb)
            if itf.kind == "identity":
                out += identity_pairs(L, (ia, da, pa, fa), (ib, db, pb, fb), itf.swap, tuple(itf.flip))
            else:
                out += branch_pairs(itf, (ia, da, pa, fa), (ib, db, pb, fb), self._root_domain(ra))
        return out

    def _unnested_roots(self, analysis_refine: int = 0) -> set:
        """Roots whose leaves are parents, across a branch interface of the roots, of a child leaf whose face
        space (after ``analysis_refine`` bisections) does not contain the parent's restricted face space."""
        pairs = [p for p in self._pairs() if p.root_branch and p.a[0] >= 0]
        if not pairs:
            return set()
        patches = {i: self._leaf_patch(i) for i in {q for p in pairs for q in (p.a[0], p.b[0])}}
        bad = set()
        for p in pairs:
            if p.a[1] not in FACE_AXIS or p.b[1] not in FACE_AXIS:
                continue  # slot faces: the roots' own spaces, unchanged by in-place bisection of both sides
            itf = interface(p, patches)
            parent = bisected(face_knots(patches[p.a[0]].spline, p.a[1]), analysis_refine)
            child = oriented_face_knots(bisected(face_knots(patches[p.b[0]].spline, p.b[1]), analysis_refine),
                                        p.swap, p.flip)
            try:
                nested_refinement(parent, itf.box, child)
            except SplineError:
                bad.add(int(self.leaves.root[p.a[0]]))
        return bad

    # ------------------------------------------------------------------- model
    def model(self):
        """The analysis model of the leaves (a ``tiling.Microstructure`` when the roots were one)."""
        L = self.leaves
        patches = [self._leaf_patch(i) for i in range(len(L))]
        interfaces = []
        for p in self._pairs():
            if p.a[0] < 0:
                raise ProblemError("the refinement is not closed; call closed() first")
            interfaces.append(interface(p, patches))
        tags = {}
        for tag, faces in self.roots.tags.items():
            new = []
            for r, face in faces:
                ids = self._face_leaves(r, face)[0]
                new += [(int(i), face) for i in ids]
            tags[tag] = new
        regions = {}
        for (r, face), rects in getattr(self.roots, "face_regions", {}).items():
            for i in self._face_leaves(r, face)[0]:
                regions[(int(i), face)] = rects
        return same_kind(self.source, patches, interfaces, tags, regions)


def _identity_tile(degrees, knots) -> BSpline:
    """The identity map of [0, 1]^3 in the B-spline basis of ``knots`` (control points at the Greville points)."""
    g = [kn.greville(U, p) for U, p in zip(knots, degrees)]
    cp = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1)
    return BSpline(tuple(degrees), [np.asarray(U, float) for U in knots], cp)
