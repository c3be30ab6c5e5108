"""Offsets of surfaces, approximated by cubic B-splines to a stated tolerance (Elber 2017, Fig. 8).

The offset ``O = S + d n`` of a surface along its unit normal ``n = S_u x S_v / |S_u x S_v|`` is
not a (rational) spline in general.  It is interpolated here on a tensor grid of nodes, a few per
knot span of S and restarted at S's C0 knots (:mod:`geometry.shapes.fitting`), and the grid is refined
until the distance to the exact offset, measured on the grid of the nodes and three check points
between consecutive nodes in each direction, is within 80% of the tolerance.  At the nodes the result is exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.bspline import BSpline
from geometry.errors import SplineError, show
from geometry.shapes.fitting import c0_joints, evaluate, interpolate, span_nodes
from geometry.numbers import is_real

__all__ = ["Offset", "offset", "exact_offset"]

_START, _MAX_NODES = 4, 1 << 16  # nodes in all: the check grid has 16 times as many points
#: the measured error must be within this fraction of the tolerance: the check points are a sample (random
#: points were measured up to 10% above the check points' largest error)
_RESERVE = 0.8


@dataclass
class Offset:
    """An offset surface and what it is measured to be: ``surface`` (bicubic BSpline over S's domain),
    ``distance`` (model units, along S_u x S_v), ``error`` (largest distance to the exact offset at the
    check points, model units; at most 0.8 ``tolerance``)."""

    surface: BSpline
    distance: float
    error: float
    tolerance: float


def exact_offset(S: BSpline, distance: float, params: np.ndarray) -> np.ndarray:
    """``S + distance * n`` at parameters (N, 2): (N, 3); refuses points where the normal is undefined."""
    X, J = S.value_and_jacobian(params)
    n = np.cross(J[:, :3, 0], J[:, :3, 1])
    norm = np.linalg.norm(n, axis=1)
    scale = max(1.0, float(np.abs(X[:, :3]).max()))
    if np.any(norm <= 1e-12 * scale ** 2):
        i = int(np.argmin(norm))
        raise SplineError(f"the surface has no normal at parameters {np.round(params[i], 6).tolist()} (a collapsed "
                          "edge or a fold); offset a surface that is regular everywhere")
    return X[:, :3] + distance * n / norm[:, None]


def offset(S: BSpline, distance: float, tolerance: float | None = None) -> Offset:
    """The offset of the surface ``S`` by ``distance`` (model units, along S_u x S_v; negative: the other side)
    as a bicubic B-spline within ``tolerance`` (model units, default 1e-3 |distance|) of the exact offset.

    >>> from geometry import primitives
    >>> S = primitives.box().boundary("wmax")          # the unit square at z = 1
    >>> o = offset(S, 0.1)
    >>> o.surface.evaluate([[0.3, 0.7]])[0, :3].round(12).tolist(), o.error < 1e-12
    ([0.3, 0.7, 1.1], True)
    """
    if not isinstance(S, BSpline) or S.dim != 2:
        raise SplineError(f"offset needs a BSpline surface, got {show(S)}")
    if not (is_real(distance) and np.isfinite(distance) and distance != 0):
        raise SplineError(f"offset distance must be a non-zero length (model units), got {show(distance)}")
    tol = 1e-3 * abs(distance) if tolerance is None else tolerance
    if not (is_real(tol) and np.isfinite(tol) and tol > 0):
        raise SplineError(f"offset tolerance must be a positive length (model units), got {show(tolerance)}")
    breaks = [S.breakpoints(k) for k in range(2)]
    _check_curvature(S, float(distance), breaks)
    joints = [c0_joints(S.knots[k], S.degrees[k]) for k in range(2)]
    per = [_START, _START]
    while True:
        nodes = [span_nodes(b, p) for b, p in zip(breaks, per)]
        O = exact_offset(S, distance, _grid(nodes)).reshape(len(nodes[0]), len(nodes[1]), 3)
        k, tu, cu = interpolate(nodes[0], O, joints[0])  # along u: (n_cu, n_v, 3)
        _, tv, c = interpolate(nodes[1], np.swapaxes(cu, 0, 1), joints[1])  # then along v: (n_cv, n_cu, 3)
        coef = np.swapaxes(c, 0, 1)
        err = _error(S, distance, k, (tu, tv), coef, nodes)
        if err <= _RESERVE * tol or len(nodes[0]) * len(nodes[1]) * 4 > _MAX_NODES:
            break
        per = [p * 2 for p in per]
    if err > _RESERVE * tol:
        raise SplineError(f"offset: {len(nodes[0])} x {len(nodes[1])} nodes still leave an error of {err:.3g} > "
                          f"tolerance {tol:.3g}; raise the tolerance, or offset less than the surface's radius of "
                          "curvature")
    return Offset(BSpline((k, k), [tu, tv], coef), float(distance), err, float(tol))


CURVATURE_MARGIN = 1e-6
"""The offset X + d n has the Jacobian (I - d W) dX (W the shape operator): it folds where 1 - d k reaches 0 for a
principal curvature k.  ``1 - d k`` must stay above ``CURVATURE_MARGIN`` at every check point."""


def _check_curvature(S: BSpline, distance: float, breaks) -> None:
    """Refuse an offset onto or past a radius of curvature of ``S`` (the offset would fold onto itself),
    naming the parameters, the radius and the side; checked at 16 points per knot span in each direction."""
    P = _grid([span_nodes(b, 16) for b in breaks])
    d = S.derivatives(P, 2)
    Su, Sv = d[(1, 0)][:, :3], d[(0, 1)][:, :3]
    n = np.cross(Su, Sv)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-12 * max(1.0, float(np.abs(d[(0, 0)][:, :3]).max())) ** 2  # no normal: exact_offset refuses
    n = n[ok] / norm[ok, None]
    E, F, G = (np.einsum("ij,ij->i", a[ok], b[ok]) for a, b in ((Su, Su), (Su, Sv), (Sv, Sv)))
    L, M, N = (np.einsum("ij,ij->i", d[k][ok, :3], n) for k in ((2, 0), (1, 1), (0, 2)))
    # principal curvatures: eigenvalues of I^-1 II (n = S_u x S_v / |.|; positive where the surface bends away
    # from n), from det(II - k I) = 0
    a = E * G - F * F
    b = -(E * N + G * L - 2 * F * M)
    c = L * N - M * M
    mean, root = -b / (2 * a), np.sqrt(np.maximum(b * b - 4 * a * c, 0.0)) / (2 * a)
    k = np.stack([mean - root, mean + root], 1)
    fold = 1.0 - distance * k
    i, j = np.unravel_index(int(np.argmin(fold)), fold.shape)
    if fold[i, j] <= CURVATURE_MARGIN:
        uv = np.round(P[np.flatnonzero(ok)[i]], 6).tolist()
        raise SplineError(f"offset distance {show(distance)} reaches the surface's radius of curvature "
                          f"{1.0 / abs(k[i, j]):.6g} at parameters {uv} (on the side the offset goes): the offset "
                          f"would fold onto itself; offset by less than {1.0 / abs(k[i, j]):.6g}")


def _grid(axes) -> np.ndarray:
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)


def _error(S, distance, k, knots, coef, nodes) -> float:
    """The largest distance to the exact offset on the grid of the nodes and three check points between
    consecutive nodes in each direction."""
    fine = [span_nodes(n, 4) for n in nodes]
    cu = evaluate(k, knots[0], coef, fine[0])  # (n_u, n_cv, 3)
    got = np.swapaxes(evaluate(k, knots[1], np.swapaxes(cu, 0, 1), fine[1]), 0, 1).reshape(-1, 3)
    return float(np.linalg.norm(got - exact_offset(S, distance, _grid(fine)), axis=1).max())
