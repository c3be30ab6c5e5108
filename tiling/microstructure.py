"""The Microstructure: placed tile patches, the interfaces that glue them, boundary tags.

Every placed patch keeps its tile patch (analysed in its own parameter space,
000 Remark 2), its placement ``[A | b]`` into the deformation map's domain, its
level and tile index, and its composed image ``D(A T + b)`` (exact, computed
lazily and cached; :meth:`Microstructure.compose_all` batches it per tile
patch with :func:`geometry.compose_many`).

Interfaces
----------
``identity``: two trivariate faces that coincide in space (through D, so
periodic maps glue across their seam), with the parameter map between them (``swap``, ``flip``: face B's parameters
(s', t') are face A's (s, t) swapped and/or reversed).
``branch``: a child's branch-in face on a sub-rectangle ``box`` of its
parent's branch-out face, with ``R`` (sparse) such that
child face coefficients = R @ parent face coefficients (000 Eqs. 11-12).

Tags: every free face (no interface) of every trivariate is tagged with the
boundary of D's domain it lies on (``umin`` .. ``wmax``) or ``internal``;
``boundary`` holds every free face; ``branch-in`` the root faces of a
hierarchy; ``exterior`` every free face except the ``branch-in`` ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from geometry import BSpline, compose, compose_many
from geometry import knots as kn
from geometry.spline import FACE_NAMES

from .errors import TilingError
from .tile import FACE_AXIS

TOL = 1e-9


@dataclass(eq=False)
class PlacedPatch:
    """One tile patch placed into the deformation map's domain."""

    spline: BSpline
    placement: np.ndarray  # (3, 4)
    outer: BSpline
    tile: int
    level: int = 0
    patch_in_tile: int = 0
    _composed: BSpline | None = field(default=None, repr=False)

    @property
    def composed(self) -> BSpline:
        """D(A T + b), exact (computed on first access, then cached)."""
        if self._composed is None:
            self._composed = compose(self.outer, self.spline.affine(self.placement[:, :3], self.placement[:, 3]))
        return self._composed


@dataclass(eq=False)
class Interface:
    """Two glued faces: ``a`` = (patch, face), ``b`` = (patch, face)."""

    kind: str  # "identity" or "branch"
    a: tuple
    b: tuple
    swap: bool = False
    flip: tuple = (False, False)
    box: tuple | None = None  # branch: sub-rectangle of a's face (the parent's)
    R: sp.csr_matrix | None = None  # branch: child (b) face coefficients = R @ parent (a) face coefficients


# corner index (i, j, k) of the 4 corners of each face, in face-parameter order (00, 10, 01, 11)
def _face_corner_index() -> np.ndarray:
    out = np.zeros((6, 4), np.int64)
    for fi, f in enumerate(FACE_NAMES):
        k, side = FACE_AXIS[f]
        rest = [d for d in range(3) if d != k]
        for c, (s_, t_) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
            ijk = [0, 0, 0]
            ijk[k], ijk[rest[0]], ijk[rest[1]] = side, s_, t_
            out[fi, c] = ijk[0] * 4 + ijk[1] * 2 + ijk[2]
    return out


_FACE_CORNERS = _face_corner_index()


def _all_face_corners(placed: list):
    """Trivariate patch indices (T,) and their face corners (T, 6, 4, 3) in D's parameter domain.

    One array operation per tile patch (patches sharing a spline share its corners).
    """
    groups: dict = {}
    for i, P in enumerate(placed):
        if P.spline.dim == 3:
            groups.setdefault(id(P.spline), []).append(i)
    if not groups:
        return np.zeros(0, np.int64), np.zeros((0, 6, 4, 3))
    idx, out = [], []
    for members in groups.values():
        c = placed[members[0]].spline.points[np.ix_([0, -1], [0, -1], [0, -1])].reshape(8, 3)
        M = np.stack([placed[i].placement for i in members])  # (P, 3, 4)
        pts = np.einsum("pij,cj->pci", M[:, :, :3], c) + M[:, None, :, 3]  # (P, 8, 3)
        out.append(pts[:, _FACE_CORNERS])  # (P, 6, 4, 3)
        idx += members
    idx = np.asarray(idx)
    order = np.argsort(idx, kind="stable")
    return idx[order], np.concatenate(out)[order]


