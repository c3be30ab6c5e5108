"""Triangles filling polygons with holes, their boundary kept as given (for caps welded to neighbouring meshes).

:func:`fill_rings` triangulates closed rings (an outer ring and holes, in a
plane) by VTK's constrained Delaunay triangulation (``vtkDelaunay2D`` with
the rings as constraints; mapbox-earcut only where VTK does not recover
every ring edge, as earcut drops ring vertices between collinear neighbours,
a straight side's samples), then refines the interior until no edge off the
rings is longer than ``max_edge``: an edge is split at its midpoint, and
each triangle is split by the number of its split edges (1: into 2, 2: into
3, 3: into 4), so the mesh stays conforming while the ring edges, and hence
the ring points shared with a neighbouring mesh, never change.  After every
pass, edges that are not locally Delaunay are flipped (Lawson's algorithm,
ring edges fixed), so the mesh stays the constrained Delaunay triangulation
of its points: splitting alone keeps slivers thin, and on a curved surface a
sliver in the parameter plane stands across the surface and adds area that
is not there.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import SplineError

__all__ = ["fill_rings", "delaunay_flips"]


def _rotate(tris: np.ndarray, flags: np.ndarray, mids: np.ndarray, shift: np.ndarray):
    """Roll each triangle's vertices (and its edge flags / midpoints) left by ``shift`` (0, 1 or 2)."""
    idx = (np.arange(3)[None, :] + shift[:, None]) % 3
    return (np.take_along_axis(tris, idx, 1), np.take_along_axis(flags, idx, 1), np.take_along_axis(mids, idx, 1))


def fill_rings(rings, max_edge: float, max_passes: int = 40, max_triangles: int | None = None):
    """Triangulate the region bounded by ``rings`` (list of (n_i, 2) vertex arrays, the first the outer
    boundary, the others holes; a ring does not repeat its first point).  ``max_triangles``: refuse
    (:class:`SplineError`, "more than N triangles") as soon as a refinement pass would exceed it.

    Returns ``(points (N, 2), triangles (T, 3))``; the ring vertices come first, in order and unchanged.
    Interior edges are at most ``max_edge`` long (same units as the points; use at least the longest ring
    edge: an edge from a ring vertex to a point near its ring edge cannot get shorter than that edge);
    ring edges are never split.  Triangles are counter-clockwise in the plane.
    """
    rings = [np.asarray(r, float).reshape(-1, 2) for r in rings]
    if not rings or any(len(r) < 3 for r in rings):
        raise SplineError("fill_rings needs rings of at least 3 points")
    if not (np.isfinite(max_edge) and max_edge > 0):
        raise SplineError(f"max_edge must be a positive length, got {max_edge!r}")
    pts = np.concatenate(rings)
    ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
    starts = np.r_[0, ends[:-1]].astype(np.int64)
    a = np.arange(len(pts))
    b = np.concatenate([np.roll(np.arange(s, e), -1) for s, e in zip(starts, ends.astype(np.int64))])
    big = np.int64(1) << 32
    fixed = np.sort(np.minimum(a, b) * big + np.maximum(a, b))  # the ring edges, as codes
    tris = _constrained_delaunay(rings, fixed)
    if tris is None:  # VTK could not recover every ring edge: earcut (which drops collinear ring vertices)
        import mapbox_earcut

        tris = mapbox_earcut.triangulate_float64(pts, ends).reshape(-1, 3).astype(np.int64)
        flip = _orient(pts, tris) < 0
        tris[flip] = tris[flip][:, ::-1]
    if not len(tris):
        raise SplineError("the rings enclose no area (no triangle fills them)")
    for _ in range(max_passes):
        tris = delaunay_flips(pts, tris, fixed)
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
        if max_triangles is not None and len(tris) > max_triangles:
            raise SplineError(f"filling the rings needs more than {max_triangles:,} triangles at edges of "
                              f"{max_edge:.3g}")
    # valid and conforming; only edges fanning out of a ring vertex may still be longer
    return pts, delaunay_flips(pts, tris, fixed)


def _constrained_delaunay(rings, fixed: np.ndarray):
    """VTK's constrained Delaunay triangulation of the region bounded by ``rings`` (outer first, then holes),
    every ring vertex used and every ring edge (``fixed``, codes as in :func:`delaunay_flips`) kept; None
    where VTK did not recover them all.

    (mapbox-earcut, the first choice for speed, drops every ring vertex between collinear neighbours, a
    straight side's samples, so a neighbouring mesh that uses them would meet T-junctions there.)
    """
    import pyvista as pv

    oriented, start = [], 0
    for i, r in enumerate(rings):
        x, y = r[:, 0], r[:, 1]
        ccw = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
        idx = np.arange(start, start + len(r))
        oriented.append(idx if ccw == (i == 0) else idx[::-1])  # VTK: outer counter-clockwise, holes clockwise
        start += len(r)
    pts = np.concatenate(rings)
    P = np.c_[pts, np.zeros(len(pts))]
    source = pv.PolyData(P, faces=np.concatenate([np.r_[len(o), o] for o in oriented]))
    out = pv.PolyData(P).delaunay_2d(tol=1e-12, edge_source=source)
    if out.n_points != len(pts) or not out.n_cells:
        return None
    tris = out.faces.reshape(-1, 4)[:, 1:].astype(np.int64)
    big = np.int64(1) << 32
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    have = np.unique(e[:, 0] * big + e[:, 1])
    if len(np.unique(tris)) != len(pts) or not np.all(np.isin(fixed, have)):
        return None
    flip = _orient(pts, tris) < 0  # VTK's triangles come in either orientation
    tris[flip] = tris[flip][:, ::-1]
    return tris


