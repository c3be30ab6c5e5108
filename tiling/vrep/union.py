"""Bridging across a trimming surface shared by two primitives of a union (Hong and Elber 2021, Sections 3.4-3.6).

In A u B with A of higher priority, every tile of A is kept and B's tiles
near A are purged (Section 3.4, case 1).  An anchoring face of B whose way
out leaves B's territory *into the model* (into A's) is a *union anchor*:
it is matched, by :func:`tiling.vrep.matching.unbalanced_match` (two Hungarian
stages and GeomFilter, Algorithms 1-2), to the faces of A's tiles that lie
on A's boundary inside B (the anchoring faces on A's side, M_A is kept
whole).  One-to-one matches become cubic Hermite tubes, a face matched twice
the inlet of a bifurcation bridge (a base and two arms,
:mod:`tiling.vrep.tubes`).  Colliding tubes are raised to quintics whose two
inner layers are repelled (Section 3.6), and eliminated if that fails.
Unmatched faces stay open and are counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry.numbers import TINY
from geometry import BSpline
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.patches.multipatch import PlacedPatch, face_points, tile_corners

from ..errors import TilingError
from .matching import unbalanced_match
from .report import UnionCounts
from .repulsion import Collisions, closest, repel
from .fork import bifurcation_base
from .tubes import (are_regular, bridge_patch, carrier, face_of, face_space, hermite_tube, is_regular as _regular,
                    tube_space)
from geometry.grouping import ObjectIndex, near_pairs
from geometry.tolerances import COINCIDENT, same_space

__all__ = ["Fork", "UnionBridges", "union_anchors", "boundary_faces", "shared_faces", "bridge_union"]


@dataclass
class Fork:
    """A two-to-one bifurcation bridge (Section 3.5): the ``inlet`` face, the ``base`` trivariate whose bottom
    is the inlet and whose two ``sides`` (face names) start the two ``arms`` (tubes to the outlets), and the
    base's analysis ``space`` [(knots, degree)] * 3."""

    inlet: object  # tiling.vrep.tubes.Face
    base: BSpline
    sides: tuple
    arms: tuple
    space: list


@dataclass
class UnionBridges:
    """The patches of the union bridges (geometry in space), with counts and, for tests, the pieces:
    ``tubes`` the one-to-one tubes, ``forks`` the two-to-one :class:`Fork` bridges."""

    patches: list = field(default_factory=list)
    tubes: list = field(default_factory=list)
    forks: list = field(default_factory=list)
    counts: UnionCounts = field(default_factory=UnionCounts)


def _centres_and_directions(placed, keys):
    """Physical centres (N, 3) and unit outward directions (N, 3) of patch faces ``keys`` (cheap: no composition)."""
    if not keys:
        return np.zeros((0, 3)), np.zeros((0, 3))
    mid = face_points(placed, keys, np.array([[0.5, 0.5]]), through_outer=False)[:, 0]
    cen = mid.copy()  # the placed centre is the physical one where there is no map
    out = np.zeros((len(keys), 3))
    same = ObjectIndex()  # patches share splines and maps: group by object
    normals: dict = {}  # per (tile spline, face): patches of one tile share it
    by_outer: dict = {}
    for j, (pi, f) in enumerate(keys):
        P = placed[pi]
        key = (same(P.spline), f)
        if key not in normals:
            normals[key] = _tile_normal(P.spline, f)
        v = normals[key]
        out[j] = v if P.placement is None else P.placement[:, :3] @ v
        if P.outer is not None:
            by_outer.setdefault(same(P.outer), (P.outer, []))[1].append(j)
    for D, js in by_outer.values():  # one evaluation (points and Jacobians) per map
        x, J = D.value_and_jacobian(np.clip(mid[js], D.domain[:, 0], D.domain[:, 1]))
        cen[js] = x[:, :3]
        out[js] = np.einsum("nij,nj->ni", J[:, :3, :], out[js])
    return cen, out / np.maximum(np.linalg.norm(out, axis=1), TINY)[:, None]


