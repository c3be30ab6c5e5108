"""Lower-order approximation of high-degree trivariates (Massarwi et al. 2018, Section 6.3, Fig. 10).

Composition multiplies degrees (a (3, 3, 2) tile in a (1, 1, 2) map gives
(12, 12, 8)); :func:`reduce_degree` approximates such a patch by degree q = 2
or 3, one Bezier piece per knot span, built from the boundary inwards:

* edges: a degree-q Bezier curve through the edge's end points; for q = 3 its
  inner control points reproduce the end tangents (P1 = P0 + C'(0)/3), for
  q = 2 the inner point is the least-squares fit to samples of the edge;
* faces: the four edges, and the inner (q - 1)^2 control points by least
  squares on samples of the face;
* the volume: the six faces, and the inner (q - 1)^3 points by least squares.

Everything on a side depends on that side's exact image only, and the samples
are symmetric, so two patches (or two pieces of one patch) that share a side
get the same approximation of it (to rounding): conforming models stay
conforming and can be analysed as they are.  The pieces are joined C0 (knots
of multiplicity q at the old knots).  The deviation is measured, not bounded
(the paper's scheme gives no bound): the largest distance to the exact patch
on a grid of ``check`` points per direction in every piece.
"""

from __future__ import annotations

from math import comb

import numpy as np

from . import progress
from .bspline import BSpline
from .errors import SplineError, show
from .tolerances import ON_DOMAIN

__all__ = ["reduce_degree", "reduce_model", "deviation"]


def _bernstein(q: int, t: np.ndarray) -> np.ndarray:
    return np.stack([comb(q, j) * t ** j * (1 - t) ** (q - j) for j in range(q + 1)], axis=1)


def _fit_inner(B: np.ndarray, fixed: np.ndarray, samples: np.ndarray, inner) -> np.ndarray:
    """Least-squares values (E, n_inner, m) of the ``inner`` coefficients given the others.

    ``B``: 1-D Bernstein matrix (s, q+1); ``fixed``: (E, (q+1)^d, m) coefficients (the inner
    entries unused); ``samples``: (E, s^d, m) values at the tensor grid of the sample points;
    ``inner``: boolean mask of shape (q+1,)*d.  Grids are flattened in C order.
    """
    M = B
    for _ in range(inner.ndim - 1):
        M = np.kron(M, B)  # (s^d, (q+1)^d), first direction slowest
    mask = inner.ravel()
    rhs = samples - np.einsum("sc,ecm->esm", M[:, ~mask], fixed[:, ~mask, :])
    E, S, m = rhs.shape
    sol = np.linalg.lstsq(M[:, mask], rhs.transpose(1, 0, 2).reshape(S, E * m), rcond=None)[0]
    return sol.reshape(-1, E, m).transpose(1, 0, 2)


