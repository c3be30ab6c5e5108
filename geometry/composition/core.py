"""Exact functional composition ``outer(inner(.))`` (Elber 2017, Section 2, Eqs. 4-7).

The outer map ``D`` (a surface or a trivariate; usually the trivariate
deformation map) is taken one Bezier piece at a time: every placed inner
patch must lie in one knot span of ``D``, where ``D`` is one polynomial (or
rational) piece, and the composition with that piece is computed exactly:

* :mod:`geometry.composition.bezier` -- the general case, by Bernstein products,
  of degree ``(n_1 + ... + n_D) * m`` per inner direction (Eq. 7);
* :mod:`geometry.composition.boxes` -- axis-aligned boxes (regular pavings of
  box-shaped tile patches): ``D`` restricted to a sub-box, outer degrees kept;
* :mod:`geometry.composition.affine` -- a piece of ``D`` that is affine (a box or
  slab modelled at a higher degree): the inner spline's control points mapped,
  inner degrees kept;
* :mod:`geometry.composition.curves` -- curves crossing knot lines (:func:`compose`
  splits them at the crossings and joins the composed pieces).

Channels: the outer map's channels are composed like its coordinates; the
inner spline's own channels are carried along unaltered (re-expressed in the
result basis).  Result channels = outer.channels + inner.channels.  One
exception to Eq. 7, forced by the mathematics: a *rational* outer map with an
inner spline that carries its own channels needs one extra factor ``W`` (one
extra inner degree ``m``) so that the carried channel shares the result's
denominator; the result degree is then ``(n_1 + ... + n_D + 1) * m``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from functools import partial

import numpy as np

from geometry import knots as kn
from geometry import progress
from geometry.bspline import BSpline
from geometry.composition.affine import affine_images, affine_piece
from geometry.composition.bezier import compose_batch, inner_bezier
from geometry.composition.boxes import axis_aligned, restrict_batch
from geometry.composition.curves import compose_curve_split
from geometry.errors import SplineError
from geometry.grouping import ObjectIndex
from geometry.patches.placed_points import IDENTITY, placements
from geometry.resources import one_blas_thread, usable_cores
from geometry.tolerances import SINGULAR, SNAP

__all__ = ["compose", "compose_many", "compose_placed", "map_points", "result_degrees", "KnotLineCrossing"]


class KnotLineCrossing(SplineError):
    """A placed patch crosses a knot line of the outer map (``placement``, ``direction``, ``line``)."""

    def __init__(self, message, placement: int, direction: int, line: float):
        super().__init__(message)
        self.placement, self.direction, self.line = placement, direction, line


def result_degrees(outer_degrees, inner_degrees) -> tuple[int, ...]:
    """Degrees of ``outer(inner)`` by Eq. (7) of Elber 2017: ``sum(outer_degrees) * m_k``."""
    n = sum(outer_degrees)
    return tuple(n * m for m in inner_degrees)


def _check_pair(outer, inner):
    if not isinstance(outer, BSpline) or not isinstance(inner, BSpline):
        raise SplineError(f"compose() takes two geometry.BSpline objects, got {type(outer).__name__} and "
                          f"{type(inner).__name__}")
    if outer.dim not in (2, 3):
        raise SplineError(f"the outer map must be a surface or a trivariate, got a {outer.dim}-variate spline")
    if outer.dim == 2 and inner.dim == 3:
        raise SplineError("a trivariate cannot be composed into a surface; use a trivariate outer map")
    clash = set(outer.channels) & set(inner.channels)
    if clash:
        raise SplineError(f"outer and inner both define channel(s) {sorted(clash)}; rename one of them")


def finish(outer, inner, degrees, knots, homs, rational) -> list:
    """The composed BSplines, one per coefficient array (n_1, ..., m) of ``homs`` (an array or a list), all on
    ``knots``: from validated-by-construction data (re-validation dominated large pavings), the knots
    checked once."""
    if not len(homs):
        return []
    shape = np.shape(homs[0])[:-1]
    knots = [kn.validate_knots(U, p, n, k) for k, (U, p, n) in enumerate(zip(knots, degrees, shape))]
    channels = outer.channels + inner.channels
    return [BSpline._trusted(degrees, knots, np.ascontiguousarray(h), rational, channels=channels) for h in homs]


def _spans(lo, hi, breaks, tol):
    """Knot span per direction of parameter boxes [lo, hi] (P, D), or -1 where a box crosses a knot line.

    The span is the one holding the box's centre; a box lying on a knot plane
    (zero extent there, e.g. a tile wall on the boundary between two spans)
    takes the span above it, which agrees with the one below on the plane.
    """
    idx = []
    for k, bp in enumerate(breaks):
        mid = 0.5 * (lo[:, k] + hi[:, k])
        i = np.clip(np.searchsorted(bp, mid, side="right") - 1, 0, len(bp) - 2)
        inside = (lo[:, k] >= bp[i] - tol[k]) & (hi[:, k] <= bp[i + 1] + tol[k])
        idx.append(np.where(inside, i, -1))
    return np.stack(idx, axis=1)


def _placements(outer, inner, placements, name):
    P = np.asarray(placements, float)
    if P.ndim != 3 or P.shape[1:] != (3, 4) or not np.all(np.isfinite(P)) or not len(P):
        raise SplineError(f"{name} placements must be a finite, non-empty array of shape (P, 3, 4), got shape "
                          f"{P.shape}")
    if inner.dim == 3:
        det = np.linalg.det(P[:, :, :3])
        scale = np.abs(P[:, :, :3]).max(axis=(1, 2)) ** 3
        flat = ~(np.abs(det) > SINGULAR * scale)
        if flat.any():
            i = int(np.argmax(flat))
            raise SplineError(f"{name} placement {i} is singular (det A = {det[i]:.3g}): it flattens the "
                              "trivariate to a surface or a point; give every placement a non-zero volume")
    return P


def _locate(outer, inner, P, name):
    """(A, b, placed control points, span index (P, D)) with domain and knot-line checks."""
    Do = outer.dim
    A, b = P[:, :Do, :3], P[:, :Do, 3]
    placed = np.einsum("pkj,nj->pnk", A, inner.points.reshape(-1, 3)) + b[:, None, :]
    lo, hi = placed.min(axis=1), placed.max(axis=1)
    dom = outer.domain
    tol = SNAP * (dom[:, 1] - dom[:, 0])
    outside = np.any((lo < dom[:, 0] - tol) | (hi > dom[:, 1] + tol), axis=1)
    if outside.any():
        i = int(np.argmax(outside))
        raise SplineError(
            f"{name} placement {i} reaches parameters {lo[i].tolist()}..{hi[i].tolist()} outside the outer "
            f"domain {dom.tolist()}; scale the placements into the domain"
        )
    breaks = [outer.breakpoints(k) for k in range(Do)]
    where = _spans(lo, hi, breaks, tol)
    crossing = np.any(where < 0, axis=1)
    if crossing.any():
        i = int(np.argmax(crossing))
        k = int(np.argmax(where[i] < 0))
        bp = breaks[k]
        line = float(bp[(bp > lo[i, k] + tol[k]) & (bp < hi[i, k] - tol[k])][0])
        raise KnotLineCrossing(
            f"{name} placement {i} crosses the outer map's knot line {'uvw'[k]} = {line:g} "
            f"(its control points span {lo[i, k]:g}..{hi[i, k]:g}); pave per knot span so no tile crosses a knot "
            "line" + (", or use compose(), which splits curves" if inner.dim == 1 else ""), i, k, line)
    return A, b, placed, where


def compose_many(outer: BSpline, inner: BSpline, placements, name: str = "inner") -> list[BSpline]:
    """Compose ``inner`` placed by each affine map into ``outer``, exactly.

    Parameters
    ----------
    outer : trivariate (or surface) BSpline, the deformation map D.
    inner : BSpline whose coordinates live in the unit cube (the tile patch).
    placements : array (P, 3, 4): ``[A | b]`` mapping tile coordinates ``p``
        to outer parameters ``A p + b`` (only the first ``outer.dim`` rows are
        used for a surface outer map); a trivariate needs det A != 0.

    Every placed patch must lie inside one knot span of ``outer`` (pave per
    span); otherwise :class:`KnotLineCrossing` names the placement and knot line.
    Placements falling into the same Bezier piece of ``outer`` are composed in
    one vectorised batch.

    >>> import numpy as np
    >>> from geometry import BSpline, primitives
    >>> D = primitives.annulus(1.0, 2.0, 1.0)        # a NURBS quarter shell, radii 1 and 2
    >>> tile = primitives.box((0.5, 0.5, 0.5), (0.25, 0.25, 0.25), degrees=(2, 2, 2))
    >>> A = np.hstack([np.eye(3) * 0.5, [[0.0], [0.5], [0.5]]])   # the tile into one octant of D's domain
    >>> [piece] = compose_many(D, tile, A[None])
    >>> t = np.random.default_rng(0).random((100, 3))
    >>> bool(np.allclose(piece.evaluate(t)[:, :3], D.evaluate(tile.evaluate(t)[:, :3] @ A[:, :3].T + A[:, 3])[:, :3]))
    True
    """
    _check_pair(outer, inner)
    P = _placements(outer, inner, placements, name)
    A, b, placed, where = _locate(outer, inner, P, name)
    return _compose_located(outer, inner, A, b, placed, where)


def _compose_located(outer, inner, A, b, placed, where, patches=None) -> list[BSpline]:
    """Compose placements whose knot spans ``where`` (P, D) are known; ``patches``: the outer map's homogeneous
    Bezier pieces when the caller has them (many curve pieces into one map)."""
    Do = outer.dim
    if patches is None:
        patches, _ = outer.bezier_patches(homogeneous=True)
    breaks = [outer.breakpoints(k) for k in range(Do)]
    shape = tuple(len(bp) - 1 for bp in breaks)
    results = [None] * len(A)
    keys = np.ravel_multi_index(where.T, shape)

    def piece(key):
        e = np.unravel_index(key, shape)
        return e, np.array([breaks[k][e[k]] for k in range(Do)]), np.array([breaks[k][e[k] + 1] for k in range(Do)])

    perm, alpha, beta = axis_aligned(inner, placed, Do)
    for key in np.unique(keys[perm[:, 0] >= 0]):  # boxes: the outer map restricted, no products
        e, elo, ehi = piece(key)
        sel = np.nonzero((keys == key) & (perm[:, 0] >= 0))[0]
        for sigma in np.unique(perm[sel], axis=0):
            sub = sel[np.all(perm[sel] == sigma, axis=1)]
            for i, spline in zip(sub, restrict_batch(outer, patches[e], elo, ehi, inner, sigma, alpha[sub],
                                                        beta[sub], finish)):
                results[i] = spline
    todo = np.nonzero(perm[:, 0] < 0)[0]
    todo = _affine_into(outer, inner, A, b, keys[todo], todo, patches, piece, results)
    if not len(todo):
        return results
    bez = inner_bezier(inner)
    # chunks of placements whose result coefficients fill about 1 MiB: the batched products are
    # memory-bound and run faster on cache-sized chunks than in one batch (docs/performance.md)
    size = np.prod([sum(outer.degrees) * m + 1 for m in inner.degrees]) * bez[0].shape[0]
    chunk = int(np.clip((1 << 20) // (8 * outer.homogeneous.shape[-1] * size), 1, 256))
    # placements in different outer pieces share one batch (the factor products do not depend on the
    # piece), in order of their piece
    todo = todo[np.argsort(keys[todo], kind="stable")]

    def run(sel):
        es = [piece(key) for key in keys[sel]]
        Q = np.stack([patches[e] for e, _, _ in es])
        elo, ehi = np.stack([lo for _, lo, _ in es]), np.stack([hi for _, _, hi in es])
        degrees, knots, coefs, rational = compose_batch(Q, outer.is_rational, elo, ehi, inner, A[sel], b[sel], bez)
        for i, spline in zip(sel, finish(outer, inner, degrees, knots, coefs, rational)):
            results[i] = spline

    chunks = [todo[c0 : c0 + chunk] for c0 in range(0, len(todo), chunk)]
    workers = min(usable_cores(), len(chunks))
    # BLAS on one thread, in the pool and without it: its idle threads would spin between the calls of every
    # worker (2.0 -> 1.1 s on Fig. 4(c), 2 cores), and a product's sums split over two threads round
    # differently from one thread's, so the composed coefficients would depend on how many chunks there are
    with one_blas_thread():
        if workers < 2:
            for sel in chunks:
                run(sel)
            return results
        # the chunks on the cores, the compiled products releasing the GIL
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(run, chunks))
    return results


def _affine_into(outer, inner, A, b, keys, todo, patches, piece, results) -> np.ndarray:
    """Compose the placements ``todo`` whose outer piece (``keys``) is affine (:mod:`geometry.composition.affine`)
    into ``results``; returns the others."""
    rest = []
    for key in np.unique(keys):
        sel = todo[keys == key]
        e, lo, hi = piece(key)
        affine = affine_piece(patches[e], lo, hi, outer.is_rational)
        if affine is None:
            rest.append(sel)
            continue
        homs = [affine_images(inner, *affine, A[i], b[i]) for i in sel]
        for i, spline in zip(sel, finish(outer, inner, inner.degrees, inner.knots, homs, inner.is_rational)):
            results[i] = spline
    return np.sort(np.concatenate(rest)) if rest else np.zeros(0, np.int64)


def _compose_curve_piece(outer: BSpline, piece: BSpline, patches=None) -> BSpline:
    """Compose a curve piece whose image lies in one knot span (located from its midpoint, not its hull);
    ``patches``: the outer map's homogeneous Bezier pieces, extracted once for many pieces."""
    Do = outer.dim
    A, b = IDENTITY[None, :Do, :3], IDENTITY[None, :Do, 3]  # inner coordinates are the outer parameters
    placed = piece.points[None, :, :Do]
    mid = piece.evaluate(np.array([[piece.domain[0].mean()]]))[:, :Do]
    breaks = [outer.breakpoints(k) for k in range(Do)]
    where = np.array([[int(np.clip(np.searchsorted(bp, mid[0, k], side="right") - 1, 0, len(bp) - 2))
                       for k, bp in enumerate(breaks)]])
    return _compose_located(outer, piece, A, b, placed, where, patches)[0]


