"""Sample axes of surface patches that agree where the patches' rims meet (for welded surface meshes).

Surface tiles meet along their rims: the walls of a bifurcation's trunk and
arms, tubes across a level change.  One patch's edge may cover part of
another's or carry other sample points, and triangles that do not share their
edge points leave T-junctions (open edges) inside the mesh.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from geometry.sampling import sample_axes

__all__ = ["conforming_axes"]


def conforming_axes(patches, samples: int, rounds: int = 32) -> dict:
    """Sample axes of the surface patches, made conforming where their edges meet: {patch: [axis 0, axis 1]}.

    Surface tiles meet along their rims (the walls of a bifurcation's trunk and arms, a level change of
    tubes), where one patch's edge may cover part of another's or hold other sample points.  Each patch's
    per-element samples are extended by the parameters of every other patch's edge samples that lie on its
    own edges (in D's parameter domain, where the placed tiles are exact: within 1e-10 of the edge's sample
    polyline, parameter by linear interpolation, exact for straight edges), round after round until no patch
    gains a sample, so the triangles of neighbouring patches share their edge points and weld.  Curved rims
    that meet only partway keep their own samples.
    """
    surf = [i for i, P in enumerate(patches) if P.spline.dim == 2]
    axes = {i: sample_axes(patches[i].spline.knots, samples) for i in surf}
    if len(surf) < 2:
        return axes
    for _ in range(rounds):
        edges = [(i, d, side) + _placed_edge(patches[i], axes[i], d, side) for i in surf for d in (0, 1)
                 for side in (0, 1)]
        pts = np.concatenate([e[3] for e in edges])
        owner = np.concatenate([np.full(len(e[3]), e[0]) for e in edges])
        scale = max(1.0, float(np.ptp(pts, axis=0).max()))
        tree = cKDTree(pts)
        grew = False
        for i, d, _side, y, t in edges:
            seg_lo, seg_hi = y[:-1], y[1:]
            mids = 0.5 * (seg_lo + seg_hi)
            half = 0.5 * np.linalg.norm(seg_hi - seg_lo, axis=1) + 1e-10 * scale
            cand = {j for m, r in zip(mids, half) for j in tree.query_ball_point(m, r)}
            cand = np.array([j for j in cand if owner[j] != i], dtype=np.int64)
            if not len(cand):
                continue
            new = _on_polyline(pts[cand], y, t, 1e-10 * scale)
            have = axes[i][d]
            new = new[np.abs(new[:, None] - have[None, :]).min(axis=1) > 1e-12 * max(1.0, np.ptp(have))]
            if len(new):
                axes[i][d] = np.unique(np.concatenate([have, new]))
                grew = True
        if not grew:
            break
    return axes


def _placed_edge(P, ax, d: int, side: int):
    """The edge of surface patch P along parameter direction d at the ``side`` end of the other direction: its
    sample points in D's parameter domain (placed tile coordinates) and their parameters."""
    o = 1 - d
    t = np.asarray(ax[d], float)
    prm = np.empty((len(t), 2))
    prm[:, d] = t
    prm[:, o] = ax[o][-1] if side else ax[o][0]
    y = P.spline.evaluate(prm)[:, :3]
    if P.placement is not None:
        y = y @ P.placement[:, :3].T + P.placement[:, 3]
    return y, t


def _on_polyline(q: np.ndarray, y: np.ndarray, t: np.ndarray, tol: float) -> np.ndarray:
    """Parameters of the points ``q`` (m, 3) that lie within ``tol`` of the polyline ``y`` (n, 3) sampled at
    parameters ``t`` (n,), interpolated linearly along the segment they lie on."""
    a, b = y[:-1], y[1:]
    ab = b - a
    L2 = np.maximum(np.sum(ab * ab, axis=1), 1e-300)
    s = np.clip(np.einsum("mnk,nk->mn", q[:, None, :] - a[None], ab) / L2[None], 0.0, 1.0)  # (m, segments)
    dist = np.linalg.norm(q[:, None, :] - (a[None] + s[..., None] * ab[None]), axis=2)
    seg = np.argmin(dist, axis=1)
    hit = dist[np.arange(len(q)), seg] <= tol
    s = s[np.arange(len(q)), seg]
    return (t[:-1][seg] + s * np.diff(t)[seg])[hit]
