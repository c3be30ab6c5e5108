"""Surface bridges rebuilt in space where their map's knot lines would cut them (Hong and Elber 2021, Section
3.3).

A bridge to a trimming surface (:mod:`tiling.vrep.bridges`) is built in its primitive's parameters and
composed through the map D, as the tiles are.  Composition is exact per Bezier piece of D only: where the
bridge's parameter image crosses one of D's knot planes, its image is piecewise polynomial across a curved
surface, which no tensor-product spline holds, so the model would not be one exact B-spline model (no
:meth:`~tiling.Microstructure.compose_all`, no IGES).  Such a bridge is rebuilt in space, as the union tubes
are (:func:`tiling.vrep.tubes.hermite_tube`):

* its first face is the tile's composed anchoring face (exact), so it meets the tile by an identity
  interface and, its second control layer continuing the tile's cross derivative, G1 across the whole face;
* its last face has the far section's control points, which :func:`~tiling.vrep.bridges.build_bridges`
  snapped onto the trimming surface, mapped through D (points, not a composition), with D's channels there;
  its end tangent is the trimming surface's normal at the far end of the axis;
* it is analysed in the tile face's space and a uniform space along the sweep (the tube's carrier).
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry.faces import FACE_AXIS
from geometry.maps.inversion import invert_nearest
from geometry.tolerances import COINCIDENT

from .tubes import Face, face_of, face_space, hermite_tube, tube_space

__all__ = ["crosses_knot_lines", "in_space"]


def crosses_knot_lines(b) -> bool:
    """Whether the bridge's control net (its convex hull holds the bridge) crosses an interior knot plane of its
    map D: composition would then need the bridge cut along a curved surface."""
    pts = b.spline.points.reshape(-1, 3)
    lo, hi = pts.min(0), pts.max(0)
    dom = b.D.domain
    tol = COINCIDENT * np.ptp(dom, axis=1)
    for k in range(3):
        inner = b.D.breakpoints(k)[1:-1]
        if np.any((inner > lo[k] + tol[k]) & (inner < hi[k] - tol[k])):
            return True
    return False


def _end_normal(b, end: np.ndarray) -> np.ndarray:
    """Unit normal of the trimming surface nearest to the physical point ``end``, towards the bridge's start."""
    near, inv = invert_nearest(b.target, end[None])  # a near tie at an edge: the lower index, on every kernel
    _, J = b.target[int(near[0])].value_and_jacobian(inv.params)
    n = np.cross(J[0, :3, 0], J[0, :3, 1])
    start = b.D.evaluate(b.axis[:1])[0, :3]
    return n * np.sign(np.dot(n, start - end)) / np.linalg.norm(n)


def in_space(b, placed, beta: float | None = None) -> tuple[BSpline, list] | None:
    """The bridge ``b`` rebuilt in space (module notes): (geometry on [0, 1]^3, analysis space [(U, p)] * 3), or
    None where the tile's composed face is rational (union tubes join polynomial faces only).  ``beta``: the
    end tangents' length over the ends' distance (default the bridge's bend parameter)."""
    P = placed[b.patch]
    if P.composed.is_rational:
        return None
    a = face_of(P, b.face, (b.patch, b.face))
    k, s = FACE_AXIS[b.face]
    tile_face = P.spline.boundary(b.face)
    far = b.spline.control_points[:, :, 3, :3]  # the far section, snapped onto the trimming surface (parameters)
    mapped = b.D.evaluate(far.reshape(-1, 3)).reshape(far.shape[:2] + (-1,))  # xyz and D's channels
    tile_channels = np.take(P.spline.control_points, -1 if s else 0, axis=k)[..., 3:]
    net = np.concatenate([mapped, tile_channels], axis=-1)
    surf = BSpline(tile_face.degrees, tile_face.knots, net, channels=a.surface.channels)
    surf = surf.reparametrize(np.array([[0.0, 1.0], [0.0, 1.0]]))
    end = surf.evaluate(np.array([[0.5, 0.5]]))[0, :3]
    n = _end_normal(b, end)
    out = BSpline(surf.degrees, surf.knots, np.broadcast_to(n, surf.shape + (3,)).copy())
    tube = hermite_tube(a, Face(surf, out, face_space(P.spline, b.face), None), beta=b.beta if beta is None else beta)
    return tube.geometry, tube_space(tube)