def compose(outer: BSpline, inner: BSpline) -> BSpline:
    """Exact composition ``outer(inner(.))``.

    ``inner``'s first ``outer.dim`` coordinates are parameters of ``outer``.
    Curves, surfaces and trivariates go into a trivariate; curves and surfaces
    into a surface (using the inner x, y).  A curve crossing knot lines of a
    B-spline outer map is split at the crossings and the composed pieces are
    joined into one B-spline (C0 at the joints); a surface or trivariate that
    crosses a knot line raises :class:`KnotLineCrossing`.
    """
    _check_pair(outer, inner)
    try:
        return compose_many(outer, inner, IDENTITY[None])[0]
    except KnotLineCrossing:
        if inner.dim != 1:
            raise
    return compose_curves(outer, [inner])[0]


def compose_curves(outer: BSpline, curves) -> list[BSpline]:
    """``[compose(outer, c) for c in curves]`` with the outer map's Bezier pieces extracted once (curves that
    cross its knot lines are split and joined as in :func:`compose`)."""
    piece = partial(_compose_curve_piece, patches=outer.bezier_patches(homogeneous=True)[0])
    out = []
    for c in curves:  # per curve: its own crossings and pieces
        _check_pair(outer, c)
        out.append(compose_curve_split(outer, c, piece))
    return out