def _orient(p, tris):
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def delaunay_flips(pts: np.ndarray, tris: np.ndarray, fixed: np.ndarray, max_passes: int = 200) -> np.ndarray:
    """Flip interior edges of a planar triangulation until every edge not in ``fixed`` is locally Delaunay.

    ``fixed``: sorted edge codes ``min * 2^32 + max`` that must stay (the rings).  Each pass flips, at once,
    a set of violating edges no two of which share a triangle (the most violating edge of each triangle
    wins); a flip is made only where both new triangles keep the mesh's orientation, so the result is a
    valid triangulation of the same points with the same boundary.  Returns the new triangles.
    """
    big = np.int64(1) << 32
    tris = np.asarray(tris, np.int64).copy()
    area = _orient(pts, tris)
    flip_back = np.sum(area) < 0  # work counter-clockwise, hand back the given orientation
    if flip_back:
        tris = tris[:, ::-1].copy()
    scale = float(np.ptp(pts, axis=0).max()) or 1.0
    # Lawson's active set: only an edge of a triangle changed in the last pass, or a violating edge that lost
    # the last pass's contest, can need a flip; the others keep their verdict
    active = np.ones(len(tris), bool)
    for _ in range(max_passes):
        e0, e1, opp = tris, np.roll(tris, -1, axis=1), np.roll(tris, -2, axis=1)  # edge k = (k, k+1), opposite k+2
        codes = (np.minimum(e0, e1) * big + np.maximum(e0, e1)).ravel()
        order = np.argsort(codes, kind="stable")
        sc = codes[order]
        pair = np.flatnonzero(sc[1:] == sc[:-1])
        pair = pair[active[order[pair] // 3] | active[order[pair + 1] // 3]]
        pos = np.minimum(np.searchsorted(fixed, sc[pair]), max(len(fixed) - 1, 0))
        pair = pair[fixed[pos] != sc[pair]] if len(fixed) else pair
        if not len(pair):
            break
        i1, i2 = order[pair], order[pair + 1]
        t1, k1 = np.divmod(i1, 3)
        t2, k2 = np.divmod(i2, 3)
        a, b, c, d = e0[t1, k1], e1[t1, k1], opp[t1, k1], opp[t2, k2]
        val = _incircle(pts[a], pts[b], pts[c], pts[d]) / scale ** 4
        new1, new2 = np.stack([a, d, c], 1), np.stack([d, b, c], 1)
        ok = (val > 1e-12) & (_orient(pts, new1) > 1e-14 * scale ** 2) & (_orient(pts, new2) > 1e-14 * scale ** 2)
        if not ok.any():
            break
        cand = np.flatnonzero(ok)
        rank = np.empty(len(cand), np.int64)
        rank[np.argsort(val[cand])] = np.arange(len(cand))  # distinct priorities, most violating highest
        best = np.full(len(tris), -1, np.int64)
        np.maximum.at(best, t1[cand], rank)
        np.maximum.at(best, t2[cand], rank)
        won = (best[t1[cand]] == rank) & (best[t2[cand]] == rank)
        win = cand[won]
        tris[t1[win]], tris[t2[win]] = new1[win], new2[win]
        active = np.zeros(len(tris), bool)
        active[t1[cand]] = True  # the flipped pairs and the violating edges that lost this pass's contest
        active[t2[cand]] = True
    return tris[:, ::-1].copy() if flip_back else tris


def _incircle(a, b, c, d) -> np.ndarray:
    """Positive where d lies inside the circle through the counter-clockwise triangle (a, b, c)."""
    ad, bd, cd = a - d, b - d, c - d
    return (np.einsum("ij,ij->i", ad, ad) * (bd[:, 0] * cd[:, 1] - bd[:, 1] * cd[:, 0])
            - np.einsum("ij,ij->i", bd, bd) * (ad[:, 0] * cd[:, 1] - ad[:, 1] * cd[:, 0])
            + np.einsum("ij,ij->i", cd, cd) * (ad[:, 0] * bd[:, 1] - ad[:, 1] * bd[:, 0]))
