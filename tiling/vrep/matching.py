"""Matching anchoring faces across a shared trimming surface (Hong and Elber 2021, Section 3.4.1, Algorithms 1-2).

Along a trimming surface shared by two V-cells of a union, the M anchoring
faces on one side and the N on the other are matched, one-to-one and, where
M != N, two-to-one ("bigamy"), by two rounds of the Hungarian assignment
(SciPy's ``linear_sum_assignment``):

* edge weights: the distance between the faces' centres (over ``d_maxdist``:
  invalid) and the angles between the connecting vector and each face's
  bridging direction (90 degrees or more: invalid);
* stage 1 matches up to min(M, N) pairs; among assignments with the most
  valid pairs, the least total weight (invalid edges carry a penalty larger
  than any sum of valid weights, so cardinality comes first);
* stage 2 matches the still unmatched faces of the larger side to the
  smaller side again, without the edges that GeomFilter (Algorithm 2)
  rejects: a second arm at a face must leave, in the plane normal to its
  bridging direction, at 90 degrees or more from the first arm.

Pairs matched at the same face in both stages form a two-to-one match.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from geometry.numbers import TINY

from ..errors import TilingError

__all__ = ["edge_weights", "hungarian", "geom_filter", "unbalanced_match", "Matching"]


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    c = np.sum(a * b, axis=-1) / np.maximum(na * nb, TINY)
    return np.arccos(np.clip(c, -1.0, 1.0))


def edge_weights(Pm, Dm, Pn, Dn, d_maxdist: float, w_dist: float = 1.0, w_angle: float = 1.0) -> np.ndarray:
    """(M, N) weights (np.inf = invalid) between faces at centres ``Pm`` (M, 3) / ``Pn`` (N, 3) with bridging
    directions ``Dm`` / ``Dn``: w_dist |Pi - Pj| / d_maxdist + w_angle (angle_i + angle_j) / pi."""
    Pm, Dm, Pn, Dn = (np.asarray(a, float).reshape(-1, 3) for a in (Pm, Dm, Pn, Dn))
    if not (np.isfinite(d_maxdist) and d_maxdist > 0):
        raise TilingError(f"d_maxdist must be a positive length (model units), got {d_maxdist!r}")
    if not all(np.all(np.isfinite(a)) for a in (Pm, Dm, Pn, Dn)) or not (np.isfinite(w_dist) and np.isfinite(w_angle)):
        raise TilingError("anchoring face centres, directions and weights must be finite numbers (NaN given)")
    if len(Pm) != len(Dm) or len(Pn) != len(Dn):
        raise TilingError("each anchoring face needs one centre and one bridging direction")
    v = Pn[None, :, :] - Pm[:, None, :]  # from V_i to V_j
    dist = np.linalg.norm(v, axis=2)
    ai = _angle(v, Dm[:, None, :])
    aj = _angle(-v, Dn[None, :, :])
    W = w_dist * dist / d_maxdist + w_angle * (ai + aj) / np.pi
    W[(dist > d_maxdist) | (ai >= np.pi / 2) | (aj >= np.pi / 2)] = np.inf
    return W


def hungarian(W: np.ndarray, allowed: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Pairs (i, j) of an assignment with the most valid (finite, allowed) edges and, among those, the least
    total weight."""
    W = np.asarray(W, float)
    valid = np.isfinite(W) if allowed is None else (np.isfinite(W) & allowed)
    if not valid.any():
        return []
    finite = W[valid]
    big = (float(finite.max()) + 1.0) * (min(W.shape) + 1) + float(np.abs(finite).sum())
    C = np.where(valid, W, big)
    rows, cols = linear_sum_assignment(C)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if valid[i, j]]


def geom_filter(Pm, Pn, Dn, candidates: np.ndarray, first: list) -> np.ndarray:
    """Algorithm 2: ``candidates`` (M, N) bool without the edges (i, j) whose projection on the plane normal to
    d_j makes less than 90 degrees with the projection of j's first-stage arm (k, j)."""
    Pm, Pn, Dn = (np.asarray(a, float).reshape(-1, 3) for a in (Pm, Pn, Dn))
    out = np.array(candidates, bool)
    d = Dn / np.linalg.norm(Dn, axis=1)[:, None]
    for k, j in first:
        arm = Pm[k] - Pn[j]
        arm -= np.dot(arm, d[j]) * d[j]
        rel = Pm - Pn[j]
        rel -= (rel @ d[j])[:, None] * d[j]
        out[:, j] &= _angle(rel, np.broadcast_to(arm, rel.shape)) >= np.pi / 2
    return out


@dataclass
class Matching:
    """``first`` and ``second`` stage pairs (i in the M side, j in the N side), ``one_to_one`` the j matched once
    and ``two_to_one`` {j: (i1, i2)}; ``unmatched`` faces of the M side and of the N side."""

    first: list
    second: list
    one_to_one: list
    two_to_one: dict
    unmatched_m: list
    unmatched_n: list


def unbalanced_match(Pm, Dm, Pn, Dn, d_maxdist: float, w_dist: float = 1.0, w_angle: float = 1.0,
                     names=("first side", "second side")) -> Matching:
    """Algorithm 1 for M >= N faces (the sides are swapped internally when M < N; the result keeps the
    caller's sides): stage 1 Hungarian, GeomFilter, stage 2 Hungarian on the unmatched faces."""
    Pm, Dm, Pn, Dn = (np.asarray(a, float).reshape(-1, 3) for a in (Pm, Dm, Pn, Dn))
    for P, name in ((Pm, names[0]), (Pn, names[1])):
        if not len(P):
            raise TilingError(f"matching needs anchoring faces on both sides of the trimming surface; {name} has "
                              "none")
    swap = len(Pm) < len(Pn)
    if swap:
        Pm, Dm, Pn, Dn = Pn, Dn, Pm, Dm
    W = edge_weights(Pm, Dm, Pn, Dn, d_maxdist, w_dist, w_angle)
    first = hungarian(W)
    used = {i for i, _ in first}
    rest = np.array([i not in used for i in range(len(Pm))])
    allowed = geom_filter(Pm, Pn, Dn, rest[:, None] & np.isfinite(W), first)
    second = hungarian(W, allowed)
    twice = {j for _, j in second}
    two = {j: (next(i for i, jj in first if jj == j), i2) for i2, j in second}
    one = [(i, j) for i, j in first if j not in twice]
    um = [i for i in range(len(Pm)) if i not in used and i not in {i for i, _ in second}]
    un = [j for j in range(len(Pn)) if j not in {j for _, j in first}]
    if swap:  # back to the caller's sides: the "two" are then on the caller's first side
        flip = [(j, i) for i, j in first], [(j, i) for i, j in second]
        return Matching(flip[0], flip[1], [(j, i) for i, j in one], {j: arms for j, arms in two.items()}, un, um)
    return Matching(first, second, one, two, um, un)