def _tile_normal(T, face):
    """The outward cross direction of a tile patch face in tile space (mean of control layer 0 - layer 1; the
    axis direction if that vanishes)."""
    k, s = FACE_AXIS[face]
    pts = T.points
    d = (np.take(pts, -1 if s else 0, axis=k) - np.take(pts, -2 if s else 1, axis=k)).reshape(-1, 3).mean(0)
    if np.linalg.norm(d) > 0:
        return d
    e = np.zeros(3)
    e[k] = 1.0 if s else -1.0
    return e


def union_anchors(model, prim, placed, anchors, reach: float):
    """Split ``anchors`` [(patch, face)] of ``prim`` into union anchors {partner primitive name: [(patch, face)]}
    and the rest: a face is a union anchor when the ray out of it leaves ``prim``'s territory within ``reach``
    (model units) into the territory of another positive primitive (the one that tiles beyond)."""
    cen, out = _centres_and_directions(placed, anchors)
    steps = np.linspace(0.05, 1.0, 20) * reach
    rays = cen[:, None] + steps[None, :, None] * out[:, None]  # (N, S, 3)
    flat = rays.reshape(-1, 3)
    mine = prim.contains(flat)
    idx = np.flatnonzero(mine)
    mine[idx] = model.territory(prim, flat[idx])
    mine = mine.reshape(rays.shape[:2])
    left = ~mine
    first = np.where(left.any(1), np.argmax(left, 1), -1)
    partners = {}
    rest = []
    others = [q for q in model.positive() if q is not prim]
    higher = [q for q in others if q.priority > prim.priority]
    negative = [q for q in model.primitives() if q not in model.positive()]
    # faces whose ray leaves into the void (e.g. a face under a purged tile near the other primitive): a union
    # anchor still when the nearest trimming primitive within reach is a positive one of higher priority
    near_pos = np.stack([q.distance(cen) for q in higher]) if higher else np.full((1, len(cen)), np.inf)
    near_neg = np.stack([q.distance(cen) for q in negative]).min(0) if negative else np.full(len(cen), np.inf)
    # who tiles the first point out of prim's territory: the positive primitives, highest priority first
    exits = np.flatnonzero(first >= 0)
    X = rays[exits, first[exits]]
    who = np.full(len(anchors), -1)
    todo = np.arange(len(exits))
    ranked = sorted(others, key=lambda q: -q.priority)
    for g, q in enumerate(ranked):
        if not len(todo):
            break
        hit = q.contains(X[todo])
        if hit.any():
            hit[hit] = model.territory(q, X[todo[hit]])
        who[exits[todo[hit]]] = g
        todo = todo[~hit]
    for i, key in enumerate(anchors):
        owner = None
        if first[i] >= 0:
            owner = ranked[who[i]] if who[i] >= 0 else None
        elif higher:
            g = int(np.argmin(near_pos[:, i]))
            if near_pos[g, i] < min(reach, near_neg[i]):
                owner = higher[g]
        if owner is None:
            rest.append(key)
        else:
            partners.setdefault(owner.name, []).append(key)
    return partners, rest


def boundary_faces(prim, placed, first: int, last: int) -> list:
    """(patch, face) of ``prim``'s kept patches (placed[first:last]) lying on the boundary of its map's domain."""
    sub = placed[first:last]
    pidx, fc = tile_corners(sub)
    dom = prim.D.domain
    tol = COINCIDENT * float(np.abs(dom).max() + 1.0)
    out = []
    for k in range(3):
        for s in (0, 1):
            on = np.all(np.abs(fc[..., k] - dom[k, s]) < tol, axis=-1)  # (T, 6)
            face = 2 * k + s
            out += [(first + int(pidx[t]), FACE_NAMES[face]) for t in np.flatnonzero(on[:, face])]
    return out


