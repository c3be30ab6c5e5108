"""One-to-one bridging tiles and their collisions (Hong and Elber 2021, Sections 3.2-3.3).

Every anchoring surface (a face of a to-be-bridged tile towards a purged
neighbour) is swept to the nearest trimming surface.  The bridge is built in
its primitive's parameter domain and composed through the primitive's map,
like the tiles (Massarwi et al. 2018, Remark 2), so its first face *is* the
anchoring face (an identity interface with the tile) and the composition
carries its continuity into space:

* axis: a cubic Bezier curve C, C + a e, P - b d, P in parameters, with C the
  anchoring face's centre, e its outward direction, P the parameters of the
  closest point on the trimming surface to C + beta L e (L = |P - C|), and d
  the parameter direction whose image is the trimming surface's normal at P
  (J^-1 n): G1 with the tile at C, orthogonal to the surface at P (the
  paper's cubic axis, Section 3.3, which frees both end tangents);
* cross-sections: the anchoring face's control net, moved with the axis and
  turned (minimal rotation) from e to the end tangent, flattened onto the
  plane normal to it at the far end.  The second control layer extends the
  tile's own last layer, so the bridge is G1 with the tile across the whole
  face, not only at its centre.

Collisions (Section 3.3): two bridges collide when their sampled axes (in
space) come closer than the sum of their inscribed radii.  A collision is
resolved by swapping the two far ends if that separates the axes more, then
by repelling along T1 x T2 (the cross product of the axes' tangents at their
closest points) the far inner control point, or, when the axes meet near
the surface, the far end itself, sliding along the surface; if that fails
the later bridge is eliminated.  The counts of each are reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np

from geometry.numbers import TINY
from geometry import BSpline
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.maps.inversion import invert, invert_nearest

from ..errors import TilingError
from .report import SurfaceCounts
from .repulsion import Collisions, closest, repel
from geometry.grouping import ObjectIndex, near_pairs
from geometry.tolerances import COINCIDENT, ROUNDOFF

__all__ = ["Bridge", "build_bridges", "resolve_collisions", "axis_samples"]

_R = np.linspace(0.0, 1.0, 24)  # axis samples for collision tests


@dataclass
class Bridge:
    """A bridging tile: ``spline`` (3-variate, in the primitive's parameters; its ``wmin`` face is the
    anchoring face), the primitive's ``D``, the anchoring (patch, face), and its axis control points."""

    spline: BSpline
    D: BSpline
    patch: int
    face: str
    axis: np.ndarray  # (4, 3) parameters
    radius: float  # inscribed radius of the sections in space (bounding the tube from inside)
    section: np.ndarray = field(repr=False, default=None)  # (ns, nt, 3) face offsets from C, parameters
    rows01: np.ndarray = field(repr=False, default=None)  # the first two control layers (fixed by the tile)
    target: list = field(repr=False, default=None)  # the trimming primitive's six boundary faces
    beta: float = 0.5  # the bend parameter it was built with
    #: where the bridge is rebuilt in space (:mod:`tiling.vrep.spatial`): its geometry and analysis space
    geometry: BSpline = field(repr=False, default=None)
    space: list = field(repr=False, default=None)
    #: (spline, whether the analysis can take it) once asked (:func:`tiling.vrep.assemble._valid`); stale once
    #: the spline is replaced (a bridge that moved is snapped into a new one)
    regular: tuple = field(repr=False, default=None)


def _bernstein3(r):
    r = np.asarray(r, float)[:, None]
    return np.hstack([(1 - r) ** 3, 3 * r * (1 - r) ** 2, 3 * r**2 * (1 - r), r**3])


def axis_samples(b: Bridge, r=_R) -> np.ndarray:
    """Physical points of the bridge's axis at ``r`` (default 24 samples)."""
    t = _bernstein3(r) @ b.axis
    return b.D.evaluate(np.clip(t, b.D.domain[:, 0], b.D.domain[:, 1]))[:, :3]


