"""Points of placed patches in bulk: face corners and face samples of thousands of patches at once.

A paving places a few tile splines thousands of times, so the work is one
spline evaluation per (tile spline, face, sample set), one batched matrix
product applying every placement, and one evaluation per outer map.  Patches
are grouped by spline and outer map with
:func:`geometry.grouping.identity_groups`: the ``patches`` list holds every
spline and map for the duration of a call, so no identity can be reused
while it is in use.
"""

from __future__ import annotations

import numpy as np

from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.grouping import identity_groups

__all__ = ["IDENTITY", "placements", "trivariates", "tile_corners", "physical_corners", "face_points"]

#: the placement [A | b] (3, 4) of a patch placed as it is (read-only, shared)
IDENTITY = np.hstack([np.eye(3), np.zeros((3, 1))])
IDENTITY.setflags(write=False)
_FACE_INDEX = {name: i for i, name in enumerate(FACE_NAMES)}


def _face_corner_index() -> np.ndarray:
    """Corner index (i, j, k) -> 4 i + 2 j + k of the 4 corners of each face, in face order (00, 10, 01, 11)."""
    out = np.zeros((6, 4), np.int64)
    for fi, name in enumerate(FACE_NAMES):
        k, side = FACE_AXIS[name]
        rest = [d for d in range(3) if d != k]
        for c, (s_, t_) in enumerate([(0, 0), (1, 0), (0, 1), (1, 1)]):
            ijk = [0, 0, 0]
            ijk[k], ijk[rest[0]], ijk[rest[1]] = side, s_, t_
            out[fi, c] = ijk[0] * 4 + ijk[1] * 2 + ijk[2]
    return out


FACE_CORNERS = _face_corner_index()
# each of the 8 corners once: (face, slot) of its first appearance in FACE_CORNERS
_ONCE = np.array([np.argwhere(FACE_CORNERS == c)[0] for c in range(8)])


def placements(patches, idx) -> np.ndarray:
    """The placements [A | b] (n, 3, 4) of patches ``idx`` (the identity where a patch has none)."""
    if not len(idx):
        return np.zeros((0, 3, 4))
    return np.array([IDENTITY if patches[i].placement is None else patches[i].placement for i in idx], float)


def trivariates(patches) -> np.ndarray:
    """Indices (T,) of the trivariate patches, in order."""
    return np.array([i for i, P in enumerate(patches) if P.spline.dim == 3], np.int64)


def _place(M: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Points (n, m, 3) = placements M (n, 3, 4) applied to points pts (n, m, 3)."""
    return pts @ M[:, :, :3].transpose(0, 2, 1) + M[:, None, :, 3]


def _through_outer(patches, idx, y: np.ndarray, of=None) -> np.ndarray:
    """Placed points y (n, m, 3) mapped by the outer maps of their patches (one evaluation per map).

    Row r of ``y`` belongs to patch ``idx[r]``, or to ``idx[of[r]]`` when ``of`` is given.
    """
    out = y.copy()
    outers = [patches[i].outer for i in idx]
    first, which = identity_groups(outers)
    if of is not None:
        which = which[of]
    order = np.argsort(which, kind="stable")
    bounds = np.searchsorted(which[order], np.arange(len(first) + 1))
    for g, f in enumerate(first):
        D = outers[f]
        if D is None:
            continue
        sel = order[bounds[g]:bounds[g + 1]]
        dom = D.domain
        params = np.clip(y[sel].reshape(-1, 3), dom[:, 0], dom[:, 1])
        out[sel] = D.evaluate(params)[:, :3].reshape(len(sel), y.shape[1], 3)
    return out


def tile_corners(patches):
    """Trivariate patch indices (T,) and their face corners (T, 6, 4, 3) in the placed (outer-parameter) space.

    The corner control points of a clamped spline are its corners: one array
    operation per distinct tile spline, one batched matrix product for all placements.
    """
    idx = trivariates(patches)
    if not len(idx):
        return idx, np.zeros((0, 6, 4, 3))
    splines = [patches[i].spline for i in idx]
    first, which = identity_groups(splines)
    corners = np.stack([splines[f].points[np.ix_([0, -1], [0, -1], [0, -1])].reshape(8, 3) for f in first])
    pts = _place(placements(patches, idx), corners[which])  # (T, 8, 3)
    return idx, pts[:, FACE_CORNERS]


def physical_corners(patches, pidx, fc) -> np.ndarray:
    """Face corners (T, 6, 4, 3) in physical space: ``fc`` of patches ``pidx`` through their outer maps (each
    patch's 8 corners mapped once, not the 24 face corners: every corner is on three faces)."""
    eight = _through_outer(patches, pidx, fc[:, _ONCE[:, 0], _ONCE[:, 1]])  # (T, 8, 3)
    return eight[:, FACE_CORNERS]


def face_points(patches, keys, st, through_outer: bool = True, which=None) -> np.ndarray:
    """Points (len(keys), n, 3) of faces ``keys`` [(patch, face name)], or an (F, 2) int array of (patch, face
    index in FACE_NAMES), at normalised face parameters.

    ``st``: one (n, 2) array for every face, or a list of them, one per face,
    or with ``which`` (len(keys),) sample sets (S, n, 2) of which face j takes
    set ``which[j]``.  Physical points, or with ``through_outer=False`` the placed points in the
    outer map's parameter space.  One tile evaluation per (tile spline, face,
    sample set), one evaluation per outer map.
    """
    K = len(keys)
    if not K:  # the sample count of one set: a list's first, a stack's rows, or the one array's rows
        n = (len(st[0]) if len(st) else 0) if isinstance(st, list) else np.shape(st)[1 if which is not None else 0]
        return np.empty((0, n, 3))
    if which is not None:
        sets, set_of = np.asarray(st, float), np.asarray(which, np.int64)
    elif isinstance(st, list):
        sets, set_of = np.unique(np.stack(st), axis=0, return_inverse=True)
    else:
        sets, set_of = np.asarray(st, float)[None], np.zeros(K, np.int64)
    set_of = set_of.reshape(-1)
    n = sets.shape[1]
    if isinstance(keys, np.ndarray):  # (patch, face index) rows: no tuple per face (a million on large pavings)
        kp, kf = keys[:, 0].astype(np.int64), keys[:, 1].astype(np.int64)
    else:
        kp = np.fromiter((k[0] for k in keys), np.int64, count=K)
        kf = np.fromiter((_FACE_INDEX[k[1]] for k in keys), np.int64, count=K)
    up, of = np.unique(kp, return_inverse=True)  # the distinct patches: faces of one patch share its data
    of = of.reshape(-1)
    spline_of = identity_groups([patches[p].spline for p in up])[1][of]
    group = (spline_of * 6 + kf) * len(sets) + set_of
    _, rep, gidx = np.unique(group, return_index=True, return_inverse=True)
    pts = np.empty((len(rep), n, 3))
    for g, j in enumerate(rep):  # one evaluation per (tile spline, face, sample set)
        s = patches[kp[j]].spline
        k, side = FACE_AXIS[FACE_NAMES[kf[j]]]
        dom = s.domain
        prm = np.empty((n, 3))
        prm[:, k] = dom[k, side]
        samples = sets[set_of[j]]
        for c, d in enumerate([d for d in range(3) if d != k]):
            prm[:, d] = dom[d, 0] + samples[:, c] * (dom[d, 1] - dom[d, 0])
        pts[g] = s.evaluate(prm)[:, :3]
    y = _place(placements(patches, up)[of], pts[gidx.reshape(-1)])
    return _through_outer(patches, up, y, of) if through_outer else y