def shared_faces(model, q_prim, placed, p_faces) -> list:
    """The faces of ``p_faces`` (on a primitive's boundary) that face into ``q_prim``'s territory."""
    if not p_faces:
        return []
    pc, pd = _centres_and_directions(placed, p_faces)
    probe = pc + pd * 0.05 * _face_size(placed, p_faces, pc)
    inside = q_prim.contains(probe)
    idx = np.flatnonzero(inside)
    inside[idx] = model.territory(q_prim, probe[idx])
    return [f for f, ok in zip(p_faces, inside) if ok]


def bridge_union(model, q_prim, p_prim, placed, q_faces, p_faces, tile: int, d_maxdist=None,
                 beta: float = 0.5, phi: float = 0.0, alpha: float = np.pi / 4) -> UnionBridges:
    """Match ``q_faces`` (union anchors of the lower-priority ``q_prim``) to ``p_faces`` (faces of ``p_prim``'s
    boundary tiles in ``q_prim``'s territory: :func:`shared_faces`) and bridge the matches (module notes)."""
    res = UnionBridges()
    if not p_faces:
        raise TilingError(f"union of {show(q_prim.name)} and {show(p_prim.name)}: {len(q_faces)} anchoring faces of "
                          f"{show(q_prim.name)} face {show(p_prim.name)}, but no tile face of {show(p_prim.name)} lies "
                          f"on its boundary inside {show(q_prim.name)} to match them to; use a tile whose patches "
                          "reach the cell faces")
    _same_face_spaces(placed, q_faces, p_faces, q_prim.name, p_prim.name)
    pc, pd = _centres_and_directions(placed, p_faces)
    qc, qd = _centres_and_directions(placed, q_faces)
    if d_maxdist is None:
        d_maxdist = 4.0 * max(_face_size(placed, q_faces, qc), _face_size(placed, p_faces, pc))
    # the side with more faces is the M side (stage 2 matches its leftovers twice to the other side)
    q_is_m = len(q_faces) >= len(p_faces)
    M = (q_faces, qc, qd) if q_is_m else (p_faces, pc, pd)
    N = (p_faces, pc, pd) if q_is_m else (q_faces, qc, qd)
    names = (q_prim.name, p_prim.name) if q_is_m else (p_prim.name, q_prim.name)
    m = unbalanced_match(M[1], M[2], N[1], N[2], d_maxdist, names=names)
    used = {i for i, _ in m.one_to_one} | {i for arms in m.two_to_one.values() for i in arms}
    _compose(placed, [M[0][i] for i in used] + [N[0][j] for j in {j for _, j in m.one_to_one} | set(m.two_to_one)])
    folded, reduced = _bridge_matches(res, placed, m, M[0], N[0], alpha, beta, phi)
    kept, collisions, refolded = resolve_tube_collisions(res)
    for t in kept["tubes"]:
        res.patches.append(bridge_patch(t.geometry, tube_space(t), tile))
    for f in kept["forks"]:
        res.patches.append(bridge_patch(f.base, f.space, tile))
        for t in f.arms:
            res.patches.append(bridge_patch(t.geometry, tube_space(t), tile))
    res.tubes, res.forks = kept["tubes"], kept["forks"]
    ends = {t.a.key for t in res.tubes} | {t.b.key for t in res.tubes}
    for f in res.forks:
        ends |= {f.inlet.key} | {t.b.key for t in f.arms}
    res.counts = UnionCounts(anchors=len(q_faces), partner_faces=len(p_faces), one_to_one=len(m.one_to_one),
                             two_to_one=len(m.two_to_one), unmatched=len(m.unmatched_m) + len(m.unmatched_n),
                             folded=folded + refolded, forks_reduced=reduced, collisions=collisions, tubes=len(res.tubes),
                             forks=len(res.forks), open_anchors=len(set(q_faces) - ends))
    return res


