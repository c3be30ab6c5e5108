"""Three concentric trimmed through-cylinders: the trimmed-surface tile of Elber 2017, Fig. 7.

Three circular cylinders of radius r about the cell's centre, along x, y and
z, each running through the cell from wall to wall.  Each cylinder is kept
where it lies outside the other two, so together they bound the solid
union of the three (outward normals) and open onto the six cell walls in
circles of radius r: neighbouring cells continue each other's tubes.

The trimming curves are exact.  On the z cylinder (x, y, z) = (r cos a,
r sin a, t) about the centre, outside the x cylinder means t^2 >= r^2
cos^2 a and outside the y cylinder t^2 >= r^2 sin^2 a, so its upper half
keeps t >= r max(|cos a|, |sin a|) (Steinmetz curves, ellipses in space).
With the circle's rational quadratic parametrisation a(s) (four quarter
arcs, 45 degrees at their parameter midpoints by symmetry), max(|cos|,
|sin|) is on each eighth of [0, 1] one coordinate of the circle, a rational
quadratic x(s) = N(s) / w(s); the loop (s, x(s)) in the surface's parameters
is the rational cubic with numerators (s w(s), N(s)) over w(s), exactly.
Every cylinder is two halves (t below and above the centre), each a
:class:`geometry.TrimmedSurface` with one loop; the other two cylinders are
cyclic permutations of the coordinates (orientation kept).  Kept area per
cell: 6 r (pi - 4 sqrt(2) r).
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline, TrimmedSurface
from geometry.errors import show
from geometry.primitives import arc
from geometry.shapes.trimmed import join_curves, reversed_curve

from tiling.errors import TilingError
from tiling.tile import Tile
from geometry.numbers import is_real

__all__ = ["through_cylinders", "through_cylinders_area"]

# per eighth of the circle: which coordinate is max(|cos|, |sin|), and its sign
_WHICH = (0, 1, 1, 0, 0, 1, 1, 0)
_SIGN = (1, 1, 1, -1, -1, -1, -1, 1)


def _segment(a, b) -> BSpline:
    return BSpline((1,), [[0.0, 0.0, 1.0, 1.0]], np.array([[a[0], a[1], 0.0], [b[0], b[1], 0.0]]))


def _trim_graph(circle: BSpline, centre: float, sign: int) -> BSpline:
    """The curve (s, centre + sign r max(|cos a(s)|, |sin a(s)|)), s from 0 to 1: eight rational cubics."""
    pieces = []
    for j in range(8):
        a, b = j / 8, (j + 1) / 8
        e = circle.extract(np.array([[a, b]]))
        w = e.weights.ravel()
        v = _SIGN[j] * e.control_points[:, _WHICH[j]]
        W = np.array([w[0], (w[0] + 2 * w[1]) / 3, (2 * w[1] + w[2]) / 3, w[2]])  # w elevated to degree 3
        N = w * v
        V = np.array([N[0], (N[0] + 2 * N[1]) / 3, (2 * N[1] + N[2]) / 3, N[2]]) / W
        S = np.array([a * w[0], (2 * a * w[1] + b * w[0]) / 3, (a * w[2] + 2 * b * w[1]) / 3, b * w[2]]) / W  # s w(s)
        cp = np.column_stack([S, centre + sign * V, np.zeros(4)])
        pieces.append(BSpline((3,), [np.r_[[a] * 4, [b] * 4]], cp, W))
    return join_curves(pieces)


def _half(circle: BSpline, r: float, upper: bool, roll: int) -> TrimmedSurface:
    """One half of a cylinder (t in [0.5, 1] or [0, 0.5]) with its loop; ``roll`` permutes the axes cyclically."""
    t0, t1 = (0.5, 1.0) if upper else (0.0, 0.5)
    P = circle.control_points
    cp = np.zeros((len(P), 2, 3))
    cp[..., 0] = 0.5 + P[:, None, 0]
    cp[..., 1] = 0.5 + P[:, None, 1]
    cp[..., 2] = np.array([t0, t1])[None, :]
    cp = np.roll(cp, roll, axis=-1)
    w = np.repeat(circle.weights.reshape(-1, 1), 2, axis=1)
    surface = BSpline((2, 1), [circle.knots[0], np.array([t0, t0, t1, t1])], cp, w)
    if upper:  # the graph from s = 0 to 1, up the seam at s = 1, back along the wall, down the seam at s = 0
        loop = [_trim_graph(circle, 0.5, 1), _segment((1, 0.5 + r), (1, 1)), _segment((1, 1), (0, 1)),
                _segment((0, 1), (0, 0.5 + r))]
    else:
        loop = [_segment((0, 0), (1, 0)), _segment((1, 0), (1, 0.5 - r)),
                reversed_curve(_trim_graph(circle, 0.5, -1)), _segment((0, 0.5 - r), (0, 0))]
    return TrimmedSurface(surface, [join_curves(loop)])


def through_cylinders(radius: float = 0.25) -> Tile:
    """The Fig. 7 tile of Elber 2017: three trimmed through-cylinders (see the module notes), six
    :class:`geometry.TrimmedSurface` members; ``radius`` in cell units, in (0, 0.5)."""
    if not (is_real(radius)
            and np.isfinite(radius) and 0 < radius < 0.5):
        raise TilingError(f"through_cylinders: radius must be a number in (0, 0.5) (cell units), got {show(radius)}")
    p, U, P, w = arc(float(radius), 2 * np.pi)
    circle = BSpline((p,), [U], P, w)
    members = [_half(circle, float(radius), up, roll) for roll in (0, 1, 2) for up in (False, True)]
    return Tile(members, name=f"through_cylinders({radius:g})")


def through_cylinders_area(radius: float) -> float:
    """Exact area of :func:`through_cylinders` in the unit cell: 6 r (pi - 4 sqrt(2) r)."""
    return 6.0 * radius * (np.pi - 4.0 * np.sqrt(2.0) * radius)
