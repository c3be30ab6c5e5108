"""Point inversion: the parameters of physical points on a curve, surface or trivariate map.

Gauss-Newton on ``|x(t) - target|^2`` (Newton for a trivariate, whose
Jacobian is square), started from the nearest point of a sampled parameter
grid (a KD-tree query, so a point far from the grid's first guess still finds
the right element), with every step clipped to the parameter domain.
Vectorised over the points: one evaluation of values and Jacobians per
iteration for all of them.  Callers that read distances and memberships only
(a V-model's classification and margins: a few hundred points at a time, a
thousand times per model) ask for the whole iteration in one compiled kernel
(``kernel=True``, :mod:`geometry.compiled._newton_kernels`): the same iterates point by
point, without a NumPy call per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.numbers import TINY
from geometry.cache import PerObject
from scipy.spatial import cKDTree

from geometry.compiled import _fast
from geometry.compiled._fast import readonly
from geometry.compiled.lock import locked
from geometry.errors import SplineError
from geometry.tolerances import COINCIDENT, ROUNDOFF

__all__ = ["Inversion", "box_gaps", "invert", "invert_nearest", "newton_inverse", "start_grid"]


@dataclass
class Inversion:
    """Result of :func:`invert`: parameters (N, d), distance |x(params) - point| (N,), and ``inside`` (N,)."""

    params: np.ndarray
    distance: np.ndarray
    inside: np.ndarray


def start_grid(domain: np.ndarray, breaks, per_element: int = 4) -> list[np.ndarray]:
    """Sample axes for starting guesses: ``per_element`` points per knot span (at least 6 per direction)."""
    axes = []
    for (lo, hi), b in zip(domain, breaks):
        n = max(6, per_element * (len(b) - 1) + 2)
        axes.append(np.linspace(lo, hi, n))
    return axes


_FREE_STEPS = 4  # steps every point takes before it may stop for want of progress
_HALVINGS = 8  # damped: halvings of an uphill step before a point stays at its better iterate
_MAX_ITER = 40  # Newton steps at most
_CREEP = 1e-6  # a point held at the domain's bound that gains less than this (relative) in a step stops


def newton_inverse(fn, domain: np.ndarray, start: np.ndarray, targets: np.ndarray, tol: float,
                   max_iter: int = _MAX_ITER, damped: bool = False) -> np.ndarray:
    """Refine parameters ``start`` (N, d) so that ``fn(params)[0]`` approaches ``targets`` (N, 3).

    ``fn(params) -> (x (N, 3), J (N, 3, d))``.  Gauss-Newton steps (the
    least-squares step for d < 3), clipped to the box ``domain`` (d, 2).  A
    point stops when its step is below ``tol`` (parameter units), or, after
    ``_FREE_STEPS`` steps, when it is held at the domain's bound and a step
    brings it nearer its target by less than ``_CREEP`` (relative): a point
    outside the image then crept along the boundary for all ``max_iter`` steps.

    ``damped``: the foot points of points off the image, for distances
    (:func:`_damped_newton`).  Off by default: where a point has two nearest
    points, the V-rep bridges are built (and were tested) on the one the full
    steps find.  Returns the parameters.
    """
    if damped:
        return _damped_newton(fn, domain, start, targets, tol, max_iter)
    t, last, active = _iterates(start)  # last: each point's residual norm at its previous iterate
    for k in range(max_iter):
        if not len(active):
            break
        J, r = _residuals(fn, t, active, targets)
        if k >= _FREE_STEPS - 1:  # residuals are compared from here on only (small calls pay per operation)
            norm = np.sqrt(np.einsum("ij,ij->i", r, r))
            if k >= _FREE_STEPS:
                ta = t[active]
                held = np.any((ta <= domain[:, 0]) | (ta >= domain[:, 1]), axis=1)
                go = ~(held & (norm >= (1.0 - _CREEP) * last[active]))
                if not go.all():
                    active, J, r, norm = active[go], J[go], r[go], norm[go]
            last[active] = norm
        ta = t[active]
        new = np.clip(ta - _gauss_newton_step(J, r, ta, domain, False), domain[:, 0], domain[:, 1])
        moved = np.abs(new - ta).max(axis=1)
        t[active] = new
        active = active[moved > tol]
    return t


def _damped_newton(fn, domain, start, targets, tol, max_iter) -> np.ndarray:
    """:func:`newton_inverse` with projected, damped steps: a parameter at its bound that the step would push
    out takes no part in the step of the others, a step that takes a point farther from its target (beyond
    round-off) is halved, up to ``_HALVINGS`` times, and a step that gains nothing beyond round-off stops the
    point.  The full step can overshoot off a curved image: iterates about a cylinder face's foot point fell
    into a two-cycle 0.003 above the distance."""
    t, last, active = _iterates(start)  # last: the residual norm at each point's last iterate that got nearer
    prev = t.copy()  # that iterate (where a halved step starts)
    halved = np.zeros(len(t), np.int64)  # halvings since that iterate
    floor = _norm_floor(targets)
    for k in range(max_iter):
        if not len(active):
            break
        J, r = _residuals(fn, t, active, targets)
        norm = np.linalg.norm(r, axis=1)
        ta, before, fl = t[active], last[active], floor[active]
        worse = norm > before + fl
        held = np.any((ta <= domain[:, 0]) | (ta >= domain[:, 1]), axis=1)
        idle = (norm >= before - fl) | (held & (norm >= (1.0 - _CREEP) * before))
        stop = ~worse & idle & (k >= _FREE_STEPS)
        back = active[worse]
        if len(back):  # halve the step that went uphill; give up at the better point after a few halvings
            t[back] = 0.5 * (prev[back] + t[back])
            halved[back] += 1
            done = (halved[back] > _HALVINGS) | (np.abs(t[back] - prev[back]).max(axis=1) <= tol)
            t[back[done]] = prev[back[done]]
            back = back[~done]
        go = ~worse & ~stop
        active, J, r, ta = active[go], J[go], r[go], ta[go]
        prev[active], last[active], halved[active] = ta, norm[go], 0
        new = np.clip(ta - _gauss_newton_step(J, r, ta, domain, True), domain[:, 0], domain[:, 1])
        moved = np.abs(new - ta).max(axis=1)
        t[active] = new
        active = np.concatenate([active[moved > tol], back])
    return t


def _norm_floor(targets: np.ndarray) -> np.ndarray:
    """Per target (N, 3): the round-off of a residual norm about it (N,), below which the damped steps count
    no gain or loss."""
    return 64 * np.finfo(float).eps * np.maximum(1.0, np.abs(targets).max(axis=1))


def _iterates(start):
    """The iterates (a copy of ``start``), residual norms so far (inf) and the active points (all)."""
    t = np.array(start, float)
    return t, np.full(len(t), np.inf), np.arange(len(t))


def _residuals(fn, t, active, targets):
    """Jacobians and residuals x(t) - target of the active points."""
    x, J = fn(t[active])
    return J, x - targets[active]


def _gauss_newton_step(J: np.ndarray, r: np.ndarray, t: np.ndarray, domain: np.ndarray,
                       projected: bool) -> np.ndarray:
    """The Gauss-Newton steps (N, d) at parameters t (N, d) (new = t - step) from Jacobians J (N, 3, d) and
    residuals r (N, 3); ``projected``: parameters pinned at a bound the step would cross left out."""
    JT = np.transpose(J, (0, 2, 1))
    A = JT @ J
    g = (JT @ r[:, :, None])[:, :, 0]
    # a rank-deficient normal matrix (degenerate point) gets a tiny regularisation instead of a LinAlgError
    reg = ROUNDOFF * (np.trace(A, axis1=1, axis2=2) + TINY)
    eye = np.eye(A.shape[1])
    A = A + reg[:, None, None] * eye
    step = np.linalg.solve(A, g[:, :, None])[:, :, 0]
    if not projected:
        return step
    pinned = ((t <= domain[:, 0]) & (step > 0)) | ((t >= domain[:, 1]) & (step < 0))
    rows = np.flatnonzero(pinned.any(axis=1) & ~pinned.all(axis=1))
    if len(rows):  # solved as if a pinned parameter could move, the step misleads the others
        free = ~pinned[rows]
        Af = A[rows] * (free[:, :, None] & free[:, None, :]) + pinned[rows][:, :, None] * eye
        step[rows] = np.linalg.solve(Af, (g[rows] * free)[:, :, None])[:, :, 0]
    return step


# the sampled start grid of each spline, kept while the spline lives: splines are immutable, and the V-rep
# builder inverts a few points at a time on the same maps and trimming surfaces about a thousand times
_STARTS = PerObject()  # per live spline: its start grid and KD-tree


def _starts(spline):
    """(grid parameters (n, d), KD-tree of their images, the model's size for ``inside``) of ``spline``."""
    def make():
        d, dom = spline.dim, spline.domain
        axes = start_grid(dom, [spline.breakpoints(k) for k in range(d)])
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, d)
        xs = spline.evaluate(grid)[:, :3]
        return grid, cKDTree(xs), max(1.0, float(np.abs(xs).max()))

    return _STARTS.get(spline, make)