class Microstructure:
    """Result of a paving: patches, interfaces, tags (see module docs)."""

    def __init__(self, outer: BSpline, patches: list, interfaces: list, tags: dict, tiles: list, name: str = "",
                 face_regions: dict | None = None):
        self.outer = outer
        self.patches = patches
        self.interfaces = interfaces
        self.tags = tags
        self.tiles = tiles
        self.name = name
        #: {(patch, slot face id): [((a1, b1), (a2, b2)), ...]} free parts of discontinuity planes
        self.face_regions = face_regions or {}

    def __repr__(self):
        return (f"Microstructure({self.name!r}: {len(self.patches)} patches, {self.n_tiles} tiles, "
                f"{len(self.interfaces)} interfaces, levels {self.levels})")

    @property
    def n_tiles(self) -> int:
        return len({p.tile for p in self.patches})

    @property
    def levels(self) -> int:
        return 1 + max((p.level for p in self.patches), default=0)

    def tiles_per_level(self) -> list[int]:
        out = [0] * self.levels
        seen = set()
        for p in self.patches:
            if p.tile not in seen:
                seen.add(p.tile)
                out[p.level] += 1
        return out

    def compose_all(self) -> list[BSpline]:
        """Compose every patch into D, batched per tile patch (cached on the patches)."""
        groups: dict = {}
        for i, p in enumerate(self.patches):
            if p._composed is None:
                groups.setdefault(id(p.spline), []).append(i)
        for members in groups.values():
            spline = self.patches[members[0]].spline
            res = compose_many(self.outer, spline, np.stack([self.patches[i].placement for i in members]))
            for i, r in zip(members, res):
                self.patches[i]._composed = r
        return [p.composed for p in self.patches]

    # ------------------------------------------------------------- assembly
    @classmethod
    def build(cls, outer, placed: list, tiles: list, branch_links: list, name: str = "", root_faces=(), leaf_faces=()):
        """Find identity interfaces, add branch interfaces, tag free faces."""
        linked = {frozenset([(p, pf), (c, cf)]) for p, pf, _, c, cf in branch_links}
        # a branch-out face that coincides with the child's branch-in face is glued by the branch constraint
        interfaces = [itf for itf in _identity_interfaces(placed) if frozenset([itf.a, itf.b]) not in linked]
        for parent, pface, pbox, child, cface in branch_links:
            interfaces.append(_branch_interface(placed, parent, pface, pbox, child, cface))
        tags = _tags(outer, placed, interfaces, root_faces, leaf_faces)
        regions = _slot_faces(placed)
        for key in regions:
            tags["internal"].append(key)
            tags["boundary"].append(key)
        roots = set(tags["branch-in"])
        tags["exterior"] = [f for f in tags["boundary"] if f not in roots]  # e.g. convection everywhere but the heated base
        return cls(outer, placed, interfaces, tags, tiles, name, regions)


def _identity_interfaces(placed: list) -> list:
    """Faces of trivariates that coincide in space (hash of rounded face centres, vectorised).

    Faces are compared through the deformation map (their corners mapped by
    D in one evaluation), so periodic maps (a full ring) glue across their seam.
    """
    pidx, fc = _all_face_corners(placed)
    if not len(pidx):
        return []
    D = placed[int(pidx[0])].outer
    params = np.clip(fc.reshape(-1, 3), D.domain[:, 0], D.domain[:, 1])
    corners = D.evaluate(params)[:, :3].reshape(len(pidx) * 6, 4, 3)
    rec_patch = np.repeat(pidx, 6)
    rec_face = np.tile(np.arange(6), len(pidx))
    scale = max(1.0, float(np.abs(corners).max()))
    key = np.round(corners.mean(axis=1) / (1e-7 * scale)).astype(np.int64)
    order = np.lexsort(key.T[::-1])
    ks = key[order]
    same = np.all(ks[1:] == ks[:-1], axis=1)
    triple = same[1:] & same[:-1]
    if triple.any():
        j = int(np.argmax(triple))
        a = order[j]
        raise TilingError(f"more than two patch faces meet at the face of patch {rec_patch[a]} "
                          f"({FACE_NAMES[rec_face[a]]}); overlapping tiles or patches")
    j = np.nonzero(same)[0]
    ia, ib = order[j], order[j + 1]
    keep = rec_patch[ia] != rec_patch[ib]
    ia, ib = ia[keep], ib[keep]
    orient = _corner_maps(corners[ia], corners[ib], TOL * scale)  # (M,) index into _ORIENTATIONS, -1: none
    out = []
    checked = set()
    for a, b, o in zip(ia, ib, orient):
        if o < 0:
            continue  # same centre but different faces (e.g. a smaller face inside a larger one)
        pa, fa = int(rec_patch[a]), FACE_NAMES[rec_face[a]]
        pb, fb = int(rec_patch[b]), FACE_NAMES[rec_face[b]]
        swap, flip = _ORIENTATIONS[o]
        sig = (id(placed[pa].spline), fa, id(placed[pb].spline), fb, o)
        if sig not in checked:  # face spaces depend on the tile patches only
            _check_face_spaces(placed, (pa, fa), (pb, fb), swap, flip)
            checked.add(sig)
        out.append(Interface("identity", (pa, fa), (pb, fb), swap, flip))
    return out


