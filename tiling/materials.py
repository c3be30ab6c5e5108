"""Heterogeneous material channels (Massarwi et al. 2018, Section 6.1).

Channels live on the tile, on the deformation map D, or on a composed patch:
:func:`interpolate_channel` sets one from any function, exactly when the
function lies in the spline's space (e.g. linear in the parameters) and as a
spline quasi-interpolant (interpolation at the Greville abscissae) otherwise.
:func:`graded_channel` is the aluminium-to-steel grading of Massarwi et al. 2018 (Fig. 18)
``k = k0 (1 - s) + k1 s`` with ``s`` the normalised distance from a face.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline, knots as kn
from geometry.faces import FACE_NAMES

from .errors import TilingError
from geometry.errors import show
from geometry.tolerances import COINCIDENT


def interpolate_channel(spline: BSpline, name: str, fn, on: str = "parameters") -> BSpline:
    """Copy of ``spline`` with channel ``name`` interpolating ``fn`` at the Greville points.

    ``fn`` takes parameters (N, d) (``on="parameters"``) or physical points
    (N, 3) (``on="points"``) and returns (N,).  Exact when the field is in the
    spline space: for a NURBS the interpolated function is the homogeneous
    numerator ``fn * W`` with the spline's own weight function ``W``.
    """
    if on not in ("parameters", "points"):
        raise TilingError(f"on must be 'parameters' or 'points', got {show(on)}")
    g = [kn.greville(U, p) for U, p in zip(spline.knots, spline.degrees)]
    grid = np.stack(np.meshgrid(*g, indexing="ij"), -1).reshape(-1, spline.dim)
    arg = grid if on == "parameters" else spline.evaluate(grid)[:, :3]
    vals = np.asarray(fn(arg), float)
    if vals.shape != (len(grid),) or not np.all(np.isfinite(vals)):
        raise TilingError(f"channel function for {show(name)} must return {len(grid)} finite values, got shape {vals.shape}")
    data = vals.reshape(spline.shape)
    if spline.is_rational:
        Wvals = spline.weights  # the weight function at the Greville grid
        for k in range(spline.dim):
            Wvals = kn.apply_along(Wvals[..., None], k, kn.basis_matrix(spline.knots[k], spline.degrees[k], g[k]))[..., 0]
        data = data * Wvals
    for k in range(spline.dim):  # tensor-product collocation solve, one direction at a time
        B = kn.basis_matrix(spline.knots[k], spline.degrees[k], g[k]).toarray()
        data = kn.apply_along(data[..., None], k, np.linalg.inv(B))[..., 0]
    if spline.is_rational:
        data = data / spline.weights
    return spline.with_channel(name, data)


def graded_channel(spline: BSpline, name: str = "k", near: float = 205.0, far: float = 54.0,
                   face: str = "wmin", mode: str = "parameter") -> BSpline:
    """Grade a channel from ``near`` at ``face`` to ``far`` at the opposite face (Massarwi et al. 2018, Fig. 18).

    ``mode="parameter"``: s is the normalised parameter distance from the face
    (exact: linear in one parameter).  ``mode="distance"``: s is the physical
    distance from the face's control net plane fit, normalised to [0, 1], and
    represented by quasi-interpolation (planar faces only).  Defaults: aluminium 205 W/(m K) to
    stainless steel 54 W/(m K).
    """
    if face not in FACE_NAMES[: 2 * spline.dim]:
        raise TilingError(f"unknown face {show(face)}; use one of {list(FACE_NAMES[: 2 * spline.dim])}")
    k, side = divmod(FACE_NAMES.index(face), 2)
    lo, hi = spline.domain[k]
    if mode == "parameter":
        def s_of(x):
            t = (x[:, k] - lo) / (hi - lo)
            return t if side == 0 else 1 - t
        return interpolate_channel(spline, name, lambda x: near * (1 - s_of(x)) + far * s_of(x))
    if mode == "distance":
        pts = spline.boundary(face).points.reshape(-1, 3)
        c = pts.mean(0)
        n = np.linalg.svd(pts - c)[2][-1]  # plane through the face's control net
        allp = spline.points.reshape(-1, 3)
        size = np.ptp(allp, axis=0).max()
        if np.abs((pts - c) @ n).max() > COINCIDENT * size:
            raise TilingError(f"face {face} is curved; mode='distance' needs a planar face, use mode='parameter'")
        dmax = np.abs((allp - c) @ n).max()
        return interpolate_channel(spline, name, lambda x: near + (far - near) * np.clip(np.abs((x - c) @ n) / dmax, 0, 1),
                                   on="points")
    raise TilingError(f"mode must be 'parameter' or 'distance', got {show(mode)}")