def _bridge_matches(res: UnionBridges, placed, m, m_faces, n_faces, alpha, beta, phi) -> tuple[int, int]:
    """Tubes for the one-to-one matches and forks for the two-to-one ones (a fork with no room for a base
    becomes one tube to the nearer outlet), appended to ``res``; returns (given up folded, forks reduced)."""
    faces: dict = {}

    def face(key):
        if key not in faces:
            faces[key] = face_of(placed[key[0]], key[1], key)
        return faces[key]

    folded = reduced = 0
    # every match's first tube proven at once (one Bernstein form for all); a folded one tries the others
    ends = [(face(m_faces[i]), face(n_faces[j])) for i, j in m.one_to_one]
    first = [hermite_tube(a, b, min(beta * _BETAS[0], 0.95), phi) for a, b in ends]
    for (a, b), t, ok in zip(ends, first, are_regular([t.geometry for t in first])):
        t = t if ok else _regular_tube(a, b, beta, phi, _BETAS[1:])
        if t is None:
            folded += 1
        else:
            res.tubes.append(t)
    jobs = [(face(n_faces[j]), (face(m_faces[i1]), face(m_faces[i2]))) for j, (i1, i2) in m.two_to_one.items()]
    for (inlet, outs), fork in zip(jobs, _regular_forks(jobs, alpha, beta, phi)):
        if fork is not None:
            res.forks.append(fork)
            continue
        # no room for a base and two arms (e.g. the faces nearly coplanar): one tube to the nearer outlet
        near = min(outs, key=lambda o: float(np.linalg.norm(o.centre - inlet.centre)))
        t = _regular_tube(near, inlet, beta, phi)
        if t is None:
            folded += 1
        else:
            res.tubes.append(t)
            reduced += 1
    return folded, reduced


_BETAS = (1.0, 0.7, 1.4, 0.4)  # tangent-length factors tried before a folded bridge is given up
# (side-angle offset, base height) tried for a folded bifurcation, the paper's alpha first
_SHAPES = ((0.0, 0.5), (np.pi / 12, 0.5), (-np.pi / 12, 0.5), (0.0, 0.25), (np.pi / 6, 0.25), (0.0, 0.8))


def _regular_tube(a, b, beta, phi, factors=_BETAS):
    """The first one-to-one tube from a to b that does not fold, over a few tangent lengths; None if all do."""
    for f in factors:
        t = hermite_tube(a, b, min(beta * f, 0.95), phi)
        if _regular(t.geometry):
            return t
    return None


def _regular_forks(jobs, alpha, beta, phi) -> list:
    """:func:`_regular_fork` of every (inlet, outlets) of ``jobs``, the same forks: the first try of each (the
    first shape's base, then its arms at the first tangent length) built for all and proven in two batches,
    the search one by one only for the forks where one of these folds (the winged duck's 120 forks were
    proven one trivariate at a time: 4.0 of its 15 s under a line profiler)."""
    da, height = _SHAPES[0]
    bases = [bifurcation_base(inlet, outs, float(np.clip(alpha + da, 0.15, 1.45)), phi, height) for inlet, outs in jobs]
    tried = []  # (job, base, space, arms) of the forks whose first base is regular
    for j, ((inlet, outs), (G, split, sides), ok) in enumerate(zip(jobs, bases, are_regular([b[0] for b in bases]))):
        if ok:
            space = [inlet.space[0], inlet.space[1], inlet.space[split]]
            tried.append((j, G, space, [hermite_tube(_base_face(G, side, space), out, min(beta * _BETAS[0], 0.95), phi)
                                        for side, out in zip(sides, outs)]))
    arms_ok = are_regular([t.geometry for *_, arms in tried for t in arms])
    first = {}
    for k, (j, G, space, arms) in enumerate(tried):
        if arms_ok[2 * k] and arms_ok[2 * k + 1]:
            first[j] = Fork(jobs[j][0], G, tuple(bases[j][2]), tuple(arms), space)
    return [first[j] if j in first else _regular_fork(inlet, outs, alpha, beta, phi)
            for j, (inlet, outs) in enumerate(jobs)]