def _orientations():
    """The 8 face orientations (swap, (flip_s, flip_t)) and, for each, the corner permutation of face b."""
    out, perms = [], []
    for swap in (False, True):
        for fs in (False, True):
            for ft in (False, True):
                idx = []
                for t in (0, 1):
                    for s in (0, 1):
                        s2, t2 = (t, s) if swap else (s, t)
                        s2, t2 = (1 - s2 if fs else s2), (1 - t2 if ft else t2)
                        idx.append(t2 * 2 + s2)
                out.append((swap, (fs, ft)))
                perms.append(idx)
    return out, np.array(perms)


_ORIENTATIONS, _ORIENTATION_PERMS = _orientations()


def _corner_maps(ca: np.ndarray, cb: np.ndarray, tol: float) -> np.ndarray:
    """First orientation index with B(s', t') = A(s, t) for face pairs (M, 4, 3), or -1 if none."""
    if not len(ca):
        return np.zeros(0, np.int64)
    err = np.abs(cb[:, _ORIENTATION_PERMS] - ca[:, None]).max(axis=(2, 3))  # (M, 8)
    ok = err <= tol
    return np.where(ok.any(axis=1), np.argmax(ok, axis=1), -1)


def face_knots(P: PlacedPatch, face: str):
    k, _ = FACE_AXIS[face]
    return [(P.spline.knots[d], P.spline.degrees[d]) for d in range(3) if d != k]


def _normalised(U):
    U = np.asarray(U, float)
    return (U - U[0]) / (U[-1] - U[0])


def _check_face_spaces(placed, a, b, swap, flip):
    ka, kb = face_knots(placed[a[0]], a[1]), face_knots(placed[b[0]], b[1])
    if swap:
        kb = kb[::-1]
        flip = flip[::-1]
    for d in range(2):
        Ua, pa = ka[d]
        Ub, pb = kb[d]
        Ua = _normalised(Ua)
        Ub = _normalised(Ub)
        if flip[d]:
            Ub = 1 - Ub[::-1]
        if pa != pb or len(Ua) != len(Ub) or np.abs(Ua - Ub).max() > 1e-12:
            raise TilingError(
                f"faces patch {a[0]} {a[1]} and patch {b[0]} {b[1]} coincide but their spline spaces differ "
                f"(degrees {pa} vs {pb}, knots {np.round(Ua, 6).tolist()} vs {np.round(Ub, 6).tolist()}); "
                "use tiles whose opposite faces have matching knot vectors"
            )


def branch_refinement(parent_knots, box, child_knots) -> sp.csr_matrix:
    """R with child face coefficients = R @ parent face coefficients (per-direction Kronecker product).

    ``parent_knots``, ``child_knots``: [(U, p)] * 2 of the two faces; ``box``:
    sub-rectangle of the parent face carrying the child's face.  Raises
    :class:`TilingError` unless the child's face space contains the parent's.
    """
    Rs = []
    for d in range(2):
        (Up, pp), (Uc, pc) = parent_knots[d], child_knots[d]
        a, b = box[d]
        if pc != pp:
            raise TilingError(f"branch faces need equal degrees; parent {pp}, child {pc} (direction {d})")
        sub, S = kn.restriction(np.asarray(Up, float), pp, a, b)
        mapped = a + _normalised(Uc) * (b - a)
        vals_s, m_s = kn.breakpoints(sub)
        vals_c, m_c = kn.breakpoints(mapped)
        need = []
        for v, m in zip(vals_c, m_c):
            have = m_s[np.abs(vals_s - v) < 1e-12]
            have = int(have[0]) if len(have) else 0
            need += [v] * max(0, m - have)
        for v, m in zip(vals_s, m_s):
            if not np.any((np.abs(vals_c - v) < 1e-12) & (m_c >= m)):
                raise TilingError(
                    f"the child's branch-in face space does not contain the parent's branch-out face space: "
                    f"parent knot {v:g} (multiplicity {m}) is missing on the child (direction {d}); not nested"
                )
        inner = [v for v in need if a < v < b]
        _, Rins = kn.insertion_matrix(sub, pp, inner)
        Rs.append(sp.csr_matrix(Rins @ S))
    return sp.csr_matrix(sp.kron(Rs[0], Rs[1]))