def _rotation(a, b):
    """Minimal rotation taking unit vector a to unit vector b (Rodrigues)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if np.linalg.norm(v) < ROUNDOFF:
        if c > 0:
            return np.eye(3)
        p = np.eye(3)[np.argmin(np.abs(a))]
        p = p - a * np.dot(p, a)
        p /= np.linalg.norm(p)
        return 2 * np.outer(p, p) - np.eye(3)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1 + c)


def _far_section(b: Bridge) -> np.ndarray:
    """The far section's control points (parameters) before snapping: the face net turned to the end tangent."""
    e = b.axis[1] - b.axis[0]
    e = e / np.linalg.norm(e)
    end = b.axis[3] - b.axis[2]
    end = end / np.linalg.norm(end)
    flat = b.section - np.einsum("ijk,k->ij", b.section, end)[..., None] * end  # onto the plane normal to `end`
    return b.axis[3] + flat @ _rotation(e, end).T


def _snap(bridges: list) -> None:
    """Move the far sections' control points onto their trimming surfaces (through each bridge's map), in one
    batch of inversions per trimming primitive and map, and rebuild the control nets."""
    same = ObjectIndex()  # bridges share trimming primitives and maps: group by object
    groups: dict = {}
    for b in bridges:
        groups.setdefault((same(b.target[0]) if b.target else None, same(b.D)), []).append(b)
    for members in groups.values():
        lasts = [_far_section(b) for b in members]
        b0 = members[0]
        if b0.target:
            flat = np.concatenate([x.reshape(-1, 3) for x in lasts])
            x = b0.D.evaluate(np.clip(flat, b0.D.domain[:, 0], b0.D.domain[:, 1]))[:, :3]
            near, inv = invert_nearest(b0.target, x)  # the nearest of the primitive's faces, point by point
            on = np.empty_like(x)
            for g, G in enumerate(b0.target):
                sel = near == g
                if sel.any():
                    on[sel] = G.evaluate(inv.params[sel])[:, :3]
            back = invert(b0.D, on)
            flat = np.where(back.inside[:, None], back.params, flat)
            lasts = np.split(flat, np.cumsum([x.size // 3 for x in lasts])[:-1])
        for b, last in zip(members, lasts):
            last = np.asarray(last).reshape(b.section.shape)
            rows = np.stack([b.rows01[0], b.rows01[1], last - (b.axis[3] - b.axis[2]), last], axis=2)
            b.spline = BSpline(b.spline.degrees, b.spline.knots, rows)


def _retarget(b: Bridge, x: np.ndarray) -> bool:
    """Move the bridge's far end to the trimming surface point nearest to the physical point ``x``, its end
    tangent along the surface normal there; False (unchanged) when that point leaves the primitive."""
    near, inv = invert_nearest(b.target, x[None])
    g = int(near[0])
    p, J = b.target[g].value_and_jacobian(inv.params)
    back = invert(b.D, p[:, :3])
    if not back.inside[0]:
        return False
    n = np.cross(J[0, :3, 0], J[0, :3, 1])
    start = b.D.evaluate(b.axis[:1])[0, :3]
    n *= np.sign(np.dot(n, start - p[0, :3])) / np.linalg.norm(n)
    d = np.linalg.solve(b.D.jacobian(back.params)[0, :3, :], n)
    reach = float(np.linalg.norm(b.axis[2] - b.axis[3]))
    b.axis[3] = back.params[0]
    b.axis[2] = np.clip(back.params[0] + reach * d / np.linalg.norm(d), b.D.domain[:, 0], b.D.domain[:, 1])
    return True


def _anchor_geometry(placed, anchors) -> list:
    """Per anchoring face, in the primitive's parameters: (patch, face, face surface, control net F, the tile's
    next layer T1, centre C, unit outward direction e)."""
    geo = []
    for pi, face in anchors:
        P = placed[pi]
        S = P.spline.affine(P.placement[:, :3], P.placement[:, 3])  # the tile patch in D's parameters
        k, s = FACE_AXIS[face]
        cp = S.control_points[..., :3]
        F, T1 = np.take(cp, -1 if s else 0, axis=k), np.take(cp, -2 if s else 1, axis=k)
        fs = S.boundary(face)
        C = fs.evaluate(fs.domain.mean(1)[None])[0, :3]
        e = (F - T1).mean((0, 1))
        e /= np.linalg.norm(e)
        geo.append((pi, face, fs, F, T1, C, e))
    return geo


def _targets(model, prim, faces: list, geo: list):
    """(points (N, 3) in space, unit normals towards the anchors (N, 3), index of the chosen face (N,)): for
    every anchor the nearest boundary point of another primitive that bounds ``prim``'s territory (just beyond
    it, away from the point ahead of the anchor, the territory ends); one batch of inversions per face."""
    D = prim.D
    ahead = np.array([C + e * float(np.ptp(F.reshape(-1, 3), axis=0).max()) for _, _, _, F, _, C, e in geo])
    M = D.evaluate(np.clip(ahead, D.domain[:, 0], D.domain[:, 1]))[:, :3]
    invs = [invert(G, M) for G in faces]
    dist = np.stack([v.distance for v in invs])  # (faces, anchors)
    pts = np.stack([G.evaluate(v.params)[:, :3] for G, v in zip(faces, invs)])
    away = pts - M[None]
    away /= np.maximum(np.linalg.norm(away, axis=2), TINY)[..., None]
    eps = 1e-3 * max(float(np.ptp(D.points.reshape(-1, 3), axis=0).max()), TINY)
    ends = model.territory(prim, (pts + eps * away).reshape(-1, 3)).reshape(dist.shape)
    order = np.argsort(dist, axis=0)
    choice = np.array([next((g for g in order[:, i] if not ends[g, i]), order[0, i]) for i in range(len(geo))])
    Pphys = pts[choice, np.arange(len(geo))]
    normals = np.zeros_like(Pphys)
    for g in np.unique(choice):
        sel = np.flatnonzero(choice == g)
        _, J = faces[g].value_and_jacobian(invs[g].params[sel])
        normals[sel] = np.cross(J[:, :3, 0], J[:, :3, 1])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    # towards the anchoring face: the point ahead (M) may already lie beyond a close surface
    start = D.evaluate(np.array([C for _, _, _, _, _, C, _ in geo]))[:, :3]
    normals *= np.sign(np.sum(normals * (start - Pphys), axis=1))[:, None]
    return Pphys, normals, choice


def build_bridges(model, prim, cls, placed, anchors, beta: float = 0.5) -> tuple[list, SurfaceCounts]:
    """Bridges for the anchoring faces ``anchors`` [(patch index into ``placed``, face)] of primitive ``prim``.

    Returns (bridges, report) with the counts of anchoring faces, bridges built and those dropped because
    their target lies outside the primitive's domain.
    """
    if not (np.isfinite(beta) and 0 < beta < 1):
        raise TilingError(f"the bend parameter beta must be in (0, 1), got {beta!r}")
    targets = [q for q in model.primitives() if q is not prim]
    if not targets:
        raise TilingError(f"primitive {prim.name!r} has anchoring faces but no trimming surface to bridge to")
    sides = {q: [q.D.boundary(f) for f in FACE_NAMES] for q in targets}  # shared: bridges snap in batches
    faces = [G for q in targets for G in sides[q]]
    owner = [sides[q] for q in targets for _ in FACE_NAMES]
    D = prim.D
    geo = _anchor_geometry(placed, anchors)
    if not geo:
        return [], SurfaceCounts()
    Pphys, normals, choice = _targets(model, prim, faces, geo)
    back = invert(D, Pphys)
    JD = D.jacobian(back.params)[:, :3, :]
    out, dropped = [], 0
    for i, (pi, face, fs, F, T1, C, e) in enumerate(geo):
        if not back.inside[i]:
            dropped += 1
            continue
        Pp = back.params[i]
        d = np.linalg.solve(JD[i], normals[i])
        d /= np.linalg.norm(d)
        L = float(np.linalg.norm(Pp - C))
        axis = np.stack([C, C + beta * L * e, Pp + beta * L * d, Pp])
        if np.any(axis < D.domain[:, 0] - COINCIDENT) or np.any(axis > D.domain[:, 1] + COINCIDENT):
            dropped += 1
            continue
        spline = BSpline(fs.degrees + (3,), list(fs.knots) + [np.array([0, 0, 0, 0, 1, 1, 1, 1.0])],
                         np.zeros(F.shape[:2] + (4, 3)))
        lam = beta * L / max(float(np.linalg.norm((F - T1).mean((0, 1)))), TINY)
        b = Bridge(spline, D, pi, face, axis, 0.0, F - C, np.stack([F, F + lam * (F - T1)]), owner[choice[i]],
                   float(beta))
        ring = D.evaluate(F.reshape(-1, 3))[:, :3]
        ring = ring - ring.mean(0)
        proj = ring @ np.linalg.svd(ring, full_matrices=False)[2][:2].T  # in the face's principal plane
        b.radius = float(np.abs(proj).max(axis=0).min())  # half the narrower width: inscribed
        out.append(b)
    _snap(out)
    return out, SurfaceCounts(anchoring_faces=len(anchors), built=len(out), dropped=dropped)


def resolve_collisions(bridges: list, max_repel: int = 20) -> tuple[list, Collisions]:
    """Detect and resolve collisions (see the module notes); returns (kept bridges, counts)."""
    counts = Collisions()
    if len(bridges) < 2:
        return bridges, counts
    mids = np.array([axis_samples(b, [0.5])[0] for b in bridges])
    reach = max(float(np.linalg.norm(axis_samples(b, [0.0]) - axis_samples(b, [1.0]))) for b in bridges)
    rmax = max(b.radius for b in bridges)
    pairs = near_pairs(mids, reach + 2 * rmax)  # in a fixed order: collisions are resolved in turn
    alive, moved = np.ones(len(bridges), bool), np.zeros(len(bridges), bool)
    axes = [axis_samples(b) for b in bridges]  # kept current: a bridge that moves is sampled again
    for i, j in pairs:
        if not (alive[i] and alive[j]):
            continue
        a, b = bridges[i], bridges[j]
        dist = closest(axes[i], axes[j])[0]
        need = a.radius + b.radius
        if dist >= need * (1 - 1e-9):
            continue
        counts.collisions += 1
        if _swap_far_ends(a, b, dist):
            counts.swapped += 1
        dist, steps = repel(partial(axis_samples, a), partial(axis_samples, b), _mover(a, b), need, max_repel)
        moved[[i, j]] = True
        axes[i], axes[j] = axis_samples(a), axis_samples(b)
        if dist >= need:
            counts.repelled += int(steps > 0)
            continue
        alive[j] = False
        counts.eliminated += 1
    # the collision tests read the axes only: the far sections follow them once, in one batch per trimming
    # primitive (the winged duck's 180 collisions re-snapped a pair each: 3.3 of its 26 s under a profiler)
    _snap([b for b, ok, m in zip(bridges, alive, moved) if ok and m])
    return [b for b, ok in zip(bridges, alive) if ok], counts


def _swap_far_ends(a: Bridge, b: Bridge, dist: float) -> bool:
    """Swap the two bridges' far ends (and targets) when that separates their axes more; else leave them."""
    a2, b2 = a.axis.copy(), b.axis.copy()
    a.axis[2:], b.axis[2:] = b2[2:].copy(), a2[2:].copy()
    a.target, b.target = b.target, a.target
    # the axes decide (the caller snaps the sections), by a stated margin: a swap that gains only round-off
    # would be taken on one CPU kernel and not on another
    if closest(axis_samples(a), axis_samples(b))[0] > dist + COINCIDENT * max(a.radius + b.radius, dist):
        return True
    a.axis, b.axis = a2, b2
    a.target, b.target = b.target, a.target
    return False


def _mover(a: Bridge, b: Bridge):
    """How surface bridges move apart (:func:`tiling.vrep.repulsion.repel`): the far inner control point
    (the near one keeps the bridge G1 with its tile), or the far end itself, sliding along its surface, when
    the axes come closest near the surface.  A control point moves its axis by less than itself, hence
    twice the step."""
    def move(v, s, ia, ib, pa, pb):
        for bb, sgn, idx, pp in ((a, 1.0, ia, pa), (b, -1.0, ib, pb)):
            if idx >= 0.6 * (len(pp) - 1) and bb.target:
                _retarget(bb, pp[-1] + sgn * 2 * s * v)
            else:
                J = bb.D.jacobian(bb.axis[2:3])[0, :3, :]
                bb.axis[2] = np.clip(bb.axis[2] + np.linalg.solve(J, sgn * 2 * s * v), bb.D.domain[:, 0],
                                     bb.D.domain[:, 1])
    return move