def _regular_fork(inlet, outs, alpha, beta, phi) -> Fork | None:
    """The first bifurcation bridge whose base and arms do not fold, over a few side angles, base heights and
    tangent lengths; None if none."""
    for da, height in _SHAPES:
        G, split, sides = bifurcation_base(inlet, outs, float(np.clip(alpha + da, 0.15, 1.45)), phi, height)
        if not _regular(G):
            continue
        space = [inlet.space[0], inlet.space[1], inlet.space[split]]
        arms = [_regular_tube(_base_face(G, side, space), out, beta, phi) for side, out in zip(sides, outs)]
        if all(a is not None for a in arms):
            return Fork(inlet, G, tuple(sides), tuple(arms), space)
    return None


def _same_face_spaces(placed, q_faces, p_faces, q_name, p_name) -> None:
    """Refuse faces of other spline spaces (:func:`geometry.tolerances.same_space`, in either parameter
    order): bridges meet both ends by identity interfaces (module notes)."""
    faces = [(name, key, face_space(placed[key[0]].spline, key[1]))
             for keys, name in ((q_faces, q_name), (p_faces, p_name)) for key in keys]
    if not faces:
        return
    n1, k1, s1 = faces[0]
    for n2, k2, s2 in faces[1:]:
        if not (same_space(s2, s1) or same_space(s2[::-1], s1)):
            raise TilingError(f"union of {show(q_name)} and {show(p_name)}: the faces to bridge have different spline "
                              f"spaces ({n1!r} patch {k1[0]} {k1[1]}: degrees {[d for _, d in s1]}; {n2!r} patch "
                              f"{k2[0]} {k2[1]}: degrees {[d for _, d in s2]}, knots differ or not); the bridges meet "
                              "both ends by identity interfaces, so give the primitives tiles whose bridged faces "
                              "share one space")


def _compose(placed, keys) -> None:
    """Compose the patches of ``keys`` that are not yet, in one batch per tile patch and map."""
    from geometry.composition.core import compose_many

    same = ObjectIndex()
    groups: dict = {}
    for pi in {k[0] for k in keys}:
        P = placed[pi]
        if not P.is_composed and P.outer is not None and P.placement is not None:
            groups.setdefault((same(P.spline), same(P.outer)), []).append(pi)
    for members in groups.values():
        P0 = placed[members[0]]
        for pi, C in zip(members, compose_many(P0.outer, P0.spline, np.stack([placed[i].placement for i in members]))):
            placed[pi].set_composed(C)


def _face_size(placed, keys, centres) -> float:
    """A typical face diameter (model units): the median distance from a face centre to its first corner."""
    if not keys:
        return 0.0
    corner = face_points(placed, keys[:64], np.array([[0.0, 0.0]]))[:, 0]
    return float(2 * np.median(np.linalg.norm(corner - centres[: len(corner)], axis=1)))


def _base_face(G, side: str, space: list):
    """A side face of a bifurcation base as a :class:`Face` (its outward field from the base's own net)."""
    P = PlacedPatch(carrier(space), None, G)
    P.set_composed(G)
    f = face_of(P, side, ("base", side))
    # the arms leave along the side's normal: a linear base's cross direction runs to the opposite side instead
    out = f.out
    _, J = f.surface.value_and_jacobian(np.array([[0.5, 0.5]]))
    n = np.cross(J[0, :3, 0], J[0, :3, 1])
    n *= np.sign(np.dot(n, out.points.reshape(-1, 3).mean(0))) / np.linalg.norm(n)
    f.out = BSpline(out.degrees, out.knots, np.broadcast_to(n, out.points.shape).copy())
    return f


