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

from geometry import progress
from geometry.bspline import BSpline
from geometry.errors import SplineError, show
from geometry.faces import face_knots, nested_refinement
from geometry.numbers import is_integer

__all__ = ["reduce_degree", "reduce_model", "reduced_model", "deviation"]


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
    """Degree-``degree`` approximation (C0 at the old knots, C^-1 where the patch is) of a trivariate, and its
    measured deviation.

    Returns ``(reduced, deviation)``: ``deviation`` is the largest distance
    (model units) between the two on ``check`` points per direction in every
    Bezier piece.  Channels are approximated like coordinates.  Every piece is
    fitted to its own exact Bezier polynomial, so on both sides of a
    discontinuity (an interior knot of full multiplicity: the slots of a
    partial discontinuity, Massarwi et al. 2018, Section 3.1) each piece sees
    its own one-sided limit, and the reduced patch keeps that knot of full
    multiplicity.
    """
    if not isinstance(spline, BSpline) or spline.dim != 3:
        raise SplineError(f"reduce_degree approximates trivariate BSplines, got {show(spline)}")
    if not is_integer(degree) or degree not in (2, 3):
        raise SplineError(f"the reduced degree must be the integer 2 or 3 (Massarwi et al. 2018, Section 6.3), got {show(degree)}")
    if not is_integer(check) or check < 2:
        raise SplineError(f"check must be an integer >= 2 (points per direction), got {show(check)}")
    q = int(degree)
    m = spline.control_points.shape[-1]
    pieces, boxes = spline.bezier_patches(homogeneous=True)
    ne = list(pieces.shape[:3])
    at = _PieceValues(pieces.reshape((-1,) + pieces.shape[3:]), spline.is_rational)
    s = 2 * q + 3  # samples per direction, symmetric about the middle
    t = np.linspace(0.0, 1.0, s)
    B = _bernstein(q, t)
    E = int(np.prod(ne))
    C = np.full((E, q + 1, q + 1, q + 1, m), np.nan)
    corner = np.array([0, q])
    C[:, corner[:, None, None], corner[None, :, None], corner[None, None, :]] = at([[0.0, 1.0]] * 3)
    _fit_edges(C, at, q, t, B)
    _fit_faces(C, at, q, t, B)
    flat = _fit_interior(C, at, q, t, B)
    brk = [spline.breakpoints(k) for k in range(3)]
    cut = [_discontinuous(spline, k, b) for k, b in enumerate(brk)]
    G = _join_pieces(flat, ne, q, m, cut)
    knots = [np.concatenate([[b[0]] * (q + 1), np.repeat(b[1:-1], np.where(c, q + 1, q)), [b[-1]] * (q + 1)])
             for b, c in zip(brk, cut)]
    reduced = BSpline((q,) * 3, knots, G, channels=spline.channels)
    return reduced, deviation(spline, reduced, check)


def _discontinuous(spline: BSpline, k: int, brk: np.ndarray) -> np.ndarray:
    """Which interior breakpoints ``brk[1:-1]`` of direction k are knots of full multiplicity (C^-1)."""
    vals, mult = np.unique(spline.knots[k], return_counts=True)
    full = dict(zip(vals.tolist(), (mult >= spline.degrees[k] + 1).tolist()))
    return np.array([full.get(float(v), False) for v in brk[1:-1]], bool)


class _PieceValues:
    """Values and first derivatives of every Bezier piece on tensor grids of local coordinates in [0, 1]^3
    (exact one-sided limits at the piece's sides: each piece is its own polynomial).

    ``pieces``: (E, p0+1, p1+1, p2+1, m (+1 homogeneous)) Bezier nets, ``rational``: whether the last
    component is the weight.  ``self(axes, axis)``: (E, n0, n1, n2, m) values on the grid of the three 1-D
    local coordinate arrays ``axes``, or with ``axis`` the derivative along that local axis (per unit local
    coordinate); one contraction per direction (sum factorisation).
    """

    def __init__(self, pieces: np.ndarray, rational: bool):
        self.pieces, self.rational = pieces, rational

    def _grid(self, mats) -> np.ndarray:
        H = self.pieces
        for k, M in enumerate(mats):  # contract direction k: (E, ..., p_k+1, ...) -> (E, ..., n_k, ...)
            H = np.moveaxis(np.tensordot(H, M, axes=([k + 1], [1])), -1, k + 1)
        return H

    def __call__(self, axes, axis: int | None = None) -> np.ndarray:
        degs = [n - 1 for n in self.pieces.shape[1:4]]
        Bs = [_bernstein(p, np.asarray(x, float)) for p, x in zip(degs, axes)]
        H = self._grid(Bs)
        if axis is None:
            return H[..., :-1] / H[..., -1:] if self.rational else H
        Bd = list(Bs)
        Bd[axis] = _bernstein_derivative(degs[axis], np.asarray(axes[axis], float))
        dH = self._grid(Bd)
        if not self.rational:
            return dH
        w, dw = H[..., -1:], dH[..., -1:]
        return (dH[..., :-1] - H[..., :-1] / w * dw) / w