def invert(spline, points, tol: float = 1e-10, compiled: bool | None = None, damped: bool = False,
           kernel: bool = False) -> Inversion:
    """Parameters of ``points`` (N, 3) on ``spline`` (curve, surface or trivariate), nearest in the image.

    ``distance`` is the remaining distance to the image; ``inside`` marks
    points whose distance is below ``tol`` times the model size (for a
    trivariate: points inside the volume).  Raises :class:`SplineError` for
    non-finite or badly shaped points.  ``compiled``: whether the Newton iterations of a trivariate evaluate
    by the compiled kernel (:mod:`geometry.compiled._fast`): None from :data:`geometry.compiled._fast.MIN_POINTS` / 10 points
    (the iterations evaluate them about ten times, so the kernel's import pays as it does for one
    evaluation of MIN_POINTS), True for any number, False never.  ``damped``: for points off the image,
    the nearest point and its distance by damped, projected steps (:func:`newton_inverse`).  ``kernel``: the
    whole iteration of a surface or trivariate in one compiled kernel (:mod:`geometry.compiled._newton_kernels`, when
    numba is installed), point by point: the same iterates up to round-off, about ten times faster on the few
    hundred points a V-model's membership and margin tests invert at a time; for callers that read the
    distances and ``inside``, not the last bits of the parameters.
    """
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise SplineError(f"points to invert must be a finite array of shape (N, 3), got shape {np.shape(points)}")
    d = spline.dim
    dom = spline.domain
    grid, tree, scale = _starts(spline)
    if not len(pts):
        return Inversion(np.zeros((0, d)), np.zeros(0), np.zeros(0, bool))
    _, nearest = tree.query(pts)
    span = float((dom[:, 1] - dom[:, 0]).max())
    if kernel and _fast.AVAILABLE and d in (2, 3):
        t, dist = _kernel_invert(spline, grid[nearest], pts, 1e-15 * span, damped)
        return Inversion(t, dist, dist <= tol * scale)

    if compiled is None and 10 * len(pts) >= _fast.MIN_POINTS:
        compiled = True

    def fn(t):  # the iterates are clipped to the domain: no parameter checks
        v, J = spline._value_jacobian(t, values=True, checked=True, compiled=compiled)
        return v[:, :3], J[:, :3, :]

    t = newton_inverse(fn, dom, grid[nearest], pts, 1e-15 * span, damped=damped)
    dist = np.linalg.norm(spline.evaluate(t)[:, :3] - pts, axis=1)
    return Inversion(t, dist, dist <= tol * scale)


