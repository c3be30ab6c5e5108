"""Multi-patch models: placed patches, the interfaces that glue their faces, and boundary tags.

This is the model protocol shared by tiling and analysis (like G+Smo's
``gsMultiPatch`` with its box topology): anything with ``patches`` (each with
``spline``, ``placement``, ``outer``, ``tile``, ``level``), ``interfaces`` and
``tags`` is a model.  :class:`MultiPatch` is the plain implementation; a
``tiling.Microstructure`` is one too.

* :class:`PlacedPatch`: a trivariate (or lower) patch ``spline`` placed by an
  affine map ``[A | b]`` into the parameter domain of an ``outer`` deformation
  map; its physical image is ``outer(A spline(xi) + b)`` (or the affine image,
  or the spline itself).  Analysis uses the patch's own parameters and basis.
* :class:`Interface`: ``identity`` (two faces that coincide in space, with
  the parameter map between them: face B's parameters (s', t') are face A's
  (s, t) swapped if ``swap``, then reversed per ``flip``) or ``branch``
  (a child face on a sub-rectangle ``box`` of a parent face, child face
  coefficients = ``R`` @ parent face coefficients).
* :func:`detect_interfaces` finds conforming shared faces (equal corners, equal
  face spline spaces, coinciding images at interior sample points), as G+Smo's
  ``computeTopology`` does; :meth:`MultiPatch.from_splines` couples a list of
  patches that way and refuses patches that touch without conforming.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np
import scipy.sparse as sp

from geometry.bspline import BSpline
from geometry.composition.core import compose_many, compose_placed
from geometry.errors import SplineError
from geometry.faces import FACE_NAMES, face_knots, nested_refinement, oriented_face_knots
from geometry.maps.inversion import invert
from geometry.patches.placed_points import IDENTITY, face_points, physical_corners, tile_corners, trivariates
from geometry.grouping import identity_groups, near_pairs
from geometry.tolerances import CONTACT, INTERFACE, model_size, same_space

__all__ = ["PlacedPatch", "Interface", "MultiPatch", "detect_interfaces", "free_faces", "free_face_mask", "face_points",
           "ORIENTATIONS"]

TOL = INTERFACE  # coinciding corners and faces, relative to the model's size (at least 1)



@dataclass(eq=False, slots=True)
class PlacedPatch:
    """One patch of a model: ``spline`` placed by ``placement`` (3, 4) into the domain of ``outer``."""

    spline: BSpline
    placement: np.ndarray | None = None
    outer: BSpline | None = None
    tile: int = 0
    level: int = 0
    patch_in_tile: int = 0
    #: knot-span bisections of this patch beyond its tile's own (set by adaptive refinement, ``iga.adaptivity``)
    refinement: int = 0
    #: the composed image, once computed (:attr:`composed`) or set by a batch (:meth:`set_composed`)
    _composed: BSpline | None = field(default=None, repr=False)

    @property
    def channels(self) -> tuple[str, ...]:
        """Channel names available on this patch: the spline's, then the outer map's."""
        return tuple(self.spline.channels) + (tuple(self.outer.channels) if self.outer is not None else ())

    @property
    def composed(self) -> BSpline:
        """The exact physical patch ``outer(A spline + b)`` as one spline (computed once, then kept)."""
        if self._composed is None:
            A = IDENTITY if self.placement is None else self.placement
            if self.outer is None:
                self._composed = self.spline if self.placement is None else self.spline.affine(A[:, :3], A[:, 3])
            else:
                self._composed = compose_many(self.outer, self.spline, A[None])[0]
        return self._composed

    @property
    def is_composed(self) -> bool:
        """Whether :attr:`composed` is already known."""
        return self._composed is not None

    def set_composed(self, spline: BSpline) -> None:
        """Store the composed image computed elsewhere (a batch of :func:`geometry.compose_many`)."""
        self._composed = spline

    def image(self, params: np.ndarray) -> np.ndarray:
        """Physical points (N, 3) at the patch's parameters ``params`` (N, d)."""
        y = self.spline.evaluate(params)[:, :3]
        return _finish_image(self, y)


def _finish_image(P: PlacedPatch, y: np.ndarray) -> np.ndarray:
    """Apply placement and outer map to tile-space points y (N, 3)."""
    if P.placement is not None:
        y = y @ P.placement[:, :3].T + P.placement[:, 3]
    if P.outer is not None:
        dom = P.outer.domain
        y = P.outer.evaluate(np.clip(y, dom[:, 0], dom[:, 1]))[:, :3]
    return y


