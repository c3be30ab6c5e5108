"""Face quadrature: physical geometry of patch faces at their Gauss points.

A face is one of the six faces of a patch or a slot face (``u=0.5-``: the
discontinuity plane u = 0.5 seen from u < 0.5), integrated on the one-sided
sub-patch and restricted to the model's free rectangles of that plane.
Faces of patches that share a tile spline and a space are evaluated together
(one tile evaluation, one deformation-map evaluation per batch); results are
cached per (patch, face) for the lifetime of the problem.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.faces import FACE_AXIS, face_name, parse_slot_face
from geometry.patches.multipatch import PlacedPatch

from iga.assembly import compiled as fast_assembly
from iga.discretisation.rational import weight_grid
from iga.errors import ProblemError
from geometry.patches.chain import patches_geometry_derivs
from geometry.errors import show
from geometry.grouping import ObjectIndex

__all__ = ["FaceData", "FaceQuadrature", "cross"]

_CHUNK_POINTS = 1 << 18  # Gauss points evaluated together: bounds a batch's memory


def cross(a, b, axis=-1):
    """Cross product along ``axis``, written out (np.cross is slow for many small vectors)."""
    a, b = np.moveaxis(a, axis, 0), np.moveaxis(b, axis, 0)
    c = np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
    return np.moveaxis(c, 0, axis)


def chunks(members, points_each):
    """Split ``members`` into batches of at most about ``_CHUNK_POINTS`` Gauss points."""
    size = max(1, _CHUNK_POINTS // max(int(points_each), 1))
    return [members[i : i + size] for i in range(0, len(members), size)]


@dataclass
class FaceData:
    """Quadrature data of one patch face (physical geometry at the face's Gauss points).

    ``x`` (N, 3) points (m), ``dAw`` (N,) area element times quadrature weight
    (m^2), ``normal`` (N, 3) outward unit normal, ``chans`` {name: (N,)} channel
    values, ``dofs`` the global DOF numbers of the face space (C order).
    """

    patch: int
    face: str
    space: object
    dofs: np.ndarray
    x: np.ndarray
    chans: dict
    dAw: np.ndarray
    normal: np.ndarray
    #: where the patch is analysed in the NURBS basis R = w N / W (:mod:`iga.discretisation.rational`): 1 / W at the Gauss
    #: points and the face DOFs' weights w; else None (the face forms scale their basis functions by them)
    inv_w: np.ndarray | None = None
    w_dofs: np.ndarray | None = None

    def trace(self, u: np.ndarray) -> np.ndarray:
        """Values at the face Gauss points of the global coefficient vector ``u``."""
        Bs, Bt = [d.B[0][:, :-1] for d in self.space.dirs]
        U = u[self.dofs] if self.w_dofs is None else u[self.dofs] * self.w_dofs
        out = np.einsum("ab,aq,br->qr", U.reshape(self.space.shape), Bs, Bt).ravel()
        return out if self.inv_w is None else out * self.inv_w

    def basis_scale(self, power: int = 1):
        """The factor (1 / W)^power of ``power`` basis functions at the Gauss points (1.0 in the polynomial
        basis); the DOF weights are applied by the forms (:attr:`w_dofs`)."""
        return 1.0 if self.inv_w is None else self.inv_w**power


class FaceQuadrature:
    """Face data of a model on given spaces, computed in batches and cached: ``fq(keys) -> [FaceData]``.

    ``compiled``: large face grids run in the compiled grid kernel (the
    problem decides, from its size, whether compiled kernels are in use).
    """

    def __init__(self, model, spaces, offsets, compiled: bool = False, weights=None):
        self.model, self.spaces, self.offsets, self.compiled = model, spaces, offsets, compiled
        self.weights = weights if weights is not None else [None] * len(spaces)  # NURBS basis: iga.discretisation.rational
        self.cache: dict = {}

    def __call__(self, keys) -> list[FaceData]:
        same = ObjectIndex()  # patches share splines and maps: group by object
        groups: dict = {}
        n = len(self.model.patches)
        for pi, face in keys:
            if (pi, face) in self.cache:
                continue
            if not (0 <= pi < n):
                raise ProblemError(f"patch index {pi} out of range (the model has {n} patches)")
            if face not in FACE_AXIS and parse_slot_face(face) is None:
                raise ProblemError(f"unknown face {show(face)}; use umin .. wmax or a slot face id such as 'u=0.5-'")
            gk = (same(self.model.patches[pi].spline), self.spaces[pi].key(), face)
            groups.setdefault(gk, []).append(pi)
        # compiled evaluation where this call's face points together reach the compiled assembly's threshold
        # (a V-model's 136k Robin faces come in 800 small batches; the demo's faces stay below it)
        points = sum(len(m) * (self.spaces[m[0]].nq_total // min(self.spaces[m[0]].qshape)) for m in groups.values())
        compiled = self.compiled or (fast_assembly.AVAILABLE and points >= fast_assembly.MIN_POINTS)
        for (_, _, face), members in groups.items():
            space = self.spaces[members[0]]
            for chunk in chunks(members, space.nq_total // min(space.qshape)):
                self._group(chunk, face, compiled)
        return [self.cache[(pi, face)] for pi, face in keys]

    def _group(self, members, face, compiled: bool = False):
        """Fill the cache for ``face`` of patches ``members`` (same tile spline and space)."""
        patch0, space = self.model.patches[members[0]], self.spaces[members[0]]
        slot = parse_slot_face(face)
        if slot is None:
            k, side = FACE_AXIS[face]
            U = patch0.spline.knots[k]
            at = U[-1] if side else U[0]
            geos = [self.model.patches[pi] for pi in members]
            dofs = space.face_dofs(face)
        else:
            k, at, sgn = slot
            side = 1 if sgn < 0 else 0  # u=v- is the max face of the sub-patch below the plane
            box = patch0.spline.domain.copy()
            box[k] = [box[k, 0], at] if sgn < 0 else [at, box[k, 1]]
            sub = patch0.spline.extract(box)
            geos = [PlacedPatch(sub, p.placement, p.outer, p.tile, p.level)
                    for p in (self.model.patches[pi] for pi in members)]
            first = int(np.searchsorted(space.dirs[k].knots, at, side="left"))
            layer = first - 1 if sgn < 0 else first
            dofs = np.take(np.arange(space.ndof).reshape(space.shape), layer, axis=k).ravel()
        axes = [d.qpts for d in space.dirs]
        axes[k] = np.array([at])
        x, Dx, chans = patches_geometry_derivs(geos, axes, compiled=compiled)
        a, b = [i for i in range(3) if i != k]
        cr = cross(Dx[a], Dx[b])
        dA = np.linalg.norm(cr, axis=-1)
        if np.any(~(dA > 0)):
            bad = members[int(np.argmax(np.any(~(dA > 0), axis=1)))]
            raise ProblemError(f"patch {bad} face {face} is degenerate (zero or undefined area at some Gauss points)")
        inward = np.einsum("pni,pni->pn", cr, Dx[k])
        sign = np.where(inward > 0, 1.0, -1.0) * (1.0 if side else -1.0)
        normal = cr / dA[..., None] * sign[..., None]
        fs = space.face_space(face_name(k, 0))
        w = np.multiply.outer(fs.dirs[0].qw, fs.dirs[1].qw).ravel()
        dAw = dA * w
        if slot is not None:
            rest = [i for i in range(3) if i != k]
            q1, q2 = np.meshgrid(space.dirs[rest[0]].qpts, space.dirs[rest[1]].qpts, indexing="ij")
            for j, pi in enumerate(members):
                rects = self.model.face_regions.get((pi, face))
                if rects is None:
                    raise ProblemError(f"patch {pi} has no free region recorded for slot face {show(face)}")
                mask = np.zeros(q1.shape, bool)
                for (a1, b1), (a2, b2) in rects:
                    mask |= (q1 > a1) & (q1 < b1) & (q2 > a2) & (q2 < b2)
                dAw[j] *= mask.ravel()
        # one face object per patch (the forms take them one by one): rows of batch arrays, built at once
        names = list(chans)
        rows = zip(*(chans[c] for c in names)) if names else ((),) * len(members)
        global_dofs = dofs[None, :] + np.asarray(self.offsets)[np.asarray(members)][:, None]
        inv_w = w_dofs = None
        if self.weights[members[0]] is not None:  # the group shares its spline: one weight function
            inv_w = 1.0 / weight_grid(geos[0].spline, axes)[0]
            w_dofs = self.weights[members[0]].reshape(-1)[dofs]
        for pi, d, xj, ch, a, nj in zip(members, global_dofs, x, rows, dAw, normal):
            self.cache[(pi, face)] = FaceData(pi, face, fs, d, xj, dict(zip(names, ch)), a, nj, inv_w, w_dofs)
