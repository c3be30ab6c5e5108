"""Triangles filling polygons with holes, their boundary kept as given (for caps welded to neighbouring meshes).

:func:`fill_rings` triangulates closed rings (an outer ring and holes, in a
plane) with mapbox-earcut, then refines the interior until no edge off the
rings is longer than ``max_edge``: an edge is split at its midpoint, and
each triangle is split by the number of its split edges (1: into 2, 2: into
3, 3: into 4), so the mesh stays conforming while the ring edges, and hence
the ring points shared with a neighbouring mesh, never change.
"""

from __future__ import annotations

import numpy as np

from .errors import SplineError

__all__ = ["fill_rings"]


def _rotate(tris: np.ndarray, flags: np.ndarray, mids: np.ndarray, shift: np.ndarray):
    """Roll each triangle's vertices (and its edge flags / midpoints) left by ``shift`` (0, 1 or 2)."""
    idx = (np.arange(3)[None, :] + shift[:, None]) % 3
    return (np.take_along_axis(tris, idx, 1), np.take_along_axis(flags, idx, 1), np.take_along_axis(mids, idx, 1))


def fill_rings(rings, max_edge: float, max_passes: int = 40):
    """Triangulate the region bounded by ``rings`` (list of (n_i, 2) vertex arrays, the first the outer
    boundary, the others holes; a ring does not repeat its first point).

    Returns ``(points (N, 2), triangles (T, 3))``; the ring vertices come first, in order and unchanged.
    Interior edges are at most ``max_edge`` long (same units as the points; use at least the longest ring
    edge: an edge from a ring vertex to a point near its ring edge cannot get shorter than that edge);
    ring edges are never split.  Triangles keep the orientation earcut gives them.
    """
    import mapbox_earcut

    rings = [np.asarray(r, float).reshape(-1, 2) for r in rings]
    if not rings or any(len(r) < 3 for r in rings):
        raise SplineError("fill_rings needs rings of at least 3 points")
    if not (np.isfinite(max_edge) and max_edge > 0):
        raise SplineError(f"max_edge must be a positive length, got {max_edge!r}")
    pts = np.concatenate(rings)
    ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
    tris = mapbox_earcut.triangulate_float64(pts, ends).reshape(-1, 3).astype(np.int64)
    if not len(tris):
        raise SplineError("the rings enclose no area (earcut found no triangle)")
    starts = np.r_[0, ends[:-1]].astype(np.int64)
    a = np.arange(len(pts))
    b = np.concatenate([np.roll(np.arange(s, e), -1) for s, e in zip(starts, ends.astype(np.int64))])
    big = np.int64(1) << 32
    fixed = np.sort(np.minimum(a, b) * big + np.maximum(a, b))
    for _ in range(max_passes):
        e = np.sort(np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]], 1), axis=2)  # (T, 3, 2)
        codes = e[..., 0] * big + e[..., 1]
        uniq, inv = np.unique(codes.ravel(), return_inverse=True)
        u0, u1 = uniq // big, uniq % big
        length = np.linalg.norm(pts[u0] - pts[u1], axis=1)
        pos = np.minimum(np.searchsorted(fixed, uniq), len(fixed) - 1)
        split = (length > max_edge) & (fixed[pos] != uniq)
        if not split.any():
            return pts, tris
        new = np.full(len(uniq), -1)
        new[split] = len(pts) + np.arange(int(split.sum()))
        pts = np.concatenate([pts, 0.5 * (pts[u0[split]] + pts[u1[split]])])
        flags = split[inv].reshape(-1, 3)  # per triangle: edges 01, 12, 20 split?
        mids = new[inv].reshape(-1, 3)
        n = flags.sum(1)
        out = [tris[n == 0]]
        # one split edge: roll it to 01; then (t0, m, t2), (m, t1, t2)
        t, f, m = _rotate(tris[n == 1], flags[n == 1], mids[n == 1], np.argmax(flags[n == 1], 1))
        out += [np.stack([t[:, 0], m[:, 0], t[:, 2]], 1), np.stack([m[:, 0], t[:, 1], t[:, 2]], 1)]
        # two split edges: roll the kept one to 20; then (m01, t1, m12), (t0, m01, m12), (t0, m12, t2)
        keep = np.argmin(flags[n == 2], 1)
        t, f, m = _rotate(tris[n == 2], flags[n == 2], mids[n == 2], (keep + 1) % 3)
        out += [np.stack([m[:, 0], t[:, 1], m[:, 1]], 1), np.stack([t[:, 0], m[:, 0], m[:, 1]], 1),
                np.stack([t[:, 0], m[:, 1], t[:, 2]], 1)]
        t, m = tris[n == 3], mids[n == 3]
        out += [np.stack([t[:, 0], m[:, 0], m[:, 2]], 1), np.stack([m[:, 0], t[:, 1], m[:, 1]], 1),
                np.stack([m[:, 2], m[:, 1], t[:, 2]], 1), np.stack([m[:, 0], m[:, 1], m[:, 2]], 1)]
        tris = np.concatenate(out)
    return pts, tris  # valid and conforming; only edges fanning out of a ring vertex may still be longer