@dataclass(eq=False, slots=True)
class Interface:
    """Two glued faces: ``a`` = (patch, face), ``b`` = (patch, face); see the module notes."""

    kind: str  # "identity" or "branch"
    a: tuple
    b: tuple
    swap: bool = False
    flip: tuple = (False, False)
    box: tuple | None = None  # branch: sub-rectangle of a's face (the parent's)
    R: sp.csr_matrix | None = None  # branch: child (b) face coefficients = R @ parent (a) face coefficients


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


ORIENTATIONS, _ORIENTATION_PERMS = _orientations()


def _same_face_space(patches, a, b, swap, flip) -> bool:
    ka, kb = face_knots(patches[a[0]].spline, a[1]), face_knots(patches[b[0]].spline, b[1])
    return same_space(ka, oriented_face_knots(kb, swap, flip))  # b's axes as a's


# interior sample points of a face (normalised face parameters): images must coincide on conforming faces
FACE_SAMPLES = np.array([[0.5, 0.5], [0.2113, 0.3187], [0.7887, 0.2311], [0.3571, 0.8123], [0.8811, 0.6917]])
FACE_SAMPLES.setflags(write=False)


def _oriented_samples(swap, flip):
    """Face-b parameters of the face-a samples under an orientation."""
    st = (FACE_SAMPLES[:, ::-1] if swap else FACE_SAMPLES).copy()
    if flip[0]:
        st[:, 0] = 1 - st[:, 0]
    if flip[1]:
        st[:, 1] = 1 - st[:, 1]
    return st


def detect_interfaces(patches, strict: bool = False, placed_corners=None):
    """Identity interfaces between coinciding faces of trivariate patches.

    Faces are matched by their four corners in physical space (face centres
    within the tolerance by a KD-tree, then the corner permutation that maps
    one onto the other), so periodic maps glue across their seam.  A pair is an interface
    when the two face spline spaces are equal (after the orientation) and the
    images coincide at interior sample points.  Pairs whose corners coincide but
    that fail either check are returned in ``mismatched`` (with the reason), or
    raise :class:`SplineError` when ``strict``.  Returns ``(interfaces, mismatched)``.  ``placed_corners``:
    the :func:`geometry.patches.placed_points.tile_corners` of ``patches``, when the caller has them.
    """
    pidx, fc = tile_corners(patches) if placed_corners is None else placed_corners
    if not len(pidx):
        return [], []
    corners = physical_corners(patches, pidx, fc).reshape(len(pidx) * 6, 4, 3)
    rec_patch = np.repeat(pidx, 6)
    rec_face = np.tile(np.arange(6), len(pidx))
    scale = model_size(corners)
    # candidate pairs: face centres within the tolerance (a KD-tree, so no rounding bucket can split a pair;
    # midpoint splits build faster on 10^5 centres, the pairs are the same)
    found = near_pairs(corners.mean(axis=1), TOL * scale, balanced_tree=False)
    ia, ib = found[:, 0], found[:, 1]
    keep = rec_patch[ia] != rec_patch[ib]
    ia, ib = ia[keep], ib[keep]
    err = np.abs(corners[ib][:, _ORIENTATION_PERMS] - corners[ia][:, None]).max(axis=(2, 3)) if len(ia) else None
    ok = err <= TOL * scale if len(ia) else np.zeros((0, 8), bool)
    orient = np.where(ok.any(axis=1), np.argmax(ok, axis=1), -1)
    matched = orient >= 0
    faces, counts = np.unique(np.concatenate([ia[matched], ib[matched]]), return_counts=True)
    if np.any(counts > 1):
        a = faces[int(np.argmax(counts > 1))]
        raise SplineError(f"more than two patch faces meet at the face {FACE_NAMES[rec_face[a]]} of patch "
                          f"{rec_patch[a]}; patches overlap")
    # the matched pairs (same centre, other corners: e.g. a face inside a larger one is not), as arrays
    ia, ib, orient = ia[matched], ib[matched], orient[matched]
    pa, fa, pb, fb = rec_patch[ia], rec_face[ia], rec_patch[ib], rec_face[ib]
    # face spaces depend on the tile patches only: one check per (tile spline, face, spline, face, orientation)
    users = np.unique(np.concatenate([pa, pb]))
    spline_of = np.zeros(len(patches), np.int64)
    spline_of[users] = identity_groups([patches[i].spline for i in users])[1]
    sig = np.stack([spline_of[pa], fa, spline_of[pb], fb, orient], axis=1)
    _, first, inverse = np.unique(sig, axis=0, return_index=True, return_inverse=True)
    space_ok = np.array([_same_face_space(patches, (int(pa[j]), FACE_NAMES[fa[j]]), (int(pb[j]), FACE_NAMES[fb[j]]),
                                          *ORIENTATIONS[orient[j]]) for j in first.tolist()], bool)[inverse.ravel()]
    bad = [(_key(pa[j], fa[j]), _key(pb[j], fb[j]), "their spline spaces differ (degrees or knots)")
           for j in np.flatnonzero(~space_ok).tolist()]
    todo = np.flatnonzero(space_ok)
    coincide = _coincide(patches, pa[todo], fa[todo], pb[todo], fb[todo], orient[todo], scale)
    out = [Interface("identity", (p1, FACE_NAMES[f1]), (p2, FACE_NAMES[f2]), *ORIENTATIONS[o])
           for p1, f1, p2, f2, o in zip(*(x[todo[coincide]].tolist() for x in (pa, fa, pb, fb, orient)))]
    bad += [(_key(pa[j], fa[j]), _key(pb[j], fb[j]), "their surfaces part between the corners (the control points "
             "differ)") for j in todo[~coincide].tolist()]
    if strict and bad:
        a, b, why = bad[0]
        raise SplineError(f"face {a[1]} of patch {a[0]} and face {b[1]} of patch {b[0]} touch but do not conform: "
                          f"{why}; give both patches the same face (control points, degrees and knots)")
    return out, bad


