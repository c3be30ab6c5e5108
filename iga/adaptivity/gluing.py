"""Which leaf faces of a :class:`iga.adaptivity.tree.TileRefinement` are glued, and how: equal faces of equal
spaces are identities, a face inside a larger (or, on equal boxes, coarser) one is a branch from the larger, with
the orientation of the roots' interface between them.  Positions are integers at each leaf's depth, so every
decision here is exact."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.faces import FACE_AXIS, face_name
from geometry.patches.multipatch import Interface
from geometry.tolerances import CONSISTENT

__all__ = ["Pair", "inner_pairs", "identity_pairs", "branch_pairs", "interface", "bisected", "MAX_DEPTH"]

#: halvings of a root box at most (positions stay exact in 64-bit keys: 3 x 13 bits)
MAX_DEPTH = 12


def _encode(root, depth, index) -> np.ndarray:
    """One int64 per (root, depth, position): exact keys for lookups (depth <= MAX_DEPTH)."""
    b = MAX_DEPTH + 1
    idx = np.asarray(index, np.int64)
    return ((((np.asarray(root, np.int64) << 5) | np.asarray(depth, np.int64)) << (3 * b))
            | (idx[..., 0] << (2 * b)) | (idx[..., 1] << b) | idx[..., 2])


@dataclass
class Pair:
    """Leaf faces glued: ``a`` the larger (or, on equal faces, coarser) side; ``rect`` where b's face lies on a's,
    in a's normalised face coordinates ((lo, hi), (lo, hi)); ``swap``/``flip`` the orientation a -> b (b's face
    parameters are a's swapped, then reversed per flip: :class:`geometry.Interface`'s convention);
    ``identity``: equal faces of equal spaces; ``root_branch``: across a branch interface of the roots."""

    a: tuple
    b: tuple
    rect: tuple
    swap: bool
    flip: tuple
    identity: bool
    root_branch: bool = False


def finer(L, a: int, b: int) -> bool:
    """Whether leaf a's space is finer than leaf b's on equal boxes: more bisections, or as many and a higher
    degree (the closure then makes the other side at least as fine in both)."""
    return (int(L.level[a]), int(L.elevation[a])) > (int(L.level[b]), int(L.elevation[b]))


def same_space(L, a: int, b: int) -> bool:
    """Whether leaves a and b have the same bisections and degree elevations (equal boxes: an identity)."""
    return int(L.level[a]) == int(L.level[b]) and int(L.elevation[a]) == int(L.elevation[b])


def inner_pairs(L) -> list:
    """Pairs across the split planes inside each root: from each leaf face, the leaf just outside its centre
    at its own depth or coarser (exact integer arithmetic); equal ones once, from the max side."""
    if not (L.depth > 0).any():
        return []
    keys = _encode(L.root, L.depth, L.index)
    order = np.argsort(keys)
    sorted_keys = keys[order]
    out = []
    for k in range(3):
        for side in (0, 1):
            for e in range(int(L.depth.max()) + 1):
                sel = np.flatnonzero(L.depth >= e)
                shift = (L.depth[sel] - e)
                j = L.index[sel] >> shift[:, None]
                if side:
                    j[:, k] = (L.index[sel, k] + 1) >> shift
                else:
                    j[:, k] = -((-L.index[sel, k]) >> shift) - 1
                ok = (j[:, k] >= 0) & (j[:, k] < (1 << e))
                sel, j = sel[ok], j[ok]
                q = _encode(L.root[sel], np.full(len(sel), e), j)
                pos = np.clip(np.searchsorted(sorted_keys, q), 0, len(keys) - 1)
                hit = sorted_keys[pos] == q
                rest = [t for t in range(3) if t != k]
                for b, a in zip(sel[hit].tolist(), order[pos[hit]].tolist()):
                    d, da = int(L.depth[b]), int(L.depth[a])
                    if da == d and not side:
                        continue  # equal faces: once, from the max side
                    fb, fa = face_name(k, side), face_name(k, 1 - side)
                    if da == d and finer(L, a, b):  # equal boxes: the coarser space is the parent
                        out.append(Pair((b, fb), (a, fa), ((0.0, 1.0), (0.0, 1.0)), False, (False, False), False))
                        continue
                    s = 1.0 / (1 << (d - da))
                    rect = tuple((L.index[b, t] * s - L.index[a, t], L.index[b, t] * s - L.index[a, t] + s)
                                 for t in rest)
                    out.append(Pair((a, fa), (b, fb), rect, False, (False, False),
                                     da == d and same_space(L, a, b)))
    return out



def branch_pairs(itf, A, B, domain) -> list:
    """Pairs across a root branch interface: each child leaf face, mapped into the parent face's box, must lie
    in one parent leaf face (else a pair with ``a = (-1, ...)`` asks for the child to be split)."""
    (ia, da, pa, fa), (ib, db, pb, fb) = A, B
    dom = domain
    # the box is a float (a paving's placement), so overlap and containment are decided with a margin of a few
    # times the relative consistency of the constraints (normalised face coordinates are O(1))
    margin = 4 * CONSISTENT
    ka = [t for t in range(3) if t != FACE_AXIS[fa][0]] if fa in FACE_AXIS else [0, 1]
    box = np.array([(np.asarray(itf.box[j], float) - dom[ka[j], 0]) / (dom[ka[j], 1] - dom[ka[j], 0])
                    for j in range(2)])  # the child's face in the parent root's normalised face coordinates
    lo_a = pa / (1 << da)[:, None].astype(float)
    hi_a = (pa + 1) / (1 << da)[:, None].astype(float)
    out = []
    for b, d, p in zip(ib.tolist(), db.tolist(), pb):
        # orientation: the child's face axes run along the parent's after swap / flip (as in the constraints)
        t = [(p[0] / (1 << d), (p[0] + 1) / (1 << d)), (p[1] / (1 << d), (p[1] + 1) / (1 << d))]
        t = [(1 - h, 1 - l) if f else (l, h) for (l, h), f in zip(t, itf.flip)]
        t = t[::-1] if itf.swap else t
        r = np.array([box[j, 0] + np.array(t[j]) * (box[j, 1] - box[j, 0]) for j in range(2)])
        overlap = np.all((np.minimum(hi_a, r[:, 1]) - np.maximum(lo_a, r[:, 0])) > margin, axis=1)
        inside = np.all((lo_a <= r[:, 0] + margin) & (hi_a >= r[:, 1] - margin), axis=1)
        hit = np.flatnonzero(overlap)
        if len(hit) == 1 and inside[hit[0]]:
            a = int(ia[hit[0]])
            size = hi_a[hit[0]] - lo_a[hit[0]]
            rect = tuple(((r[j, 0] - lo_a[hit[0], j]) / size[j], (r[j, 1] - lo_a[hit[0], j]) / size[j])
                         for j in range(2))
            out.append(Pair((a, fa), (b, fb), rect, itf.swap, tuple(itf.flip), False, True))
        else:
            out.append(Pair((-1, fa), (b, fb), ((0, 1), (0, 1)), False, (False, False), False, True))
    return out


def interface(p: Pair, patches) -> Interface:
    """The model interface of a glued pair of leaf faces (a branch's box in the parent leaf's face parameters)."""
    if p.identity:
        return Interface("identity", (int(p.a[0]), p.a[1]), (int(p.b[0]), p.b[1]), p.swap, tuple(p.flip))
    dom = patches[p.a[0]].spline.domain
    ka = [t for t in range(3) if t != FACE_AXIS[p.a[1]][0]] if p.a[1] in FACE_AXIS else [0, 1]
    box = tuple((float(dom[ka[j], 0] + p.rect[j][0] * (dom[ka[j], 1] - dom[ka[j], 0])),
                 float(dom[ka[j], 0] + p.rect[j][1] * (dom[ka[j], 1] - dom[ka[j], 0]))) for j in range(2))
    return Interface("branch", (int(p.a[0]), p.a[1]), (int(p.b[0]), p.b[1]), p.swap, tuple(p.flip), box=box)


def bisected(knots, times: int) -> list:
    """Face knot vectors [(U, p)] with every span bisected ``times`` times (the analysis space's ``refine``)."""
    out = []
    for U, p in knots:
        for _ in range(times):
            b = np.unique(U)
            U = np.sort(np.r_[U, 0.5 * (b[:-1] + b[1:])])
        out.append((U, p))
    return out


def _inverse(swap, flip):
    """The orientation b -> a of an orientation a -> b (and back)."""
    return (True, (flip[1], flip[0])) if swap else (False, tuple(flip))


def _forward(p, d, swap, flip):
    """Dyadic face positions (n, 2) at depths d (n,) of face a, in face b's frame under a -> b."""
    q = p[:, ::-1].copy() if swap else p.copy()
    top = (1 << d) - 1
    for j in range(2):
        if flip[j]:
            q[:, j] = top - q[:, j]
    return q


def identity_pairs(L, A, B, swap, flip) -> list:
    """Pairs across an identity interface of two roots (orientation a -> b ``swap``/``flip``): equal dyadic faces
    are identities, nested ones branches from the larger face."""
    (ia, da, pa, fa), (ib, db, pb, fb) = A, B
    bswap, bflip = _inverse(swap, flip)
    pb_in_a = _forward(pb, db, bswap, bflip)  # b's faces in a's frame
    pa_in_b = _forward(pa, da, swap, flip)
    where_a = {(int(d), int(x), int(y)): int(i) for i, d, (x, y) in zip(ia, da, pa)}
    where_b = {(int(d), int(x), int(y)): int(i) for i, d, (x, y) in zip(ib, db, pb)}
    out = []
    for b, d, (x, y) in zip(ib.tolist(), db.tolist(), pb_in_a.tolist()):
        for e in range(d, -1, -1):
            a = where_a.get((e, x >> (d - e), y >> (d - e)))
            if a is None:
                continue
            s = 1.0 / (1 << (d - e))
            rect = ((x * s - (x >> (d - e)), x * s - (x >> (d - e)) + s), (y * s - (y >> (d - e)), y * s - (y >> (d - e)) + s))
            if e == d and finer(L, a, b):  # equal faces, a finer: b is the parent
                out.append(Pair((b, fb), (a, fa), ((0.0, 1.0), (0.0, 1.0)), bswap, bflip, False))
            else:
                out.append(Pair((a, fa), (b, fb), rect, swap, flip, e == d and same_space(L, a, b)))
            break
    for a, d, (x, y) in zip(ia.tolist(), da.tolist(), pa_in_b.tolist()):
        for e in range(d - 1, -1, -1):
            b = where_b.get((e, x >> (d - e), y >> (d - e)))
            if b is None:
                continue
            s = 1.0 / (1 << (d - e))
            rect = ((x * s - (x >> (d - e)), x * s - (x >> (d - e)) + s), (y * s - (y >> (d - e)), y * s - (y >> (d - e)) + s))
            out.append(Pair((b, fb), (a, fa), rect, bswap, bflip, False))
            break
    return out


