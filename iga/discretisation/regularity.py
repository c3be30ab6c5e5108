"""Exact proof, before assembly, that every patch of a model is a regular (fold-free) map.

A patch's physical map is x = D(A T(t) + b), so its Jacobian determinant is

    det J(t) = det J_D(A T(t) + b) * det A * det J_T(t),

and it keeps one sign when each factor does: ``det A != 0`` per placement, the
tile patch T proven once per distinct tile spline, and the deformation map D
proven once over its whole domain (cached per map).  Only where D itself is
not provably one-signed is it proven again on each placed patch's parameter
box (the hull of the placed tile's control points, which holds its image).
The proofs use the Bernstein form of the Jacobian determinant
(:func:`geometry.check_regular` with ``allow_zeros``: a determinant that
vanishes on a set of measure zero, such as a collapsed edge, is accepted;
a sign change is a fold).  A fold raises :class:`iga.ProblemError` naming the
patch and the parameter box; an undecided proof is tried again with six more
subdivision rounds (small folds decide there), and one still undecided (a
determinant tangent to zero) is reported in the statistics and left to the
Gauss-point check of the assembly.
"""

from __future__ import annotations

import numpy as np

from geometry.maps.regularity import prove_one_signed, prove_one_signed_many

from iga.errors import ProblemError
from geometry.grouping import ObjectIndex
from geometry.tolerances import SINGULAR

__all__ = ["prove_regular"]

_DEPTH, _DEEPER = 8, 14  # subdivision rounds of each proof, and of a second try where it is undecided


def _proof(spline):
    """The proof of a whole spline (kept by geometry.maps.regularity while the spline lives: a tile or map proven
    once, or a bridge the V-rep builder proved, needs no second proof)."""
    return prove_one_signed(spline, _DEPTH, _DEEPER)


def _boxes(result) -> str:
    b = result.boxes
    hull = np.stack([b[:, :, 0].min(0), b[:, :, 1].max(0)], axis=1)
    return " x ".join(f"{'uvw'[k]} in [{hull[k, 0]:.4g}, {hull[k, 1]:.4g}]" for k in range(hull.shape[0]))


def prove_regular(model) -> dict:
    """Prove every trivariate patch of ``model`` fold-free (see the module notes); returns counts."""
    same = ObjectIndex()  # patches share splines and maps: group by object
    # every distinct tile spline and map proven at once (splines of one kind share one Bernstein form); the
    # loop below reads the proofs, kept per spline object by geometry.maps.regularity
    distinct = {same(s): s for p in model.patches for s in (p.spline, p.outer) if s is not None}
    prove_one_signed_many(list(distinct.values()), _DEPTH, _DEEPER)
    stats = {"tiles_proven": 0, "maps_proven": 0, "boxes_proven": 0, "undecided": []}
    tiles: dict = {}
    maps: dict = {}
    for pi, patch in enumerate(model.patches):
        T = patch.spline
        if same(T) not in tiles:
            r = _proof(T)
            tiles[same(T)] = r
            stats["tiles_proven"] += 1
            _judge(r, stats, f"patch {pi}", "is folded or degenerate", "its own parameters",
                   "fix its control net (geometry.check_regular locates it)")
        if patch.placement is not None:
            A = patch.placement[:, :3]
            det = float(np.linalg.det(A))
            if not abs(det) > SINGULAR * float(np.abs(A).max()) ** 3:
                pts = T.points.reshape(-1, 3) @ A.T + patch.placement[:, 3]
                box = " x ".join(f"{'uvw'[k]} in [{pts[:, k].min():.4g}, {pts[:, k].max():.4g}]" for k in range(3))
                raise ProblemError(f"patch {pi} has a singular placement (det A = {det:.3g}): it flattens the patch "
                                   f"onto the parameter box {box}; give the placement a non-zero volume")
        D = patch.outer
        if D is None:
            continue
        if same(D) not in maps:
            maps[same(D)] = _proof(D)
            stats["maps_proven"] += 1
        if maps[same(D)].status == "regular":
            continue
        M = np.eye(3, 4) if patch.placement is None else patch.placement
        pts = T.points.reshape(-1, 3) @ M[:, :3].T + M[:, 3]
        dom = D.domain
        box = np.stack([np.clip(pts.min(0), dom[:, 0], dom[:, 1]), np.clip(pts.max(0), dom[:, 0], dom[:, 1])], 1)
        if np.any(box[:, 1] <= box[:, 0]):
            continue  # a flat placement: D's one-signed determinant is not needed on a zero-volume box
        r = prove_one_signed(D.extract(box), _DEPTH, _DEEPER)
        stats["boxes_proven"] += 1
        _judge(r, stats, f"patch {pi}", "lies where the deformation map folds or degenerates", "map parameters",
               "fix the map's control net there")
    return stats


def _judge(r, stats, who: str, what: str, frame: str, fix: str) -> None:
    """Refuse a proven fold (naming the parameter box); record an undecided proof."""
    if r.status == "singular":
        raise ProblemError(f"{who} {what}: its Jacobian determinant changes sign or vanishes in {_boxes(r)} "
                           f"({frame}); {fix}")
    if r.status == "undecided":
        stats["undecided"].append(f"{who} ({frame})")