def reduce_degree(spline: BSpline, degree: int = 3, check: int = 9) -> tuple[BSpline, float]:
    """Degree-``degree`` approximation (C0 at the old knots) of a trivariate, and its measured deviation.

    Returns ``(reduced, deviation)``: ``deviation`` is the largest distance
    (model units) between the two on ``check`` points per direction in every
    Bezier piece.  Channels are approximated like coordinates.
    """
    if not isinstance(spline, BSpline) or spline.dim != 3:
        raise SplineError(f"reduce_degree approximates trivariate BSplines, got {show(spline)}")
    if not isinstance(degree, (int, np.integer)) or isinstance(degree, (bool, np.bool_)) or degree not in (2, 3):
        raise SplineError(f"the reduced degree must be the integer 2 or 3 (Massarwi et al. 2018, Section 6.3), got {show(degree)}")
    if not isinstance(check, (int, np.integer)) or check < 2:
        raise SplineError(f"check must be an integer >= 2 (points per direction), got {show(check)}")
    q = degree
    m = spline.control_points.shape[-1]
    brk = [spline.breakpoints(k) for k in range(3)]
    boxes = [np.stack([b[:-1], b[1:]], 1) for b in brk]
    ne = [len(b) for b in boxes]
    s = 2 * q + 3  # samples per direction, symmetric about the middle
    t = np.linspace(0.0, 1.0, s)
    B = _bernstein(q, t)

    lo = np.stack(np.meshgrid(*[b[:, 0] for b in boxes], indexing="ij"), -1).reshape(-1, 3)  # (E, 3)
    size = np.stack(np.meshgrid(*[b[:, 1] - b[:, 0] for b in boxes], indexing="ij"), -1).reshape(-1, 3)

    def at(local):  # exact values at local coordinates (..., 3) of every element -> (E, ..., m)
        x = lo[:, None] + local.reshape(-1, 3)[None] * size[:, None]
        return spline.evaluate(x.reshape(-1, 3)).reshape((len(lo),) + local.shape[:-1] + (m,))

    E = int(np.prod(ne))
    C = np.full((E, q + 1, q + 1, q + 1, m), np.nan)
    corner = np.array([0, q])
    # corners
    g = np.stack(np.meshgrid(*[np.array([0.0, 1.0])] * 3, indexing="ij"), -1)
    vals = at(g)
    C[:, corner[:, None, None], corner[None, :, None], corner[None, None, :]] = vals
    _fit_edges(C, at, spline, lo, size, q, t, B)
    _fit_faces(C, at, q, t, B)
    flat = _fit_interior(C, at, q, t, B)
    G = _join_pieces(flat, ne, q, m)
    knots = [np.concatenate([[b[0]] * (q + 1), np.repeat(b[1:-1], q), [b[-1]] * (q + 1)]) for b in brk]
    reduced = BSpline((q,) * 3, knots, G, channels=spline.channels)
    return reduced, deviation(spline, reduced, check)


def _fit_edges(C, at, spline, lo, size, q: int, t, B) -> None:
    """The edge control points of every Bezier piece (C (E, q+1, q+1, q+1, m), filled in place): Hermite
    end derivatives for q = 3, least squares on the samples ``t`` for q = 2."""
    s = len(t)
    # edges: along axis k, at the four corner positions of the other two axes
    for k in range(3):
        o = [j for j in range(3) if j != k]
        for a in (0, 1):
            for b in (0, 1):
                loc = np.zeros((s, 3))
                loc[:, k], loc[:, o[0]], loc[:, o[1]] = t, a, b
                samples = at(loc)  # (E, s, m)
                idx = [slice(None)] * 3
                idx[o[0]], idx[o[1]] = a * q, b * q
                edge = C[(slice(None),) + tuple(idx)]  # (E, q+1, m) along k (a view)
                if q == 3:
                    p0, p3 = samples[:, 0], samples[:, -1]
                    d0 = _edge_derivative(spline, lo, size, k, o, a, b, 0.0)
                    d1 = _edge_derivative(spline, lo, size, k, o, a, b, 1.0)
                    edge[:, 1], edge[:, 2] = p0 + d0 / 3.0, p3 - d1 / 3.0
                else:
                    inner = np.zeros(q + 1, bool)
                    inner[1:-1] = True
                    edge[:, inner] = _fit_inner(B, edge, samples, inner)


def _fit_faces(C, at, q: int, t, B) -> None:
    """The inner (q-1)^2 control points of every face, by least squares on an s x s sample grid (in place)."""
    E, m = C.shape[0], C.shape[-1]
    s = len(t)
    # faces: normal axis k at side c, inner (q-1)^2 points by least squares
    for k in range(3):
        o = [j for j in range(3) if j != k]
        for c in (0, 1):
            loc = np.zeros((s, s, 3))
            loc[..., o[0]], loc[..., o[1]] = np.meshgrid(t, t, indexing="ij")
            loc[..., k] = c
            samples = at(loc)  # (E, s, s, m)
            idx = [slice(None)] * 3
            idx[k] = c * q
            face = C[(slice(None),) + tuple(idx)]  # (E, q+1, q+1, m), axes o[0], o[1]
            inner = np.zeros((q + 1, q + 1), bool)
            inner[1:-1, 1:-1] = True
            flat = face.reshape(E, -1, m)
            flat[:, inner.ravel()] = _fit_inner(B, flat, samples.reshape(E, -1, m), inner)
            C[(slice(None),) + tuple(idx)] = flat.reshape(face.shape)


