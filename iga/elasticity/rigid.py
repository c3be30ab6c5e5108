"""Rigid-body motions a set of displacement conditions leaves free (refused before an elastic solve).

A rigid motion u(x) = t + w x (x - x0) does no work against the stiffness,
so each connected piece of a model needs Dirichlet components that stop all
six (three translations, three rotations).  The six modes are sampled at the
Greville points of the analysis spaces (exact for the linear functions the
spaces reproduce; close enough elsewhere to count the modes), restricted to
the prescribed DOFs of a piece; the rank deficit of that restriction is the
number of free modes.
"""

from __future__ import annotations

import numpy as np

from geometry.numbers import TINY
from geometry import knots as kn
from geometry.patches.chain import patches_geometry_derivs
from geometry.errors import show
from geometry.grouping import ObjectIndex

from iga.errors import ProblemError, SingularProblemError

__all__ = ["greville_points", "rigid_modes", "free_modes", "three_two_one", "refuse_net_load"]

MODE_NAMES = ("translation along x", "translation along y", "translation along z",
              "rotation about x", "rotation about y", "rotation about z")


def greville_points(model, spaces, offsets) -> np.ndarray:
    """Physical points (ndof, 3) of every scalar DOF: its patch's image of the Greville abscissae (one batched
    evaluation per group of patches sharing a tile spline and a space)."""
    out = np.empty((int(offsets[-1]), 3))
    same = ObjectIndex()
    groups: dict = {}
    for i, s in enumerate(spaces):
        groups.setdefault((s.key(), same(model.patches[i].spline)), []).append(i)
    for members in groups.values():
        space = spaces[members[0]]
        axes = [kn.greville(d.knots, d.degree) for d in space.dirs]
        x, _, _ = patches_geometry_derivs([model.patches[i] for i in members], axes)
        for j, i in enumerate(members):
            out[offsets[i] : offsets[i + 1]] = x[j]
    return out


def rigid_modes(x: np.ndarray, centre=None, size: float | None = None) -> np.ndarray:
    """The six rigid modes (3 N, 6) at points x (N, 3), component-major; rotations about ``centre`` scaled by
    1 / ``size`` so that all six are of unit magnitude."""
    centre = x.mean(0) if centre is None else centre
    y = x - centre
    size = size or max(float(np.abs(y).max()), TINY)
    y = y / size
    n = len(x)
    B = np.zeros((3, n, 6))
    for a in range(3):
        B[a, :, a] = 1.0
    for k, w in enumerate(np.eye(3)):  # w x y for the unit axis w
        B[:, :, 3 + k] = np.cross(np.broadcast_to(w, y.shape), y).T
    return B.reshape(3 * n, 6)


def free_modes(points: np.ndarray, labels: np.ndarray, prescribed: list, pieces: int) -> None:
    """Refuse a piece whose prescribed displacement components leave a rigid motion free.

    ``points`` (ndof, 3) the DOF points; ``labels`` (ndof,) the connected piece of each scalar DOF;
    ``prescribed``: per component a (0, 1, 2) the scalar DOFs with component a prescribed.
    """
    for piece in range(pieces):
        own = labels == piece
        x = points[own]
        centre, size = x.mean(0), max(float(np.ptp(x, axis=0).max()), TINY)
        rows = []
        for a in range(3):
            dofs = prescribed[a][own[prescribed[a]]] if len(prescribed[a]) else prescribed[a]
            if len(dofs):
                rows.append(rigid_modes(points[dofs], centre, size).reshape(3, len(dofs), 6)[a])
        B = np.concatenate(rows) if rows else np.zeros((0, 6))
        sv = np.linalg.svd(B, compute_uv=False) if len(B) else np.zeros(0)
        rank = int(np.sum(sv > 1e-8 * max(sv.max(initial=0.0), TINY)))
        if rank == 6:
            continue
        pure = [MODE_NAMES[m] for m in range(6) if np.linalg.norm(B[:, m]) <= 1e-8 * max(np.sqrt(len(B)), 1.0)]
        named = ", ".join(pure) if pure else "combined motions (rotations about axes through the held points)"
        extra = 6 - rank - len(pure)
        if pure and extra > 0:
            named += f" and {extra} combined motion{'s' if extra > 1 else ''}"
        where = (f"piece {piece} of {pieces} (the one holding scalar DOF {int(np.flatnonzero(own)[0])})" if pieces > 1
                 else "the model")
        raise SingularProblemError(
            f"the displacement conditions leave {6 - rank} rigid-body motion{'s' if 6 - rank > 1 else ''} of "
            f"{where} free: {named}; hold more components (dirichlet(tag, value, components=...)) so that no "
            "translation or rotation is free")


