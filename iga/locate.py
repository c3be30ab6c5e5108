"""Point location in a model: which patch holds a physical point, and at which parameters.

Candidate patches come from bounding boxes of sampled points; a KD-tree of
each patch's samples gives the start of a vectorised Gauss-Newton iteration
(:func:`geometry.inversion.newton_inverse`) on the exact geometry
``D(A T(xi) + b)`` through the chain rule.  Used by ``Solution.probe`` and by
pipelines, which check their probes before the solve.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from geometry.inversion import newton_inverse, start_grid

from .errors import ProblemError
from geometry.chain import patch_geometry_grid, patch_geometry_points

__all__ = ["Locator"]


class Locator:
    """Locates physical points in the patches of ``model`` (KD-trees built once, on first use)."""

    def __init__(self, model):
        self.model = model
        self._trees = None

    def _build(self):
        self._trees = []
        for patch in self.model.patches:
            s = patch.spline
            axes = start_grid(s.domain, [s.breakpoints(k) for k in range(3)])
            x, _, _ = patch_geometry_grid(patch, axes)
            grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
            pad = 1e-9 * max(1.0, np.abs(x).max()) + 0.05 * np.ptp(x, axis=0)  # curved faces bulge between samples
            self._trees.append((cKDTree(x), grid, x.min(0) - pad, x.max(0) + pad))

    def __call__(self, points, tol: float = 1e-10, what: str = "probe"):
        """(patch index (N,), parameters (N, 3)) of physical points (N, 3).

        Raises :class:`ProblemError` for malformed points and lists the points
        found in no patch (relative tolerance ``tol``).
        """
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
            raise ProblemError(f"{what} points must be a finite array of shape (N, 3), got {np.shape(points)}")
        if self._trees is None:
            self._build()
        where = np.full(len(pts), -1)
        params = np.zeros((len(pts), 3))
        scale = max(1.0, float(np.abs(pts).max())) if len(pts) else 1.0
        for pi, (tree, grid, lo, hi) in enumerate(self._trees):
            cand = np.nonzero((where < 0) & np.all((pts >= lo) & (pts <= hi), axis=1))[0]
            if not len(cand):
                continue
            patch = self.model.patches[pi]
            dom = patch.spline.domain
            _, nearest = tree.query(pts[cand])

            def fn(t, patch=patch):
                x, J, _ = patch_geometry_points(patch, t)
                return x, J

            xi = newton_inverse(fn, dom, grid[nearest], pts[cand], 1e-14 * float((dom[:, 1] - dom[:, 0]).max()))
            x, _, _ = patch_geometry_points(patch, xi)
            ok = np.linalg.norm(x - pts[cand], axis=1) <= tol * scale
            where[cand[ok]] = pi
            params[cand[ok]] = xi[ok]
        missing = np.nonzero(where < 0)[0]
        if len(missing):
            show = np.round(pts[missing[:5]], 6).tolist()
            raise ProblemError(f"{len(missing)} {what} point(s) lie outside the model, e.g. {show}")
        return where, params
