"""Sample axes of surface patches that agree where the patches' rims meet (for welded surface meshes).

Surface tiles meet along their rims: the walls of a bifurcation's trunk and
arms, tubes across a level change.  One patch's edge may cover part of
another's or carry other sample points, and triangles that do not share their
edge points leave T-junctions (open edges) inside the mesh.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from geometry.numbers import TINY
from geometry.grouping import ObjectIndex
from geometry.patches.placed_points import placements
from geometry.patches.sampling import sample_axes

__all__ = ["conforming_axes"]


def conforming_axes(patches, samples: int, rounds: int = 32) -> dict:
    """Sample axes of the surface patches, made conforming where their edges meet: {patch: [axis 0, axis 1]}.

    Surface tiles meet along their rims (the walls of a bifurcation's trunk and arms, a level change of
    tubes), where one patch's edge may cover part of another's or hold other sample points.  Each patch's
    per-element samples are extended by the parameters of every other patch's edge samples that lie on its
    own edges (in D's parameter domain, where the placed tiles are exact: within 1e-10 of the edge's sample
    polyline, parameter by linear interpolation, exact for straight edges), round after round until no patch
    gains a sample, so the triangles of neighbouring patches share their edge points and weld.  Curved rims
    that meet only partway keep their own samples.  Each round evaluates every edge once per tile spline
    and axes (placements applied in a batch) and queries one KD-tree for all segments at once.
    """
    surf = [i for i, P in enumerate(patches) if P.spline.dim == 2]
    axes = {i: sample_axes(patches[i].spline.knots, samples) for i in surf}
    same = ObjectIndex()  # parameter domains of different maps (a two-level structure's) are not one space
    by_map: dict = {}
    for i in surf:
        by_map.setdefault(same(patches[i].outer), []).append(i)
    for members in by_map.values():
        if len(members) > 1:
            _conform(patches, members, axes, rounds)
    return axes


def _conform(patches, surf, axes, rounds) -> None:
    """:func:`conforming_axes` among the surface patches ``surf`` of one map (updates ``axes``)."""
    for _ in range(rounds):
        edges = _placed_edges(patches, surf, axes)  # [(patch, direction, points (n, 3), parameters (n,))]
        pts = np.concatenate([e[2] for e in edges])
        owner = np.concatenate([np.full(len(e[2]), e[0]) for e in edges])
        scale = max(1.0, float(np.ptp(pts, axis=0).max()))
        # every segment of every edge: its ends, parameters and edge
        a = np.concatenate([e[2][:-1] for e in edges])
        b = np.concatenate([e[2][1:] for e in edges])
        t0 = np.concatenate([e[3][:-1] for e in edges])
        t1 = np.concatenate([e[3][1:] for e in edges])
        edge = np.concatenate([np.full(len(e[3]) - 1, k) for k, e in enumerate(edges)])
        near = cKDTree(pts).query_ball_point(0.5 * (a + b), 0.5 * np.linalg.norm(b - a, axis=1) + 1e-10 * scale)
        seg = np.repeat(np.arange(len(a)), [len(n) for n in near])
        q = np.fromiter((j for n in near for j in n), np.int64, len(seg))
        keep = owner[q] != np.array([e[0] for e in edges])[edge[seg]]
        seg, q = seg[keep], q[keep]
        ab = b[seg] - a[seg]
        s_ = np.clip(np.sum((pts[q] - a[seg]) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), TINY), 0, 1)
        on = np.linalg.norm(pts[q] - (a[seg] + s_[:, None] * ab), axis=1) <= 1e-10 * scale
        seg, s_ = seg[on], s_[on]
        param = t0[seg] + s_ * (t1[seg] - t0[seg])
        # a parameter at a sample of its own edge's polyline adds nothing: keep those strictly inside a segment
        inner = (s_ > 1e-9) & (s_ < 1 - 1e-9)
        seg, param = seg[inner], param[inner]
        order = np.argsort(edge[seg], kind="stable")
        ks, starts = np.unique(edge[seg][order], return_index=True)
        grew = False
        for k, part in zip(ks, np.split(param[order], starts[1:])):
            i, d = edges[k][0], edges[k][1]
            have = axes[i][d]
            new = part[np.abs(part[:, None] - have[None, :]).min(axis=1) > 1e-12 * max(1.0, np.ptp(have))]
            if len(new):
                axes[i][d] = np.unique(np.concatenate([have, new]))
                grew = True
        if not grew:
            break


def _placed_edges(patches, surf, axes) -> list:
    """The four edges of every surface patch in D's parameter domain (placed tile coordinates), with their
    parameters: [(patch, direction along the edge, points (n, 3), parameters (n,))]; each edge is evaluated
    once per tile spline and axes, and the placements of the patches that share them applied in one batch."""
    same = ObjectIndex()  # patches share splines: group by object
    groups: dict = {}
    for i in surf:
        key = (same(patches[i].spline), tuple(np.asarray(x).tobytes() for x in axes[i]))
        groups.setdefault(key, []).append(i)
    out = []
    for members in groups.values():
        S, ax = patches[members[0]].spline, axes[members[0]]
        M = placements(patches, members)
        for d in (0, 1):
            t = np.asarray(ax[d], float)
            for side in (0, 1):
                prm = np.empty((len(t), 2))
                prm[:, d] = t
                prm[:, 1 - d] = ax[1 - d][-1] if side else ax[1 - d][0]
                y = S.evaluate(prm)[:, :3]
                placed = np.einsum("pij,nj->pni", M[:, :, :3], y) + M[:, None, :, 3]
                out += [(i, d, placed[j], t) for j, i in enumerate(members)]
    return out