def _kernel_invert(spline, start: np.ndarray, pts: np.ndarray, tol: float, damped: bool):
    """(parameters (N, d), distances (N,)) of ``pts`` on a surface or trivariate by
    :func:`geometry.compiled._newton_kernels.invert_points` from ``start`` (N, d), steps below ``tol`` ending a point."""
    from geometry.compiled._newton_kernels import invert_points

    d, n = spline.dim, len(pts)
    C, U = spline._hom, list(spline.knots)
    degrees = list(spline.degrees)
    dom = np.asarray(spline.domain, float)
    if d == 2:  # a trivariate of degree 0 in a third direction: one layer of coefficients, knots [0, 1]
        C, U, degrees = C[:, :, None, :], U + [np.array([0.0, 1.0])], degrees + [0]
        dom = np.vstack([dom, [0.0, 0.0]])
    t0 = np.zeros((n, 3))
    t0[:, :d] = start
    floor = _norm_floor(pts)
    params, dist = np.empty((n, 3)), np.empty(n)
    off = np.cumsum([0] + [len(u) for u in U])
    locked(invert_points)(readonly(C), readonly(np.concatenate(U)), readonly(off, np.int64),
                          readonly(degrees, np.int64), bool(spline.is_rational), d, readonly(dom[:, 0]),
                          readonly(dom[:, 1]), readonly(t0), readonly(pts), float(tol), _MAX_ITER, bool(damped),
                          _FREE_STEPS, _HALVINGS, _CREEP, ROUNDOFF, readonly(floor), params, dist)
    return params[:, :d], dist