def compose_placed(patches) -> list[BSpline]:
    """The composed images ``outer(A spline + b)`` of placed patches (:class:`geometry.PlacedPatch`), in batches:
    one exact composition per (spline, map) pair for all its placements; results are cached on the patches."""
    same = ObjectIndex()  # patches share splines and maps: group by object
    groups: dict = {}
    for i, p in enumerate(patches):
        if not p.is_composed and p.outer is not None:
            groups.setdefault((same(p.spline), same(p.outer)), []).append(i)
    for members in progress.bar(list(groups.values()), desc="composition", unit="tile patch"):
        first = patches[members[0]]
        A = placements(patches, members)
        for i, r in zip(members, compose_many(first.outer, first.spline, A)):
            patches[i].set_composed(r)
    return [p.composed for p in patches]


def map_points(outer: BSpline, points) -> np.ndarray:
    """Approximate mode for polygonal tiles (Elber 2017, Eq. 3): map vertices through ``outer``.

    ``points``: (N, 3) tile vertices already placed in ``outer``'s parameter
    domain (or (N, 2) for a surface outer map).  Returns (N, 3 + channels) mapped
    vertices.  Unlike :func:`compose` this is *not* exact between vertices:
    edges and faces of the polygons stay straight in Euclidean space and
    continuity is not preserved; refine the mesh to reduce the error.
    """
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] < outer.dim:
        raise SplineError(f"points must have shape (N, {outer.dim}) or (N, 3), got {pts.shape}")
    return outer.evaluate(pts[:, : outer.dim])