def _key(patch, face) -> tuple:
    """The (patch, face name) key of a patch and face index, as interfaces hold them."""
    return int(patch), FACE_NAMES[face]


def _coincide(patches, pa, fa, pb, fb, orient, scale) -> np.ndarray:
    """Whether the images of the face pairs (patch ``pa``, face index ``fa``) and (``pb``, ``fb``) (arrays) under
    the orientations ``orient`` coincide at the interior samples.

    Pairs of patches placed in one outer map are compared in its parameter
    space first (exact and cheap: placed tile coordinates); the rest, and
    pairs that differ there (a periodic map's seam), through the images.
    """
    res = np.zeros(len(pa), bool)
    if not len(pa):
        return res
    sets = np.stack([_oriented_samples(*o) for o in ORIENTATIONS])  # face b's samples, per orientation
    users = np.unique(np.concatenate([pa, pb]))
    outer_of = np.zeros(len(patches), np.int64)
    outer_of[users] = identity_groups([patches[i].outer for i in users])[1]
    ka, kb = np.stack([pa, fa], axis=1), np.stack([pb, fb], axis=1)
    same = np.flatnonzero(outer_of[pa] == outer_of[pb])
    if len(same):
        qa = face_points(patches, ka[same], FACE_SAMPLES, through_outer=False)
        qb = face_points(patches, kb[same], sets, through_outer=False, which=orient[same])
        hit = np.abs(qa - qb).max(axis=(1, 2)) <= TOL * max(1.0, float(np.abs(qa).max()))
        res[same[hit]] = True
    rest = np.flatnonzero(~res)
    if len(rest):
        qa = face_points(patches, ka[rest], FACE_SAMPLES)
        qb = face_points(patches, kb[rest], sets, which=orient[rest])
        res[rest] = np.abs(qa - qb).max(axis=(1, 2)) <= TOL * scale
    return res


def free_faces(patches, interfaces, mask=None) -> list[tuple[int, str]]:
    """Faces of trivariate patches that no interface glues, in patch then face order (``mask``: the
    :func:`free_face_mask` of these patches and interfaces, when the caller has it)."""
    pidx, free = free_face_mask(patches, interfaces) if mask is None else mask
    t, f = np.nonzero(free)  # row-major: patch then face order
    pid = pidx.tolist()  # one int per patch, shared by its faces' keys
    return [(pid[a], FACE_NAMES[b]) for a, b in zip(t.tolist(), f.tolist())]


def free_face_mask(patches, interfaces, pidx=None) -> tuple[np.ndarray, np.ndarray]:
    """(trivariate patch indices (T,), free (T, 6) bool in FACE_NAMES order): the faces no interface glues,
    from one array pass over the interfaces' ends (a set lookup per face took 0.15 s on 65k patches).
    Interface ends that are not one of the six faces (slot faces) hide none of them.  ``pidx``: the
    :func:`geometry.patches.placed_points.trivariates` of ``patches``, when the caller has them."""
    pidx = trivariates(patches) if pidx is None else pidx
    row = np.full(len(patches), -1)
    row[pidx] = np.arange(len(pidx))
    face_index = {f: k for k, f in enumerate(FACE_NAMES)}
    ends = [e for itf in interfaces for e in (itf.a, itf.b)]
    ep = np.fromiter((e[0] for e in ends), np.int64, count=len(ends))
    ef = np.fromiter((face_index.get(e[1], -1) for e in ends), np.int64, count=len(ends))
    six = (ef >= 0) & (row[ep] >= 0)
    free = np.ones((len(pidx), 6), bool)
    free[row[ep[six]], ef[six]] = False
    return pidx, free