def _branch_interface(placed, parent, pface, pbox, child, cface) -> Interface:
    P, C = placed[parent], placed[child]
    pk = face_knots(P, pface)
    if pbox is None:
        pbox = tuple((float(U[0]), float(U[-1])) for U, _ in pk)
    R = branch_refinement(pk, pbox, face_knots(C, cface))
    return Interface("branch", (parent, pface), (child, cface), box=tuple(map(tuple, pbox)), R=R)


def _tags(outer, placed, interfaces, root_faces, leaf_faces=()) -> dict:
    glued = set()
    for itf in interfaces:  # a parent's branch-out face is covered by its children's faces
        glued.add(itf.a)
        glued.add(itf.b)
    tags = {f: [] for f in FACE_NAMES}
    tags.update({"internal": [], "boundary": [], "branch-in": [], "branch-out": []})
    dom = outer.domain
    scale = float(np.abs(dom).max()) + 1.0
    pidx, fc = _all_face_corners(placed)
    # where[t, f]: index of the domain face all 4 corners lie on (the last match wins), 6 = internal
    where = np.full(fc.shape[:2], 6)
    for k in range(3):
        for side in (0, 1):
            on = np.all(np.abs(fc[..., k] - dom[k, side]) < TOL * scale, axis=-1)
            where[on] = 2 * k + side
    names = FACE_NAMES + ("internal",)
    for t, i in enumerate(pidx):
        i = int(i)
        for fi, f in enumerate(FACE_NAMES):
            if (i, f) in glued:
                continue
            tags[names[where[t, fi]]].append((i, f))
            tags["boundary"].append((i, f))
    tags["branch-in"] = list(root_faces)
    tags["branch-out"] = list(leaf_faces)  # free branch-out faces of the last level (fin tips)
    return tags


def slot_face_id(direction: int, value: float, side: int) -> str:
    """Name of one side of a discontinuity plane, e.g. ``u=0.5-`` (seen from u < 0.5)."""
    return f"{'uvw'[direction]}={value:.17g}{'-' if side < 0 else '+'}"


def parse_slot_face(face: str):
    """(direction, value, side) of a slot face id, or None for the six patch faces."""
    if face in FACE_NAMES or len(face) < 4 or face[1] != "=" or face[-1] not in "+-":
        return None
    return "uvw".index(face[0]), float(face[2:-1]), (-1 if face[-1] == "-" else 1)


def discontinuity_slots(spline: BSpline) -> dict:
    """Free parts of the discontinuity planes of a trivariate: {face id: [rectangles]}.

    Each full-multiplicity interior knot plane is compared side by side on the
    element pieces of the other two directions; pieces where the two sides do
    not coincide are free surface (a slot), on both sides.
    """
    out = {}
    size = float(np.ptp(spline.points.reshape(-1, 3), axis=0).max())
    for d in range(3):
        vals, mults = np.unique(spline.knots[d], return_counts=True)
        for v in vals[1:-1][mults[1:-1] >= spline.degrees[d] + 1]:
            rest = [k for k in range(3) if k != d]
            b1, b2 = spline.breakpoints(rest[0]), spline.breakpoints(rest[1])
            t = np.array([0.1, 0.5, 0.9])
            sides = []
            for side in (-1, 1):
                box = spline.domain.copy()
                box[d] = [box[d, 0], v] if side < 0 else [v, box[d, 1]]
                sub = spline.extract(box)  # one side of the plane: exact one-sided evaluation
                x = np.empty((len(b1) - 1, len(b2) - 1, 3, 3, 3))
                x[..., d] = v
                x[..., rest[0]] = (b1[:-1, None] + np.diff(b1)[:, None] * t)[:, None, :, None]
                x[..., rest[1]] = (b2[:-1, None] + np.diff(b2)[:, None] * t)[None, :, None, :]
                sides.append(sub.evaluate(x.reshape(-1, 3))[:, :3].reshape(x.shape[:4] + (3,)))
            free = np.linalg.norm(sides[0] - sides[1], axis=-1).max(axis=(2, 3)) > 1e-9 * size
            if free.any():
                rects = [((float(b1[i]), float(b1[i + 1])), (float(b2[j]), float(b2[j + 1])))
                         for i, j in zip(*np.nonzero(free))]
                for side in (-1, 1):
                    out[slot_face_id(d, v, side)] = rects
    return out


def _slot_faces(placed) -> dict:
    cache, out = {}, {}
    for i, P in enumerate(placed):
        if P.spline.dim != 3:
            continue
        key = id(P.spline)
        if key not in cache:
            cache[key] = discontinuity_slots(P.spline)
        for fid, rects in cache[key].items():
            out[(i, fid)] = rects
    return out