def _fit_interior(C, at, q: int, t, B):
    """The inner control points of every piece by least squares; returns C viewed as (E, (q+1)^3, m)."""
    E, m = C.shape[0], C.shape[-1]
    # the volume's inner points
    loc = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1)
    samples = at(loc)
    inner = np.zeros((q + 1,) * 3, bool)
    inner[1:-1, 1:-1, 1:-1] = True
    flat = C.reshape(E, -1, m)
    if inner.any():
        flat[:, inner.ravel()] = _fit_inner(B, flat, samples.reshape(E, -1, m), inner)
    return flat


def _join_pieces(flat, ne, q: int, m: int):
    """The control net of the C0 join of the Bezier pieces ``flat`` (E, (q+1)^3, m) on an ne[0] x ne[1] x ne[2]
    grid."""
    # join the pieces (C0 knots of multiplicity q): per direction, every piece's first q layers, then the
    # last piece's last layer; neighbouring pieces share their common side, so the one kept is theirs
    G = flat.reshape(tuple(ne) + (q + 1,) * 3 + (m,)).transpose(0, 3, 1, 4, 2, 5, 6)  # (n0, q0, n1, q1, n2, q2, m)
    for k in range(3):  # the (element, local) pair of direction k sits at axes k, k + 1 (earlier ones merged)
        body = np.take(G, np.arange(q), axis=k + 1)
        body = body.reshape(body.shape[:k] + (-1,) + body.shape[k + 2:])
        last = np.take(np.take(G, [ne[k] - 1], axis=k), q, axis=k + 1)
        G = np.concatenate([body, last], axis=k)
    return G


def _edge_derivative(spline, lo, size, k, o, a, b, tk) -> np.ndarray:
    """d/dt of the patch along axis k (local t in [0, 1]) at the edge point, for every element: (E, m).

    ``lo``, ``size``: the elements' lower corners and sizes (E, 3)."""
    x = lo.copy()
    x[:, k] += tk * size[:, k]
    x[:, o[0]] += a * size[:, o[0]]
    x[:, o[1]] += b * size[:, o[1]]
    orders = tuple(int(j == k) for j in range(3))
    # at a patch's inner knot the one-sided derivative of this element is needed: step inside it
    eps = ON_DOMAIN * size[:, k]
    x[:, k] += np.where(tk == 0.0, eps, -eps)
    return spline.derivative(x, orders) * size[:, k:k + 1]


def deviation(exact: BSpline, approx: BSpline, check: int = 9) -> float:
    """Largest distance (first three components) between two trivariates on ``check``^3 points per piece."""
    brk = [exact.breakpoints(k) for k in range(3)]
    t = np.linspace(0.0, 1.0, check)
    axes = [np.unique((b[:-1, None] + np.diff(b)[:, None] * t[None]).ravel()) for b in brk]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return float(np.linalg.norm(exact.evaluate(x)[:, :3] - approx.evaluate(x)[:, :3], axis=1).max())


def reduce_model(model, degree: int = 3, check: int = 9) -> tuple[list, dict]:
    """Every patch of a model (a :class:`geometry.MultiPatch`: its composed physical geometry) reduced to
    ``degree``; and a report.

    Returns ``(splines, report)``: ``splines`` a list of reduced trivariates (pass it to
    :meth:`geometry.MultiPatch.from_splines` for analysis: sides the model glued stay conforming);
    ``report``: {"deviation" (largest), "deviations" (per patch), "control_points" (before, after),
    "degrees_before"}.
    """
    if not callable(getattr(model, "compose_all", None)):
        raise SplineError(f"reduce_model takes a multi-patch model (a geometry.MultiPatch or tiling.Microstructure), "
                          f"got {type(model).__name__}; for a list of splines use "
                          "geometry.MultiPatch.from_splines(splines), or reduce_degree on each")
    out, devs, before, after, degs = [], [], 0, 0, set()
    for spline in progress.bar(model.compose_all(), desc="degree reduction", unit="patch"):
        r, dev = reduce_degree(spline, degree, check)
        out.append(r)
        devs.append(dev)
        before += int(np.prod(spline.shape))
        after += int(np.prod(r.shape))
        degs.add(spline.degrees)
    return out, {"deviation": max(devs), "deviations": devs, "control_points": (before, after),
                 "degrees_before": sorted(degs)}
