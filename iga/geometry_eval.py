"""Exact geometry of a patch at parameter points: x = D(A T(xi) + b), J = J_D A J_T.

The chain rule is exact and avoids forming the high-degree composed spline
(DESIGN.md, performance note).  Channels are returned by name: tile channels
from ``T``, deformation-map channels from ``D`` at the mapped point.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry import knots as kn
from geometry.spline import _apply_along

from . import ProblemError
from .model import Patch


def _grid_hom(spline, axes, orders):
    out = spline.homogeneous
    for k, ax in enumerate(axes):
        U, p = spline.knots[k], spline.degrees[k]
        ax = np.clip(ax, U[0], U[-1])
        out = _apply_along(out, k, kn.basis_matrix(U, p, ax, orders[k]))
    return out


def grid_values_jacobian(spline, axes):
    """Values (n_1, ..., n_d, m) and Jacobian (..., m, d) on a tensor grid (rational handled)."""
    d = spline.dim
    H = _grid_hom(spline, axes, (0,) * d)
    dH = [_grid_hom(spline, axes, tuple(int(i == k) for i in range(d))) for k in range(d)]
    if spline.is_rational:
        w = H[..., -1:]
        x = H[..., :-1] / w
        J = np.stack([(dh[..., :-1] - x * dh[..., -1:]) / w for dh in dH], axis=-1)
    else:
        x = H
        J = np.stack(dH, axis=-1)
    return x, J


def _outer_map(patch: Patch, xT, JT):
    """Apply the placement and the deformation map to tile values/Jacobians (flat arrays)."""
    A = patch.placement[:, :3] if patch.placement is not None else np.eye(3)
    b = patch.placement[:, 3] if patch.placement is not None else np.zeros(3)
    y = xT[:, :3] @ A.T + b
    JT3 = np.einsum("ij,njk->nik", A, JT[:, :3, :])
    D = patch.outer
    if D is None:
        return y, JT3, {}
    dom = D.domain
    y = np.clip(y, dom[:, 0], dom[:, 1])
    vals = D.evaluate(y)
    JD = D.jacobian(y)
    x = vals[:, :3]
    J = np.einsum("nij,njk->nik", JD[:, :3, :], JT3)
    chans = {c: vals[:, 3 + i] for i, c in enumerate(D.channels)}
    return x, J, chans


def patch_geometry_grid(patch: Patch, axes):
    """Geometry on a tensor grid of patch parameters.

    Returns ``(x, J, channels)``: x (N, 3), J (N, 3, 3), channels {name: (N,)}
    with N = prod(len(axes[k])) in C order.
    """
    xT, JT = grid_values_jacobian(patch.spline, axes)
    m = xT.shape[-1]
    xT = xT.reshape(-1, m)
    JT = JT.reshape(-1, m, 3)
    chans = {c: xT[:, 3 + i] for i, c in enumerate(patch.spline.channels)}
    x, J, outer_chans = _outer_map(patch, xT, JT)
    chans.update(outer_chans)
    return x, J, chans


def patch_geometry_points(patch: Patch, params):
    """Geometry at scattered parameter points (N, 3): (x, J, channels)."""
    params = np.asarray(params, float)
    vals = patch.spline.evaluate(params)
    JT = patch.spline.jacobian(params)
    chans = {c: vals[:, 3 + i] for i, c in enumerate(patch.spline.channels)}
    x, J, outer_chans = _outer_map(patch, vals, JT)
    chans.update(outer_chans)
    return x, J, chans


def checked_det(J, what: str) -> np.ndarray:
    """Jacobian determinants; a sign change or a zero means a singular patch (ProblemError)."""
    det = np.linalg.det(J)
    if not np.all(np.isfinite(det)):
        raise ProblemError(f"{what}: the geometry Jacobian is not finite at some quadrature points")
    if det.size and (det.min() <= 0 < det.max() or np.any(det == 0)):
        raise ProblemError(
            f"{what}: the geometry Jacobian vanishes or changes sign inside the patch (folded or degenerate "
            "geometry); check it with geometry.check_regular"
        )
    return det
