"""Trimmed B-spline surfaces: a surface and closed trimming loops in its parameter domain (Elber 2017, Fig. 7).

A :class:`TrimmedSurface` keeps the tensor-product surface S and its loops,
B-spline curves (u(t), v(t)) in S's parameter domain: the first loop bounds
the kept region (made counter-clockwise), the others are holes (made
clockwise).  Composition into a map D is exact for the tensor-product part,
``compose(D, S)``, while the loops are carried unaltered (they live in S's
parameters, which composition keeps); the loops' images in space are the
exact compositions ``S(loop)`` (:meth:`TrimmedSurface.boundary_curves`).

Tessellation (:meth:`TrimmedSurface.tessellate`): every loop is sampled
until the chord between consecutive samples deviates from the curve's image
by less than the tolerance and no two samples are more than h apart in the
parameter plane; the polygon with holes is triangulated there by
:func:`geometry.shapes.triangulate.fill_rings` (VTK's constrained Delaunay
triangulation, which keeps the loop edges; Shewchuk's ``triangle`` was not
taken, its licence forbids commercial use without permission; interior
edges are then split at their midpoints down to h and flipped to Delaunay,
so no triangle folds over or stands across the surface as a sliver), and h
shrinks until every edge's midpoint lies within the tolerance of the
surface (the loops' samples of one pass are refined in the next).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry.bspline import BSpline
from geometry.composition.core import compose
from geometry.errors import SplineError, show
from geometry.patches.sampling import sample_axes
from geometry.resources import check_memory
from geometry.tolerances import ON_DOMAIN, ROUNDOFF, SNAP
from geometry.numbers import TINY, is_real

__all__ = ["TrimmedSurface", "reversed_curve", "join_curves", "loop_polyline", "inside_polyline"]

_LOOP_SAMPLES = 64  # per knot span, for the validity checks


def reversed_curve(c: BSpline) -> BSpline:
    """The same curve traversed backwards over the same parameter interval."""
    (U,), (p,) = c.knots, c.degrees
    a, b = U[0], U[-1]
    w = None if c.weights is None else c.weights[::-1].copy()
    return BSpline((p,), [(a + b) - U[::-1]], c.control_points[::-1].copy(), w, c.channels)


def join_curves(curves, tol: float = 1e-9) -> BSpline:
    """One curve through ``curves`` end to start, C0 at the joints: curve i runs over [i, i + 1].

    Degrees are raised to the highest; rational pieces keep their shape (weights rescaled so the joint
    weights agree).  Raises :class:`SplineError` where a curve does not start where the previous one ends.
    """
    curves = list(curves)
    if not curves or not all(isinstance(c, BSpline) and c.dim == 1 for c in curves):
        raise SplineError("join_curves needs a non-empty list of B-spline curves")
    p = max(c.degrees[0] for c in curves)
    rational = any(c.is_rational for c in curves)
    knots, pts, wts = [np.zeros(p + 1)], [], []
    for i, c in enumerate(curves):
        c = c.elevate_to((p,)).reparametrize([[i, i + 1]])
        cp = c.control_points[..., :3]
        w = np.ones(len(cp)) if c.weights is None else c.weights.ravel().copy()
        if pts:
            gap = float(np.linalg.norm(cp[0] - pts[-1][-1]))
            if gap > tol:
                raise SplineError(f"curve {i} starts {gap:.3g} away from where curve {i - 1} ends; the curves must "
                                  "follow each other end to start")
            w *= wts[-1][-1] / w[0]
            cp, w = cp[1:], w[1:]
        U = c.knots[0]
        knots.append(U[p + 1:-(p + 1)])
        knots.append(np.full(p if i < len(curves) - 1 else p + 1, i + 1.0))
        pts.append(cp)
        wts.append(w)
    return BSpline((p,), [np.concatenate(knots)], np.concatenate(pts), np.concatenate(wts) if rational else None)


def _chord_step(S, tol: float) -> float:
    """The parameter-plane edge length at which the chord error of the surface ``S`` meets ``tol`` (model
    units): the worst midpoint deviation of the edges of a trial grid (8 steps per knot span; along u, v and
    both diagonals) divided by their squared length, as the error falls with h^2.  Infinite on a plane."""
    u, v = sample_axes(S.knots, 8)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    P = np.stack([uu, vv], -1)
    X = S.evaluate(P.reshape(-1, 2))[:, :3].reshape(P.shape[:2] + (3,))
    worst = 0.0
    for a, b in (((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
                 ((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
                 ((slice(None, -1), slice(None, -1)), (slice(1, None), slice(1, None))),
                 ((slice(1, None), slice(None, -1)), (slice(None, -1), slice(1, None)))):
        mid = S.evaluate((0.5 * (P[a] + P[b])).reshape(-1, 2))[:, :3]
        dev = np.linalg.norm(mid - 0.5 * (X[a] + X[b]).reshape(-1, 3), axis=1)
        length2 = np.sum((P[b] - P[a]) ** 2, axis=-1).ravel()
        worst = max(worst, float(np.max(dev / length2)))
    size = float(np.ptp(X.reshape(-1, 3), axis=0).max()) or 1.0
    return np.sqrt(tol / worst) if worst > 1e-14 * size else np.inf


def _ring_estimate(S, c, tol: float) -> float:
    """How many samples the loop ``c`` needs for chord error ``tol`` in space: its image's midpoint
    deviations on a trial sampling (8 steps per knot span), scaled as h^2."""
    t = sample_axes(c.knots, 8)[0]
    x = S.evaluate(c.evaluate(t[:, None])[:, :2])[:, :3]
    mid = S.evaluate(c.evaluate((0.5 * (t[:-1] + t[1:]))[:, None])[:, :2])[:, :3]
    dev = np.linalg.norm(mid - 0.5 * (x[:-1] + x[1:]), axis=1)
    return float(np.sum(np.sqrt(dev / tol)))  # a step of deviation d needs sqrt(d / tol) pieces


def _polyline(c: BSpline, per_span: int = _LOOP_SAMPLES) -> np.ndarray:
    b = c.breakpoints(0)
    t = np.unique(np.concatenate([np.linspace(x, y, per_span + 1) for x, y in zip(b[:-1], b[1:])]))
    return c.evaluate(t[:, None])[:, :2]


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _crossings(p: np.ndarray, q: np.ndarray, same: bool) -> bool:
    """Whether closed polylines p and q (or p with itself) have two non-adjacent segments that cross or touch.

    Only segment pairs whose midpoints lie within the two segments' half-lengths can meet; a KD-tree
    finds those pairs, so long loops are not tested all against all."""
    from scipy.spatial import cKDTree

    a0, a1 = p[:-1], p[1:]
    b0, b1 = q[:-1], q[1:]
    ma, mb = 0.5 * (a0 + a1), 0.5 * (b0 + b1)
    reach = 0.5 * (np.linalg.norm(a1 - a0, axis=1).max() + np.linalg.norm(b1 - b0, axis=1).max()) * (1 + 1e-9)
    pairs = cKDTree(ma).query_ball_tree(cKDTree(mb), reach + TINY)
    i = np.repeat(np.arange(len(pairs)), [len(x) for x in pairs])
    j = np.fromiter((k for x in pairs for k in x), dtype=np.int64, count=len(i))
    if same:  # neighbouring segments share an end; the first and last close the loop
        n = len(a0)
        keep = (np.abs(i - j) > 1) & ~((i == 0) & (j == n - 1)) & ~((j == 0) & (i == n - 1))
        i, j = i[keep], j[keep]
    if not len(i):
        return False

    def orient(x, y, z):
        return np.sign((y[..., 0] - x[..., 0]) * (z[..., 1] - x[..., 1]) - (y[..., 1] - x[..., 1]) * (z[..., 0] - x[..., 0]))

    A0, A1, B0, B1 = a0[i], a1[i], b0[j], b1[j]
    # crossing or touching (a loop through one of its own points is not simple); boxes rule out collinear misses
    boxes = np.all((np.minimum(A0, A1) <= np.maximum(B0, B1)) & (np.minimum(B0, B1) <= np.maximum(A0, A1)), axis=-1)
    hit = boxes & (orient(A0, A1, B0) * orient(A0, A1, B1) <= 0) & (orient(B0, B1, A0) * orient(B0, B1, A1) <= 0)
    return bool(hit.any())


def _inside(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Even-odd point-in-polygon for points (N, 2) against a closed polyline (M, 2)."""
    x0, y0 = poly[:-1, 0], poly[:-1, 1]
    x1, y1 = poly[1:, 0], poly[1:, 1]
    px, py = pts[:, None, 0], pts[:, None, 1]
    cond = (y0 > py) != (y1 > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
    return np.sum(cond & (px < xc), axis=1) % 2 == 1


# symmetric 6-point rule of degree 4 on a triangle (Dunavant 1985): barycentric points, weights summing to 1
_A, _B = 0.445948490915965, 0.091576213509771
_RULE_POINTS = np.array([[_A, _A, 1 - 2 * _A], [_A, 1 - 2 * _A, _A], [1 - 2 * _A, _A, _A],
                         [_B, _B, 1 - 2 * _B], [_B, 1 - 2 * _B, _B], [1 - 2 * _B, _B, _B]])
_RULE_WEIGHTS = np.array([0.223381589678011] * 3 + [0.109951743655322] * 3)

#: public names of the dense loop sampling and the even-odd containment used by the loop checks
loop_polyline, inside_polyline = _polyline, _inside


@dataclass
class TrimmedSurface:
    """A surface (2-variate :class:`BSpline`) and its trimming loops (curves in its parameter domain).

    ``loops[0]`` bounds the kept region; further loops are holes.  Loops
    are checked on construction: closed, inside the domain, free of self-
    and mutual intersections (on dense samples), holes inside the outer
    loop; :class:`SplineError` names the loop otherwise.
    """

    surface: BSpline
    loops: list = field(default_factory=list)

    def __post_init__(self):
        s = self.surface
        if not isinstance(s, BSpline) or s.dim != 2:
            raise SplineError(f"a trimmed surface needs a 2-variate BSpline, got {show(s)}")
        if not self.loops or not all(isinstance(c, BSpline) and c.dim == 1 for c in self.loops):
            raise SplineError("trimming loops must be a non-empty list of B-spline curves (u(t), v(t)) in the "
                              "surface's parameter domain")
        dom = s.domain
        scale = float(np.max(dom[:, 1] - dom[:, 0]))
        polys, loops = [], []
        for i, c in enumerate(self.loops):
            ends = c.evaluate(np.array([[c.domain[0, 0]], [c.domain[0, 1]]]))[:, :2]
            if np.linalg.norm(ends[1] - ends[0]) > SNAP * scale:
                raise SplineError(f"trimming loop {i} is open: it starts at {ends[0].round(9).tolist()} and ends at "
                                  f"{ends[1].round(9).tolist()}; close it (last control point = first)")
            poly = _polyline(c)
            if np.any(poly < dom[:, 0] - ON_DOMAIN * scale) or np.any(poly > dom[:, 1] + ON_DOMAIN * scale):
                raise SplineError(f"trimming loop {i} leaves the surface's parameter domain {dom.tolist()}")
            # a loop whose points lie on one line (it runs back along itself, or is a point) overlaps itself
            # everywhere: say that it encloses nothing, before the crossings test calls it self-intersecting
            if np.linalg.svd(poly - poly.mean(axis=0), compute_uv=False)[-1] < 1e-12 * scale * np.sqrt(len(poly)):
                raise SplineError(f"trimming loop {i} encloses no area (it runs back along itself or is a point); "
                                  "a loop must be a simple closed curve around a region")
            if _crossings(poly, poly, True):
                raise SplineError(f"trimming loop {i} intersects itself; a loop must be a simple closed curve")
            area = _signed_area(poly)
            if abs(area) < ROUNDOFF * scale ** 2:
                raise SplineError(f"trimming loop {i} encloses no area")
            if (area < 0) == (i == 0):  # outer counter-clockwise, holes clockwise
                c, poly = reversed_curve(c), poly[::-1]
            polys.append(poly)
            loops.append(c)
        for i in range(len(polys)):
            for j in range(i + 1, len(polys)):
                if _crossings(polys[i], polys[j], False):
                    raise SplineError(f"trimming loops {i} and {j} intersect each other")
            if i > 0 and not _inside(polys[0], polys[i][:1])[0]:
                raise SplineError(f"trimming loop {i} (a hole) lies outside loop 0 (the outer boundary)")
        self.loops = loops

    @classmethod
    def with_loops_of(cls, other: "TrimmedSurface", surface: BSpline) -> "TrimmedSurface":
        """``surface`` trimmed by the loops of ``other``, already checked and oriented there (a composed or
        placed copy of ``other``: same parameter domain), so the loop checks are not run again."""
        if not isinstance(surface, BSpline) or surface.dim != 2:
            raise SplineError(f"a trimmed surface needs a 2-variate BSpline, got {show(surface)}")
        if np.abs(surface.domain - other.surface.domain).max() > ON_DOMAIN:
            raise SplineError(f"the surface's parameter domain {surface.domain.tolist()} is not that of the loops' "
                              f"surface {other.surface.domain.tolist()}")
        out = cls.__new__(cls)
        out.surface, out.loops = surface, list(other.loops)
        return out

    def evaluate(self, params) -> np.ndarray:
        """The surface at parameter points (N, 2) (trimming does not change the map)."""
        return self.surface.evaluate(params)

    def contains(self, params) -> np.ndarray:
        """Whether parameter points (N, 2) lie in the kept region (on dense loop samples)."""
        pts = np.asarray(params, float).reshape(-1, 2)
        inside = _inside(_polyline(self.loops[0]), pts)
        for c in self.loops[1:]:
            inside &= ~_inside(_polyline(c), pts)
        return inside

    def compose(self, outer: BSpline) -> "TrimmedSurface":
        """``outer(surface)`` exactly, the loops unchanged (Elber 2017, Fig. 7)."""
        return TrimmedSurface.with_loops_of(self, compose(outer, self.surface))

    def boundary_curves(self) -> list:
        """The loops' images in space, exact: the surface composed with each loop (3-D B-spline curves)."""
        return [compose(self.surface, c) for c in self.loops]

    def area(self, tolerance: float) -> float:
        """Area of the kept region (model units squared), to quadrature accuracy rather than ``tolerance``.

        The surface's area element |S_u x S_v| is integrated over the parameter triangles of the tessellation
        at ``tolerance`` (6-point degree-4 rule), plus, along every loop edge, over the thin strip between
        the edge's chord and the loop itself (mapped from the unit square by the chord and the exact loop
        curve; Gauss-Legendre 8 x 4, signed, so a loop bulging either way is counted right).  Only the
        quadrature approximates: no chord error of the flat triangles enters.
        """
        uv, tris, _, rings = self._triangulation(tolerance)
        tri = uv[tris]  # (T, 3, 2)
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        size = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        total = float(np.sum(size[:, None] * self._area_element(np.einsum("qk,tkd->tqd", _RULE_POINTS, tri))
                             * _RULE_WEIGHTS[None]))
        xg, wx = np.polynomial.legendre.leggauss(8)
        yg, wy = np.polynomial.legendre.leggauss(4)
        xi, eta = np.meshgrid(0.5 * (xg + 1), 0.5 * (yg + 1), indexing="ij")
        w = 0.25 * np.outer(wx, wy)
        for c, t in zip(self.loops, rings):
            ta, tb = t[:-1, None, None], t[1:, None, None]
            ends = c.evaluate(t[:, None])[:, :2]
            A, B = ends[:-1, None, None], ends[1:, None, None]
            tq = ta + xi * (tb - ta)  # (E, 8, 4)
            C = c.evaluate(tq.reshape(-1, 1))[:, :2].reshape(tq.shape + (2,))
            dC = c.jacobian(tq.reshape(-1, 1))[:, :2, 0].reshape(tq.shape + (2,)) * (tb - ta)[..., None]
            L = A + xi[..., None] * (B - A)
            P_xi = (1 - eta[..., None]) * (B - A) + eta[..., None] * dC
            P_eta = C - L
            det = P_xi[..., 0] * P_eta[..., 1] - P_xi[..., 1] * P_eta[..., 0]
            P = (1 - eta[..., None]) * L + eta[..., None] * C
            # the region lies left of every loop (outer counter-clockwise, holes clockwise): a loop bulging to
            # the right of its chord (negative det) adds area, to the left removes it
            total -= float(np.sum(w * det * self._area_element(P)))
        return total

    def _area_element(self, params: np.ndarray) -> np.ndarray:
        """|S_u x S_v| at parameters (..., 2), same leading shape."""
        J = self.surface.jacobian(params.reshape(-1, 2))[:, :3, :]
        return np.linalg.norm(np.cross(J[:, :, 0], J[:, :, 1]), axis=1).reshape(params.shape[:-1])

    # ------------------------------------------------------------------------------------------------
    def tessellate(self, tolerance: float, max_triangles: int = 2_000_000):
        """Triangles of the kept region in space (``pyvista.PolyData``), chord error below ``tolerance``.

        Point data ``u``, ``v``: the parameters of every vertex.
        """
        import pyvista as pv

        uv, tris, X, _ = self._triangulation(tolerance, max_triangles)
        mesh = pv.PolyData(X, np.hstack([np.full((len(tris), 1), 3), tris]).ravel())
        mesh.point_data["u"], mesh.point_data["v"] = uv.T
        return mesh

    def _triangulation(self, tolerance: float, max_triangles: int = 2_000_000):
        """(parameters (N, 2), triangles (T, 3), points in space (N, 3), per loop its sample parameters with
        the end) of :meth:`tessellate`; the ring points come first, loop by loop."""
        from geometry.shapes.triangulate import fill_rings

        if not (is_real(tolerance) and np.isfinite(tolerance) and tolerance > 0):
            raise SplineError(f"tolerance must be a positive length (model units), got {show(tolerance)}")
        S = self.surface
        size = float(np.ptp(S.points.reshape(-1, 3), axis=0).max())
        if tolerance < 1e-9 * size:  # below that the chord errors are rounding noise: the refinement never ends
            raise SplineError(f"tolerance {show(tolerance)} is below 1e-9 of the surface's size ({size:.3g}); "
                              f"floating point cannot meet it: use at least {1e-9 * size:.3g}")
        outer = _polyline(self.loops[0])
        area = abs(_signed_area(outer))
        # estimated before any triangle is made, from the chord errors at a trial spacing (they fall as h^2):
        # the longest interior edge that meets the tolerance, and the ring samples the loops will need
        step = _chord_step(S, tolerance)
        h = min(0.25 * float(np.ptp(outer, axis=0).max()), 0.9 * step)  # longest edge in the parameter plane
        rings = sum(_ring_estimate(S, c, tolerance) for c in self.loops)
        if max(4.0 * area / h ** 2, rings) > max_triangles:
            raise SplineError(f"the tessellation at tolerance {show(tolerance)} needs at least about "
                              f"{max(4.0 * area / h ** 2, rings):,.0f} triangles (estimated from the surface's and "
                              f"the loops' curvature), more than max_triangles = {max_triangles:,}; raise the "
                              "tolerance or max_triangles")
        samples = []
        for k in range(40):
            n_est = 4.0 * area / h ** 2  # triangles of edge ~h (right isosceles ones have area h^2 / 4)
            if n_est > max_triangles:
                raise SplineError(f"the tessellation needs more than {max_triangles:,} triangles for tolerance "
                                  f"{show(tolerance)}; raise the tolerance")
            check_memory(n_est * 200.0, f"the tessellation at tolerance {show(tolerance)}", SplineError,
                         "raise the tolerance")
            samples = [self._sample_loop(c, tolerance, max_triangles, h, None if k == 0 else samples[j])
                       for j, c in enumerate(self.loops)]
            try:
                uv, tris = fill_rings([c.evaluate(t[:-1, None])[:, :2] for c, t in zip(self.loops, samples)], h,
                                      max_triangles=max_triangles)
            except SplineError as exc:
                raise SplineError(f"the tessellation at tolerance {show(tolerance)} needs more than "
                                  f"{max_triangles:,} triangles ({exc}); raise the tolerance or max_triangles"
                                  ) from None
            X = S.evaluate(uv)[:, :3]
            edges = np.unique(np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), 1), axis=0)
            mid = S.evaluate(0.5 * (uv[edges[:, 0]] + uv[edges[:, 1]]))[:, :3]
            err = float(np.linalg.norm(mid - 0.5 * (X[edges[:, 0]] + X[edges[:, 1]]), axis=1).max())
            if err <= tolerance:
                break
            h *= float(np.clip(0.9 * np.sqrt(tolerance / err), 0.25, 0.8))  # the chord error falls as h^2
        return uv, tris, X, samples

    def _sample_loop(self, c: BSpline, tol: float, limit: int = 2_000_000, step: float = np.inf, start=None):
        """Increasing parameters of loop c, from its start to its end, whose points have chord error <= tol in
        space and lie at most ``step`` apart in the parameter plane, refined from ``start`` (samples that
        already meet the chord test) or from 4 intervals per knot span; more than ``limit`` samples raise
        :class:`SplineError` (the tolerance is too fine for the loop)."""
        if start is None:
            b = c.breakpoints(0)
            t = np.unique(np.concatenate([np.linspace(x, y, 5) for x, y in zip(b[:-1], b[1:])]))
        else:
            t = start
        for _ in range(60):
            if len(t) > limit:
                raise SplineError(f"a trimming loop needs more than {limit:,} samples for tolerance {show(tol)}; "
                                  "raise the tolerance (or max_triangles)")
            uv = c.evaluate(t[:, None])[:, :2]
            pts = self.surface.evaluate(uv)[:, :3]
            mid = 0.5 * (t[:-1] + t[1:])
            mp = self.surface.evaluate(c.evaluate(mid[:, None])[:, :2])[:, :3]
            bad = ((np.linalg.norm(mp - 0.5 * (pts[:-1] + pts[1:]), axis=1) > tol)
                   | (np.linalg.norm(np.diff(uv, axis=0), axis=1) > step))
            if not bad.any():
                break
            t = np.sort(np.concatenate([t, mid[bad]]))
        return t