@dataclass(eq=False)
class MultiPatch:
    """Patches, interfaces, tags and the free regions of slot faces: the model protocol (module notes).

    ``tags``: tag -> list of (patch index, face name or slot face id);
    ``face_regions``: (patch, slot face id) -> free rectangles of that slot face.
    """

    patches: list
    interfaces: list = field(default_factory=list)
    tags: dict = field(default_factory=dict)
    face_regions: dict = field(default_factory=dict)

    def compose_all(self) -> list[BSpline]:
        """Every patch's physical geometry (:func:`geometry.compose_placed`: batched, cached on the patches)."""
        return compose_placed(self.patches)

    @classmethod
    def from_splines(cls, splines, couple: bool = True, branches=(), check_contact: bool = True) -> "MultiPatch":
        """A model of independent trivariate patches; with ``couple``, conforming shared faces are glued.

        Tags: each face name (``umin`` .. ``wmax``) holds that face of every
        patch that is free; ``patch{i}.{face}`` one face of one patch (free or
        not); ``boundary`` every free face.  Patches that touch without
        conforming (corners coincide but spaces or surfaces differ, or a face
        lies on another patch's face without matching it) raise :class:`SplineError`,
        except the pairs in ``branches``: [(parent (patch, face), box, child
        (patch, face))], glued by refinement matrices (the child's face space
        must refine the parent face's restriction to ``box``).  ``check_contact=False``
        skips the search for touching faces left unglued (for topologies given
        by a file, whose author decided what is glued).
        """
        patches = []
        for i, s in enumerate(splines):
            if not isinstance(s, BSpline) or s.dim != 3:
                what = type(s).__name__ if not isinstance(s, BSpline) else f"{s.dim}-variate BSpline"
                raise SplineError(f"patch {i} is a {what}; a multi-patch model needs trivariate geometry.BSpline patches")
            patches.append(PlacedPatch(s, tile=i))
        interfaces = []
        if couple and len(patches) > 1:
            linked = {frozenset([a, c]) for a, _, c in branches}
            interfaces, mismatched = detect_interfaces(patches, strict=not linked)
            for a, b, why in mismatched:
                if frozenset([a, b]) not in linked:
                    raise SplineError(f"faces patch {a[0]} {a[1]} and patch {b[0]} {b[1]} meet corner to corner, but {why}")
            interfaces = [i for i in interfaces if frozenset([i.a, i.b]) not in linked]
            for a, box, c in branches:
                R = nested_refinement(face_knots(patches[a[0]].spline, a[1]), box, face_knots(patches[c[0]].spline, c[1]))
                interfaces.append(Interface("branch", a, c, box=tuple(map(tuple, box)), R=R))
            if check_contact:
                _refuse_nonconforming_contact(patches, interfaces)
        free = free_faces(patches, interfaces)
        tags = {f: [(i, g) for i, g in free if g == f] for f in FACE_NAMES}
        tags["boundary"] = list(free)
        for i in range(len(patches)):
            for f in FACE_NAMES:
                tags[f"patch{i}.{f}"] = [(i, f)]
        return cls(patches, interfaces, tags)


def _refuse_nonconforming_contact(patches, interfaces) -> None:
    """Raise when an interior point of a free face lies on another patch (contact without an interface).

    Each free face's interior samples are inverted into every other patch whose
    bounding box holds them; a sample inside or on another patch means the two
    touch or overlap without a conforming interface.
    """
    free = free_faces(patches, interfaces)
    if not free:
        return
    pts = face_points(patches, free, FACE_SAMPLES)  # (F, n, 3)
    tol = CONTACT * model_size(pts)
    boxes = [P.spline.bounding_box() for P in patches]
    for j, (pi, f) in enumerate(free):
        for qi, P in enumerate(patches):
            if qi == pi:
                continue
            lo, hi = boxes[qi][:, 0] - tol, boxes[qi][:, 1] + tol
            cand = pts[j][np.all((pts[j] >= lo) & (pts[j] <= hi), axis=1)]
            if not len(cand):
                continue
            inv = invert(P.spline, cand)
            if np.any(inv.distance <= tol):
                raise SplineError(
                    f"face {f} of patch {pi} touches patch {qi} without a conforming interface (no face of patch "
                    f"{qi} matches it corner to corner with the same spline space); split or refine the patches so "
                    "that shared faces are identical, or pass them as separate models"
                )