def _bernstein_derivative(p: int, t: np.ndarray) -> np.ndarray:
    """d/dt of the degree-p Bernstein polynomials at t: (len(t), p + 1)."""
    if p == 0:
        return np.zeros((len(t), 1))
    low = _bernstein(p - 1, t)
    out = np.zeros((len(t), p + 1))
    out[:, :-1] -= p * low
    out[:, 1:] += p * low
    return out


def _fit_edges(C, at, q: int, t, B) -> None:
    """The edge control points of every Bezier piece (C (E, q+1, q+1, q+1, m), filled in place): Hermite
    end derivatives for q = 3, least squares on the samples ``t`` for q = 2."""
    s = len(t)
    # edges: along axis k, at the four corner positions of the other two axes
    for k in range(3):
        o = [j for j in range(3) if j != k]
        for a in (0, 1):
            for b in (0, 1):
                axes = [None] * 3
                axes[k], axes[o[0]], axes[o[1]] = t, [float(a)], [float(b)]
                idx = [slice(None)] * 3
                idx[o[0]], idx[o[1]] = a * q, b * q
                edge = C[(slice(None),) + tuple(idx)]  # (E, q+1, m) along k (a view)
                if q == 3:
                    axes[k] = [0.0, 1.0]
                    d = at(axes, axis=k).reshape(len(C), 2, -1)  # the piece's own end derivatives
                    edge[:, 1], edge[:, 2] = edge[:, 0] + d[:, 0] / 3.0, edge[:, 3] - d[:, 1] / 3.0
                else:
                    inner = np.zeros(q + 1, bool)
                    inner[1:-1] = True
                    edge[:, inner] = _fit_inner(B, edge, at(axes).reshape(len(C), s, -1), inner)


def _fit_faces(C, at, q: int, t, B) -> None:
    """The inner (q-1)^2 control points of every face, by least squares on an s x s sample grid (in place)."""
    E, m = C.shape[0], C.shape[-1]
    # faces: normal axis k at side c, inner (q-1)^2 points by least squares
    for k in range(3):
        for c in (0, 1):
            axes = [t, t, t]
            axes[k] = [float(c)]
            samples = at(axes)  # (E, s, s, m) with a unit axis k: the grid of the other two axes
            idx = [slice(None)] * 3
            idx[k] = c * q
            face = C[(slice(None),) + tuple(idx)]  # (E, q+1, q+1, m), the other two axes in order
            inner = np.zeros((q + 1, q + 1), bool)
            inner[1:-1, 1:-1] = True
            flat = face.reshape(E, -1, m)
            flat[:, inner.ravel()] = _fit_inner(B, flat, samples.reshape(E, -1, m), inner)
            C[(slice(None),) + tuple(idx)] = flat.reshape(face.shape)


def _fit_interior(C, at, q: int, t, B):
    """The inner control points of every piece by least squares; returns C viewed as (E, (q+1)^3, m)."""
    E, m = C.shape[0], C.shape[-1]
    # the volume's inner points
    samples = at([t, t, t])
    inner = np.zeros((q + 1,) * 3, bool)
    inner[1:-1, 1:-1, 1:-1] = True
    flat = C.reshape(E, -1, m)
    if inner.any():
        flat[:, inner.ravel()] = _fit_inner(B, flat, samples.reshape(E, -1, m), inner)
    return flat