def three_two_one(spaces, offsets, points: np.ndarray) -> list:
    """Per component, the scalar DOFs the 3-2-1 rule of :meth:`iga.ElasticityProblem.hold_rigid` prescribes (to
    zero): all of A, two components of B across AB, one of C across the plane ABC, at patch corners far apart
    (``spaces``, ``offsets``: the analysis spaces and their first DOFs; ``points`` (ndof, 3) the DOFs' points)."""
    corners = []
    for pi, space in enumerate(spaces):
        shape = space.shape
        for i in (0, shape[0] - 1):
            for j in (0, shape[1] - 1):
                for k in (0, shape[2] - 1):
                    corners.append(int(offsets[pi] + (i * shape[1] + j) * shape[2] + k))
    corners = np.unique(corners)
    x = points[corners]
    a = corners[np.argmin(x.sum(1))]
    b = corners[np.argmax(np.linalg.norm(x - points[a], axis=1))]
    ab = points[b] - points[a]
    ab /= np.linalg.norm(ab)
    off = np.linalg.norm(np.cross(x - points[a], ab), axis=1)
    c = corners[np.argmax(off)]
    normal = np.cross(ab, points[c] - points[a])
    if not np.linalg.norm(normal) > 1e-9 * np.ptp(points, axis=0).max():
        raise ProblemError("hold_rigid needs a body that is not flat along a line: no three patch corners span a "
                           "plane")
    across = np.argsort(np.abs(ab))[:2]  # the two axes least along AB
    out = [[a], [a], [a]]
    for comp in across:
        out[comp].append(b)
    out[int(np.argmax(np.abs(normal)))].append(c)
    return [np.array(o, np.int64) for o in out]


def refuse_net_load(applied: dict, body: np.ndarray, moments: dict) -> None:
    """Under :meth:`ElasticityProblem.hold_rigid` the loads must balance: its three pins hold rigid motion only,
    so a net force or moment would be carried by them alone (point reactions, a stress singularity the solution
    does not report).  Refused naming the net force and each load's share (or the net moment of the tractions),
    beyond 1e-9 of the loads' size."""
    forces = [np.asarray(v, float) for v in applied.values()] + [np.asarray(body, float)]
    net = np.sum(forces, axis=0)
    size = sum(float(np.linalg.norm(v)) for v in forces)
    if size > 0 and np.linalg.norm(net) > 1e-9 * size:
        shares = ", ".join(f"{show(tag)} {np.round(np.asarray(v, float), 6).tolist()} N" for tag, v in applied.items())
        if np.any(body):
            shares += f", body force {np.round(np.asarray(body, float), 6).tolist()} N"
        raise ProblemError(f"hold_rigid holds the body against rigid motion only, but its loads add up to a net force "
                           f"of {np.round(net, 6).tolist()} N ({shares}), which the three pins would carry alone; "
                           "support the body with displacement conditions instead, or balance the loads")
    if not np.any(body) and moments:
        M = np.sum([np.asarray(v, float) for v in moments.values()], axis=0)
        msize = sum(float(np.linalg.norm(v)) for v in moments.values())
        if msize > 0 and np.linalg.norm(M) > 1e-9 * msize:
            raise ProblemError(f"hold_rigid holds the body against rigid motion only, but its loads add up to a net "
                               f"moment of {np.round(M, 6).tolist()} N m about the origin, which the three pins would "
                               "carry alone; support the body with displacement conditions instead, or balance the "
                               "loads")
