"""Point inversion: the parameters of physical points on a curve, surface or trivariate map.

Gauss-Newton on ``|x(t) - target|^2`` (Newton for a trivariate, whose
Jacobian is square), started from the nearest point of a sampled parameter
grid (a KD-tree query, so a point far from the grid's first guess still finds
the right element), with every step clipped to the parameter domain.
Vectorised over the points: one evaluation of values and Jacobians per
iteration for all of them.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from . import _fast
from .errors import SplineError
from .tolerances import ROUNDOFF

__all__ = ["Inversion", "invert", "newton_inverse", "start_grid"]


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


def newton_inverse(fn, domain: np.ndarray, start: np.ndarray, targets: np.ndarray, tol: float,
                   max_iter: int = 40) -> np.ndarray:
    """Refine parameters ``start`` (N, d) so that ``fn(params)[0]`` approaches ``targets`` (N, 3).

    ``fn(params) -> (x (N, 3), J (N, 3, d))``.  Gauss-Newton steps (the
    least-squares step for d < 3), clipped to ``domain`` (d, 2); stops when no
    step exceeds ``tol`` (in parameter units).  Returns the parameters.
    """
    t = np.array(start, float)
    active = np.arange(len(t))
    for _ in range(max_iter):
        if not len(active):
            break
        x, J = fn(t[active])
        r = x - targets[active]
        JT = np.transpose(J, (0, 2, 1))
        A = JT @ J
        g = (JT @ r[:, :, None])[:, :, 0]
        # a rank-deficient normal matrix (degenerate point) gets a tiny regularisation instead of a LinAlgError
        reg = ROUNDOFF * (np.trace(A, axis1=1, axis2=2) + 1e-300)
        A = A + reg[:, None, None] * np.eye(A.shape[1])
        step = np.linalg.solve(A, g[:, :, None])[:, :, 0]
        new = np.clip(t[active] - step, domain[:, 0], domain[:, 1])
        moved = np.abs(new - t[active]).max(axis=1)
        t[active] = new
        active = active[moved > tol]
    return t


# the sampled start grid of each spline, kept while the spline lives: splines are immutable, and the V-rep
# builder inverts a few points at a time on the same maps and trimming surfaces about a thousand times
_STARTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _starts(spline):
    """(grid parameters (n, d), KD-tree of their images, the model's size for ``inside``) of ``spline``."""
    known = _STARTS.get(spline)
    if known is None:
        d, dom = spline.dim, spline.domain
        axes = start_grid(dom, [spline.breakpoints(k) for k in range(d)])
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, d)
        xs = spline.evaluate(grid)[:, :3]
        known = _STARTS[spline] = (grid, cKDTree(xs), max(1.0, float(np.abs(xs).max())))
    return known


def invert(spline, points, tol: float = 1e-10, compiled: bool | None = None) -> Inversion:
    """Parameters of ``points`` (N, 3) on ``spline`` (curve, surface or trivariate), nearest in the image.

    ``distance`` is the remaining distance to the image; ``inside`` marks
    points whose distance is below ``tol`` times the model size (for a
    trivariate: points inside the volume).  Raises :class:`SplineError` for
    non-finite or badly shaped points.  ``compiled``: whether the Newton iterations of a trivariate evaluate
    by the compiled kernel (:mod:`geometry._fast`): None from :data:`geometry._fast.MIN_POINTS` / 10 points
    (the iterations evaluate them about ten times, so the kernel's import pays as it does for one
    evaluation of MIN_POINTS), True for any number, False never.
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

    if compiled is None and 10 * len(pts) >= _fast.MIN_POINTS:
        compiled = True

    def fn(t):  # the iterates are clipped to the domain: no parameter checks
        v, J = spline._value_jacobian(t, values=True, checked=True, compiled=compiled)
        return v[:, :3], J[:, :3, :]

    span = float((dom[:, 1] - dom[:, 0]).max())
    t = newton_inverse(fn, dom, grid[nearest], pts, 1e-15 * span)
    dist = np.linalg.norm(spline.evaluate(t)[:, :3] - pts, axis=1)
    return Inversion(t, dist, dist <= tol * scale)