def _join_pieces(flat, ne, q: int, m: int, cut) -> np.ndarray:
    """The control net of the join of the Bezier pieces ``flat`` (E, (q+1)^3, m) on an ne[0] x ne[1] x ne[2]
    grid: C0 (knots of multiplicity q) at the breakpoints, C^-1 (q + 1) where ``cut[k]`` (per direction, one
    flag per interior breakpoint) says so."""
    # per direction, every piece's first q layers, its last layer too where a cut (or the end) follows;
    # across a C0 breakpoint neighbouring pieces share their common side, so the one kept is the next piece's
    G = flat.reshape(tuple(ne) + (q + 1,) * 3 + (m,)).transpose(0, 3, 1, 4, 2, 5, 6)  # (n0, q0, n1, q1, n2, q2, m)
    for k in range(3):  # the (element, local) pair of direction k sits at axes k, k + 1 (earlier ones merged)
        last = np.append(np.asarray(cut[k], bool), True)
        e = np.concatenate([np.repeat(np.arange(ne[k]), q), np.flatnonzero(last)])
        j = np.concatenate([np.tile(np.arange(q), ne[k]), np.full(int(last.sum()), q)])
        order = np.lexsort((j, e))
        merged = G.reshape(G.shape[:k] + (-1,) + G.shape[k + 2:])
        G = np.take(merged, (e * (q + 1) + j)[order], axis=k)
    return G


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


def reduced_model(model, degree: int = 3, check: int = 9):
    """The model with every patch reduced to ``degree`` (:func:`reduce_model`), its topology and tags kept.

    Returns ``(MultiPatch, report)``.  The reduced patches keep their
    parameter domains and their discontinuities, so every identity interface
    of ``model`` holds as it was (its sides are reduced identically, to
    rounding), slot faces keep their rectangles and every tag names the same
    faces: a heat problem is set up on the reduced model with the model's own
    tags.  Branch interfaces get their refinement matrix anew from the reduced
    face spaces; the child's side is an approximation of its own, so the
    report adds ``branch_gap``: the largest distance (model units) between a
    child's branch-in side and the part of the parent's side it is glued to,
    sampled on ``check`` x ``check`` points inside it (0 without branch interfaces).
    """
    from geometry.patches.multipatch import Interface, MultiPatch, PlacedPatch

    splines, report = reduce_model(model, degree, check)
    interfaces, gaps = [], [0.0]
    for itf in model.interfaces:
        if itf.kind != "branch":
            interfaces.append(Interface(itf.kind, itf.a, itf.b, itf.swap, itf.flip))
            continue
        (pa, fa), (pb, fb) = itf.a, itf.b
        try:
            R = nested_refinement(face_knots(splines[pa], fa), itf.box, face_knots(splines[pb], fb))
        except SplineError as exc:
            raise SplineError(f"branch interface of patch {pa} {fa} and patch {pb} {fb} after degree reduction: "
                              f"{exc}") from None
        interfaces.append(Interface("branch", itf.a, itf.b, box=itf.box, R=R))
        gaps.append(_branch_gap(splines[pa].boundary(fa), itf.box, splines[pb].boundary(fb), check))
    out = MultiPatch([PlacedPatch(s, tile=P.tile, level=P.level, patch_in_tile=P.patch_in_tile)
                      for s, P in zip(splines, model.patches)], interfaces,
                     {tag: list(faces) for tag, faces in model.tags.items()}, dict(model.face_regions))
    report["branch_gap"] = max(gaps)
    return out, report


def _branch_gap(parent: BSpline, box, child: BSpline, check: int) -> float:
    """Largest distance between the child's side and the parent side's rectangle ``box`` on a check^2 grid of
    cell centres (inside the rectangle: on its edges the parent may be discontinuous)."""
    t = (np.arange(check) + 0.5) / check
    st = np.stack(np.meshgrid(t, t, indexing="ij"), -1).reshape(-1, 2)
    dc, box = child.domain, np.asarray(box, float)
    xc = child.evaluate(dc[:, 0] + st * (dc[:, 1] - dc[:, 0]))[:, :3]
    xp = parent.evaluate(box[:, 0] + st * (box[:, 1] - box[:, 0]))[:, :3]
    return float(np.linalg.norm(xc - xp, axis=1).max())
