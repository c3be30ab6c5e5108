"""Values and physical gradients of solution fields (one or several components per basis function) on
tensor grids of points, and their integrals by the problem's Gauss rule: shared by the heat and the elastic
solutions and by the VTU sampling."""

from __future__ import annotations

import numpy as np

from geometry.chain import gradient_and_det, patches_geometry_derivs
from geometry.grouping import ObjectIndex

from .errors import ProblemError
from .faces import chunks

__all__ = ["grid_fields", "integrate_fields"]


def grid_fields(U: np.ndarray, tables, D) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Values (P N, c), physical gradients (P N, c, 3) and det J (P N,) of coefficient blocks U (P, c) + shape.

    ``tables``: per direction (values, derivatives), each (points, n) of the 1-D basis at that direction's
    grid points; ``D``: the geometry's parameter derivatives at the P N grid points (C order per patch).
    """
    vals, grads, det = [], [], None
    for a in range(U.shape[1]):
        Ua = U[:, a]
        vals.append(np.einsum("pabc,ia,jb,kc->pijk", Ua, tables[0][0], tables[1][0], tables[2][0],
                              optimize=True).reshape(-1))
        dxi = np.stack([np.einsum("pabc,ia,jb,kc->pijk", Ua, *(tables[d][int(d == k)] for d in range(3)),
                                  optimize=True).reshape(-1) for k in range(3)], -1)
        g, det = gradient_and_det(D, dxi)
        grads.append(g)
    return np.stack(vals, 1), np.stack(grads, 1), det


def integrate_fields(prob, coefficients, components: int, fn) -> float:
    """Sum over the model of int fn(x (N, 3), values (N, c), grads (N, c, 3)) dV by the problem's Gauss rule.

    ``coefficients(i)``: patch i's coefficient block (c,) + space shape; patches sharing a tile spline and
    a space are evaluated together.
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    groups: dict = {}
    for i, s in enumerate(prob.spaces):
        groups.setdefault((s.key(), same(prob.model.patches[i].spline)), []).append(i)
    total = 0.0
    for members in groups.values():
        space = prob.spaces[members[0]]
        tables = [np.swapaxes(d.B[:, :, :-1], 1, 2) for d in space.dirs]  # (2, nq, n): values and derivatives
        w = np.einsum("i,j,k->ijk", *[d.qw for d in space.dirs]).ravel()
        for chunk in chunks(members, components * space.nq_total):
            x, D, _ = patches_geometry_derivs([prob.model.patches[i] for i in chunk], space.qaxes)
            vals, grads, det = grid_fields(np.stack([coefficients(i) for i in chunk]), tables, D)
            if not np.all(np.isfinite(grads)):
                raise ProblemError(f"patches {chunk[0]}..{chunk[-1]}: the geometry Jacobian is singular at a Gauss "
                                   "point; the model is degenerate there")
            wv = np.broadcast_to(w, (len(chunk), len(w))).reshape(-1)
            total += float(np.sum(fn(x.reshape(-1, 3), vals, grads) * np.abs(det) * wv))
    return total
