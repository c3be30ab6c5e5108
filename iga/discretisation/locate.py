"""Point location in a model: which patch holds a physical point, and at which parameters.

Candidate patches come from bounding boxes of sampled points; a KD-tree of
each patch's samples gives the start of a vectorised Gauss-Newton iteration
(:func:`geometry.maps.inversion.newton_inverse`) on the exact geometry
``D(A T(xi) + b)`` through the chain rule.  Used by ``Solution.probe`` and by
pipelines, which check their probes before the solve.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from geometry.maps.inversion import newton_inverse, start_grid

from iga.errors import ProblemError
from geometry.patches.chain import patch_geometry_grid, patch_geometry_points
from geometry.patches.multipatch import PlacedPatch
from geometry.patches.sampling import piece_boxes
from geometry.tolerances import ROUNDOFF

__all__ = ["Locator"]


class Locator:
    """Locates physical points in the patches of ``model`` (KD-trees built once, on first use).

    Every patch is searched piece by piece between its discontinuity knots
    (:func:`geometry.patches.sampling.piece_boxes`): on a slot wall the two sides of a
    discontinuity plane are different surfaces, and each is found on its own
    piece, with its own one-sided limit.
    """

    def __init__(self, model):
        self.model = model
        self._trees = None

    def _build(self):
        self._trees = []  # (patch index, piece, box (3, 2), KD-tree, start parameters, bounding box lo, hi)
        for pi, patch in enumerate(self.model.patches):
            s = patch.spline
            for box in piece_boxes(s):
                piece = patch if np.array_equal(box, s.domain) else PlacedPatch(
                    s.extract(box), patch.placement, patch.outer, patch.tile, patch.level)
                ps = piece.spline
                axes = start_grid(ps.domain, [ps.breakpoints(k) for k in range(3)])
                x, _, _ = patch_geometry_grid(piece, axes)
                grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
                pad = 1e-9 * max(1.0, np.abs(x).max()) + 0.05 * np.ptp(x, axis=0)  # curved faces bulge between samples
                self._trees.append((pi, piece, box, cKDTree(x), grid, x.min(0) - pad, x.max(0) + pad))

    def __call__(self, points, tol: float = 1e-10, what: str = "probe"):
        """(patch index (N,), parameters (N, 3)) of physical points (N, 3).

        Parameters on the upper side of a discontinuity knot are returned one
        floating-point step below it, so that evaluating the whole patch there
        gives that side's limit.  Raises :class:`ProblemError` for malformed
        points and lists the points found in no patch (relative tolerance ``tol``).
        """
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
            raise ProblemError(f"{what} points must be a finite array of shape (N, 3), got {np.shape(points)}")
        if self._trees is None:
            self._build()
        where = np.full(len(pts), -1)
        params = np.zeros((len(pts), 3))
        scale = max(1.0, float(np.abs(pts).max())) if len(pts) else 1.0
        for pi, piece, box, tree, grid, lo, hi in self._trees:
            cand = np.nonzero((where < 0) & np.all((pts >= lo) & (pts <= hi), axis=1))[0]
            if not len(cand):
                continue
            _, nearest = tree.query(pts[cand])

            def fn(t, piece=piece):
                x, J, _ = patch_geometry_points(piece, t)
                return x, J

            xi = newton_inverse(fn, box, grid[nearest], pts[cand], ROUNDOFF * float((box[:, 1] - box[:, 0]).max()))
            x, _, _ = patch_geometry_points(piece, xi)
            ok = np.linalg.norm(x - pts[cand], axis=1) <= tol * scale
            dom = self.model.patches[pi].spline.domain
            for k in range(3):  # the upper side of an interior discontinuity: one step inside this piece
                if box[k, 1] < dom[k, 1]:
                    at = xi[:, k] >= box[k, 1]
                    xi[at, k] = np.nextafter(box[k, 1], -np.inf)
            where[cand[ok]] = pi
            params[cand[ok]] = xi[ok]
        missing = np.nonzero(where < 0)[0]
        if len(missing):
            show = np.round(pts[missing[:5]], 6).tolist()
            raise ProblemError(f"{len(missing)} {what} point(s) lie outside the model, e.g. {show}")
        return where, params