def _axis_distances(axes: list, pairs: np.ndarray, chunk: int = 512) -> np.ndarray:
    """:func:`tiling.vrep.repulsion.closest`'s distance of every pair (i, j) of ``pairs`` (P, 2) of sampled
    axes (each (n, 3), one n), the same numbers batched: the squared differences summed x, y, z in that
    order (as the norm sums its three terms) and the root of their least (the root is monotone, so it is
    the least root).  Component by component, not as a norm over a last axis of three: 30 -> 3 ms for box
    u cylinder's 1,484 pairs; chunks of 512 pairs keep the differences in cache."""
    if not len(pairs):
        return np.zeros(0)
    A = np.stack(axes)
    comp = [np.ascontiguousarray(A[..., k]) for k in range(3)]
    out = np.empty(len(pairs))
    for s in range(0, len(pairs), chunk):
        i, j = pairs[s:s + chunk, 0], pairs[s:s + chunk, 1]
        sq = None
        for c in comp:
            d = c[i][:, :, None] - c[j][:, None]
            sq = d * d if sq is None else sq + d * d
        out[s:s + chunk] = np.sqrt(sq.min(axis=(1, 2)))
    return out


def resolve_tube_collisions(res: UnionBridges, max_repel: int = 20) -> tuple[dict, Collisions, int]:
    """Collisions between tubes (one-to-one tubes and arms): sampled axes closer than the sum of the inscribed
    radii.  Both tubes of a colliding pair are raised to quintics and their inner layers repelled along
    T1 x T2 (Section 3.6, :func:`tiling.vrep.repulsion.repel`); a pair still colliding after ``max_repel``
    steps loses its later bridge.  Returns (kept tubes and forks, counts, bridges given up because the
    repulsion folded them: a heat model takes regular patches only, so a displaced tube is proved regular
    again, and a fork goes with a folded arm)."""
    items = [("tube", i, t) for i, t in enumerate(res.tubes)]
    items += [("fork", i, arm) for i, f in enumerate(res.forks) for arm in f.arms]
    counts = Collisions()
    dead = {"tube": set(), "fork": set()}
    moved: set = set()
    if len(items) >= 2:
        axes = [t.axis() for _, _, t in items]
        mids = np.array([a[len(a) // 2] for a in axes])
        reach = max(float(np.linalg.norm(a[-1] - a[0])) for a in axes)
        rmax = max(t.radius for _, _, t in items)
        pairs = near_pairs(mids, reach + 2 * rmax)  # in a fixed order: collisions are resolved in turn
        # the candidates' axis distances with the axes as built, all at once (the sequential loop below reads
        # them while neither tube of a pair has moved, and measures again once one has)
        first = _axis_distances(axes, pairs)
        for (i, j), d0 in zip(pairs.tolist(), first.tolist()):
            (ki, ii, a), (kj, jj, b) = items[i], items[j]
            if ii in dead[ki] or jj in dead[kj] or (ki == kj == "fork" and ii == jj):
                continue  # the two arms of one fork meet at their base by construction
            need = a.radius + b.radius
            if (d0 if i not in moved and j not in moved else closest(axes[i], axes[j])[0]) >= need:
                continue
            counts.collisions += 1

            def move(v, s, *_, a=a, b=b):
                a.displace(s * v)
                b.displace(-s * v)

            moved |= {i, j}
            dist, _ = repel(a.axis, b.axis, move, need, max_repel)
            axes[i], axes[j] = a.axis(), b.axis()
            if dist >= need:
                counts.repelled += 1
            else:
                dead[kj].add(jj)
                counts.eliminated += 1
    folded = 0
    shifted = [items[i] for i in sorted(moved) if items[i][1] not in dead[items[i][0]]]
    for (k, ii, _), ok in zip(shifted, are_regular([t.geometry for _, _, t in shifted])):  # proven together
        if not ok:
            dead[k].add(ii)
            folded += 1
    kept = {"tubes": [t for i, t in enumerate(res.tubes) if i not in dead["tube"]],
            "forks": [f for i, f in enumerate(res.forks) if i not in dead["fork"]]}
    return kept, counts, folded
