"""Closing T-junctions between separately tessellated pieces that share boundary curves.

Two trimmed surfaces that share a trimming curve (the Fig. 7 cylinders of
Elber 2017 along their intersection curves) sample it each on its own: the
vertices of one lie on the other's boundary chords, not on its vertices, so
the welded mesh is open along the curve.  :func:`stitch_boundaries` inserts
every boundary vertex of one piece that lies on a boundary edge of another
(strictly between its ends, within ``tolerance`` of it) into that edge: the
edge's triangle becomes a fan through the inserted vertices, in order along
the edge.  Both sides then carry the union of the two samplings, at the same
points, and weld.  The shape moves by at most ``tolerance`` (a vertex of one
side replaces a point of the other side's chord), which for tessellations is
their chord tolerance.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from geometry.numbers import TINY

__all__ = ["stitch_boundaries"]


def _boundary_edges(tris: np.ndarray):
    """Directed edges used by one triangle only: (a, b, opposite vertex c, triangle), a -> b in its order."""
    a = tris.reshape(-1)
    b = np.roll(tris, -1, axis=1).reshape(-1)
    c = np.roll(tris, -2, axis=1).reshape(-1)
    t = np.repeat(np.arange(len(tris)), 3)
    key = np.sort(np.stack([a, b], 1), axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = counts[inv.ravel()] == 1
    return a[once], b[once], c[once], t[once]


def stitch_boundaries(points: np.ndarray, tris: np.ndarray, part: np.ndarray, tolerance: float,
                      max_passes: int = 4):
    """Insert boundary vertices of each part into the boundary edges of the other parts they lie on.

    ``points`` (N, 3), ``tris`` (T, 3), ``part`` (N,): which piece each vertex belongs to.  Returns
    ``(points, tris, part)`` with the inserted vertices appended (copies, in the receiving part) and the
    receiving triangles fanned; coincident points are left to the caller's weld.
    """
    points, tris, part = np.asarray(points, float), np.asarray(tris, np.int64), np.asarray(part)
    same = 1e-9 * float(np.ptp(points, axis=0).max()) if len(points) else 0.0  # coincident points
    for _ in range(max_passes):
        a, b, c, t = _boundary_edges(tris)
        if not len(a):
            break
        verts = np.unique(np.concatenate([a, b]))
        tree = cKDTree(points[verts])
        mid, half = 0.5 * (points[a] + points[b]), 0.5 * np.linalg.norm(points[b] - points[a], axis=1)
        near = tree.query_ball_point(mid, half + tolerance)
        e = np.repeat(np.arange(len(a)), [len(x) for x in near])
        v = verts[np.fromiter((k for x in near for k in x), dtype=np.int64, count=len(e))]
        d = points[b[e]] - points[a[e]]
        s = np.einsum("ij,ij->i", points[v] - points[a[e]], d) / np.maximum(np.einsum("ij,ij->i", d, d), TINY)
        off = np.linalg.norm(points[a[e]] + s[:, None] * d - points[v], axis=1)
        length = np.linalg.norm(d, axis=1)
        ok = ((part[v] != part[a[e]]) & (off <= tolerance) & (s * length > same)
              & ((1 - s) * length > same))  # (a vertex at an end of the edge is welded, not inserted)
        e, v, s = e[ok], v[ok], s[ok]
        if not len(e):
            break
        # one edge per triangle in a pass (a triangle with two such edges is fanned again in the next pass)
        first = np.full(len(tris), -1)
        np.maximum.at(first, t[e], e)
        keep = first[t[e]] == e
        e, v, s = e[keep], v[keep], s[keep]
        order = np.lexsort((s, e))
        e, v = e[order], v[order]
        new = len(points) + np.arange(len(v))  # copies of the inserted vertices, in the receiving part
        points = np.concatenate([points, points[v]])
        part = np.concatenate([part, part[a[e]]])
        # fan per edge: a, v1, ..., vk, b, each consecutive pair with the opposite vertex c
        edges, starts = np.unique(e, return_index=True)
        chain_start = np.r_[True, e[1:] != e[:-1]]
        prev = np.where(chain_start, a[e], np.r_[0, new[:-1]])
        fan = [np.stack([prev, new, c[e]], 1)]
        last = np.r_[starts[1:], len(e)] - 1
        fan.append(np.stack([new[last], b[edges], c[edges]], 1))
        gone = np.zeros(len(tris), bool)
        gone[t[edges]] = True
        tris = np.concatenate([tris[~gone]] + fan)
    return points, tris, part