def invert_nearest(splines, points, tol: float = 1e-10, damped: bool = False,
                   kernel: bool = False) -> tuple[np.ndarray, Inversion]:
    """(index (N,), :class:`Inversion`): for each of ``points`` (N, 3) the one of ``splines`` (e.g. the six
    boundary surfaces of a trivariate) whose :func:`invert` distance is least (the lowest index on a tie within
    ``COINCIDENT`` x the splines' size), and that inversion: the choice and result of inverting every point into
    every spline and taking the argmin (up to round-off where a smaller batch changes :func:`invert`'s
    evaluation path, at ``MIN_POINTS`` / 10 points).
    ``kernel``: as :func:`invert`'s.

    A spline's control points' box bounds its distance from below (convex hull; a spline point lies in the
    box), so each point tries the splines in the order of its box gaps and skips one whose gap exceeds the
    least distance it found: a point near one face of a box is inverted into that face alone.
    """
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise SplineError(f"points to invert must be a finite array of shape (N, 3), got shape {np.shape(points)}")
    if not len(splines) or len({S.dim for S in splines}) != 1:
        raise SplineError(f"invert_nearest needs one or more splines of one dimension, got "
                          f"{[S.dim for S in splines] or 'none'}; pass e.g. the six boundary surfaces of a trivariate")
    n, d = len(pts), splines[0].dim
    boxes = np.array([S.bounding_box() for S in splines])
    gap = box_gaps(pts, boxes)  # (N, splines)
    # the splines' size: ties are decided with the margin COINCIDENT x size (a stated margin, so every CPU
    # kernel makes the same choice), and a box gap needs twice that of slack against a distance
    size = max(float(np.max(boxes[:, :, 1].max(0) - boxes[:, :, 0].min(0))), TINY)
    margin = COINCIDENT * size
    slack = 2 * margin
    which, params = np.full(n, len(splines)), np.zeros((n, d))
    best, inside = np.full(n, np.inf), np.zeros(n, bool)
    order = np.argsort(gap, axis=1, kind="stable")
    for k in range(len(splines)):  # round k: each point's k-th nearest box
        for g in np.unique(order[:, k]):
            sel = np.flatnonzero((order[:, k] == g) & (gap[:, g] <= best + slack))
            if not len(sel):
                continue
            inv = invert(splines[g], pts[sel], tol, damped=damped, kernel=kernel)
            # a near tie (a point off an edge where two faces are equally near) goes to the lower index
            # whatever the rounding: a later face wins only by more than the margin
            win = (inv.distance < best[sel] - margin) | ((inv.distance <= best[sel] + margin) & (g < which[sel]))
            sel = sel[win]
            which[sel], params[sel], best[sel], inside[sel] = g, inv.params[win], inv.distance[win], inv.inside[win]
    return which, Inversion(params, best, inside)


def box_gaps(points, boxes: np.ndarray) -> np.ndarray:
    """Distances (N, M) from points (N, 3) to axis-aligned boxes (M, 3, 2) (0 inside a box): lower bounds of the
    distance to a spline whose control points a box holds (convex hull)."""
    x = np.asarray(points, float)[:, None, :]
    gap = np.maximum(np.maximum(boxes[None, :, :, 0] - x, x - boxes[None, :, :, 1]), 0.0)
    return np.sqrt(np.sum(gap * gap, axis=2))
