"""Sweeps of a closed section along a B-spline axis, with a rotation-minimising frame, to a stated tolerance.

Elber 2017 (Section 4 and Fig. 10) and Massarwi et al. 2018 (Section 1): composing a
beam's round section into a map distorts it; composing only the *axis* curve (exact)
and sweeping a circle along the deformed axis keeps the section circular "as precise
as desired (and allowed by the sweep operation)".

The sweep ``S(u, v) = A(v) + x(u) N1(v) + y(u) N2(v)`` of a planar section
``(x(u), y(u))`` (a NURBS curve, e.g. the exact circle) along the axis ``A`` with a
frame ``(T, N1, N2)`` is, for each section control point ``(x_i, y_i)``, the curve
``C_i(v) = A(v) + x_i N1(v) + y_i N2(v)`` weighted by the section's rational basis:
``S = sum_i R_i(u) C_i(v)``.  The frame is not polynomial, so each ``C_i`` is
interpolated by a cubic B-spline in v; since the ``R_i`` are non-negative and sum to
one, every point of S lies within ``max_i |C_i - C_i^interp|`` of the exact sweep.

The frame is the rotation-minimising frame of the double-reflection method (Wang,
Juttler, Zheng and Liu 2008), formed as a prefix product of the per-step rotations
(a log-depth scan of 3 x 3 matrix products, no loop per sample).  Each frame is exactly
orthogonal to the axis tangent, so every section of the interpolated sweep is, at its
nodes, the exact circle in the normal plane, and in between within the measured error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import knots as kn
from geometry.bspline import BSpline
from geometry.errors import SplineError, show
from geometry.shapes.fitting import c0_joints, evaluate, interpolate, span_nodes
from geometry.primitives import arc
from geometry.numbers import TINY, is_real

__all__ = ["Sweep", "sweep", "circle", "frames", "section_error", "kinks", "points_and_tangents", "box_sweep", "trefoil"]

#: interpolation nodes per axis knot span to start from, and the most the refinement goes to
_START, _MAX_NODES = 4, 1 << 14
#: a tangent turning by more than this across one of the axis's knots is a kink (radians)
_KINK = 1e-6


@dataclass
class Sweep:
    """A swept surface and what it is measured to be.

    surface : BSpline surface, u along the section (its parametrisation), v along the axis
    axis : the axis curve (exact)
    radius : the section's radius for a circle, else None
    error : the largest distance from the surface to the exact sweep measured at the
        check points (model units); at most ``tolerance``
    tolerance : what was asked for (model units)
    """

    surface: BSpline
    axis: BSpline
    radius: float | None
    error: float
    tolerance: float

    def caps(self) -> list[BSpline]:
        """Two exact hemispheres closing a circular tube at its ends (rational biquadratic surfaces).

        Each hemisphere's rim is the tube's end section with the same control points and
        parametrisation, so tube and caps meet exactly; the pole is a collapsed edge.
        Tube and caps together bound a capsule (a closed surface of genus 0); at a lattice's
        nodes the caps of the struts that meet there are the same sphere.
        """
        if self.radius is None:
            raise SplineError("round caps close circular sweeps only; this sweep has a general section")
        s = self.surface
        ends, tangent = points_and_tangents(self.axis, self.axis.domain[0])
        out = []
        for rim, centre, t_out in ((s.points[:, 0], ends[0], -tangent[0]), (s.points[:, -1], ends[1], tangent[1])):
            rho = np.array([1.0, 1.0, 0.0])  # the quarter meridian from the rim to the pole: (rho, h) control
            h = np.array([0.0, 1.0, 1.0]) * self.radius  # points (1, 0), (1, 1), (0, 1), weights 1, 1/sqrt 2, 1
            P = centre + rho[None, :, None] * (rim - centre)[:, None, :] + h[None, :, None] * t_out
            w = np.outer(s.weights[:, 0], [1.0, np.sqrt(0.5), 1.0])
            out.append(BSpline((2, 2), [s.knots[0], [0, 0, 0, 1, 1, 1]], P, w))
        return out

    def closed(self) -> list[BSpline]:
        """The tube and its two round caps: a closed surface (:meth:`caps`)."""
        return [self.surface] + self.caps()


def circle(radius: float) -> BSpline:
    """The exact circle of ``radius`` in the (x, y) plane: a quadratic NURBS of four arcs (9 control points)."""
    p, U, P, w = arc(radius, 2 * np.pi)
    return BSpline((p,), [U], P, w)


def frames(axis: BSpline, v: np.ndarray):
    """Rotation-minimising frames along ``axis`` at increasing parameters ``v`` (n,).

    Returns ``(points, T, N1, N2)``, each (n, 3): axis points, unit tangents and two unit
    normals (N2 = T x N1) by the double-reflection method; N1 starts at the unit vector
    orthogonal to T(v_0) closest to the axis of T's smallest component.
    """
    X, T = points_and_tangents(axis, v)
    e = np.zeros(3)
    e[np.argmin(np.abs(T[0]))] = 1.0
    r0 = e - (e @ T[0]) * T[0]
    r0 /= np.linalg.norm(r0)
    M = _step_rotations(X, T)  # (n - 1, 3, 3): frame j+1 = M_j frame j
    P = _prefix_products(M)  # (n - 1, 3, 3): M_j ... M_0
    N1 = np.vstack([r0, np.einsum("nij,j->ni", P, r0)])
    N1 -= np.einsum("ni,ni->n", N1, T)[:, None] * T  # remove the rounding drift: exactly normal to T
    N1 /= np.linalg.norm(N1, axis=1)[:, None]
    return X, T, N1, np.cross(T, N1)


def points_and_tangents(curve: BSpline, v) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, 3) and unit tangents (n, 3) of ``curve`` at parameters ``v`` (n,); refuses a point of zero
    speed (a cusp, or repeated control points), where no tangent exists."""
    vals = curve.derivatives(np.asarray(v, float).reshape(-1, 1), 1)
    X, dX = vals[(0,)][:, :3], vals[(1,)][:, :3]
    speed = np.linalg.norm(dX, axis=1)
    if np.any(speed <= 1e-14 * max(1.0, float(np.abs(X).max()))):
        raise SplineError(f"the axis has zero speed at v = {float(np.ravel(v)[np.argmin(speed)]):.6g}; a sweep "
                          "needs a regular axis curve (no cusp, no repeated control points)")
    return X, dX / speed[:, None]


def _reflection(v):
    """Householder reflections I - 2 v v^T / |v|^2 (n, 3, 3); the identity where v vanishes."""
    c = np.einsum("ni,ni->n", v, v)
    scale = np.where(c > TINY, 2.0 / np.where(c > TINY, c, 1.0), 0.0)
    return np.eye(3)[None] - scale[:, None, None] * v[:, :, None] * v[:, None, :]


def _step_rotations(X, T):
    """Double reflection: reflect in the bisector plane of x_j, x_{j+1}, then in the one taking the
    reflected tangent to t_{j+1}; the product is a rotation taking t_j to t_{j+1}."""
    H1 = _reflection(X[1:] - X[:-1])
    tL = np.einsum("nij,nj->ni", H1, T[:-1])
    return np.einsum("nij,njk->nik", _reflection(T[1:] - tL), H1)


def _prefix_products(M):
    """``P_j = M_j M_{j-1} ... M_0`` for all j by doubling (Hillis-Steele scan): log2(n) batched products."""
    P = M.copy()
    shift = 1
    while shift < len(P):
        P[shift:] = np.einsum("nij,njk->nik", P[shift:], P[:-shift])
        shift *= 2
    return P


def kinks(axis: BSpline) -> np.ndarray:
    """Interior breakpoints of the axis where the tangent direction jumps."""
    b = axis.breakpoints(0)[1:-1]
    if not len(b):
        return b
    eps = 1e-9 * (axis.domain[0, 1] - axis.domain[0, 0])
    t_lo = axis.jacobian((b - eps)[:, None])[:, :3, 0]
    t_hi = axis.jacobian((b + eps)[:, None])[:, :3, 0]
    cos = np.einsum("ni,ni->n", t_lo, t_hi) / (np.linalg.norm(t_lo, axis=1) * np.linalg.norm(t_hi, axis=1))
    return b[cos < np.cos(_KINK + 1e-6)]


def _nodes(axis: BSpline, per_span: int) -> np.ndarray:
    return span_nodes(axis.breakpoints(0), per_span)


def _section_points(frame, sec: np.ndarray) -> np.ndarray:
    """Control curves' values C_i(v) at the frames: (n, m, 3) for section control points ``sec`` (m, 2)."""
    X, _, N1, N2 = frame
    return X[:, None, :] + sec[None, :, 0, None] * N1[:, None, :] + sec[None, :, 1, None] * N2[:, None, :]


def section_error(surface: BSpline, axis: BSpline, radius: float, u, v) -> np.ndarray:
    """Distance from ``surface(u, v)`` to the circle of ``radius`` about ``axis(v)`` in its normal plane (N,)."""
    S = surface.evaluate(np.column_stack([u, v]))[:, :3]
    A, T = points_and_tangents(axis, v)
    d = S - A
    along = np.einsum("ni,ni->n", d, T)
    across = np.linalg.norm(d - along[:, None] * T, axis=1)
    return np.hypot(along, across - radius)


def sweep(axis: BSpline, radius: float | None = None, section: BSpline | None = None,
          tolerance: float | None = None) -> Sweep:
    """Sweep a closed section along ``axis`` with a rotation-minimising frame, within ``tolerance``.

    axis : a regular BSpline curve (model units), e.g. a tile's axis composed into a map
    radius : sweep the exact circle of this radius (model units); or
    section : a closed planar NURBS curve in (x, y) (z ignored), swept in the frame's (N1, N2) plane
    tolerance : the largest distance allowed between the result and the exact sweep
        (model units; default 1e-4 of the section's size)

    The result's v direction is cubic, with knots refined until the control curves'
    interpolation error, measured at the nodes and 7 check points between consecutive
    nodes, is within the tolerance; ``Sweep.error`` reports it.  The axis must be tangent-continuous (a kink
    would open the tube): split it at the kink and sweep the pieces.

    >>> from geometry import BSpline
    >>> axis = BSpline((2,), [[0, 0, 0, 1, 1, 1]], [[0, 0, 0], [1, 0, 1], [2, 0, 0]])
    >>> s = sweep(axis, radius=0.1, tolerance=1e-6)
    >>> s.surface.degrees, s.error <= 1e-6
    ((2, 3), True)
    """
    if not isinstance(axis, BSpline) or axis.dim != 1:
        raise SplineError(f"sweep needs the axis as a BSpline curve, got {show(axis)}")
    if (radius is None) == (section is None):
        raise SplineError("sweep needs exactly one of radius (a circle) and section (a closed planar curve)")
    if section is None:
        if not (is_real(radius) and np.isfinite(radius) and radius > 0):
            raise SplineError(f"sweep radius must be a positive length (model units), got {show(radius)}")
        section = circle(float(radius))
    elif not isinstance(section, BSpline) or section.dim != 1:
        raise SplineError(f"sweep section must be a closed planar BSpline curve, got {show(section)}")
    cp = section.points
    size = float(np.ptp(cp[:, :2], axis=0).max())
    if not np.allclose(cp[0, :2], cp[-1, :2], atol=1e-12 * max(size, 1.0)) or size <= 0:
        raise SplineError("sweep section must be a closed curve (first and last control points equal) of "
                          "positive size in the (x, y) plane")
    tol = 1e-4 * size if tolerance is None else tolerance
    if not (is_real(tol) and np.isfinite(tol) and tol > 0):
        raise SplineError(f"sweep tolerance must be a positive length (model units), got {show(tolerance)}")
    bends = kinks(axis)
    if len(bends):
        raise SplineError(f"the axis turns abruptly at v = {bends[0]:.6g} (tangent discontinuity); split it there "
                          "(BSpline.split) and sweep each piece")
    _check_bend(axis, section)
    per = _START
    joints = c0_joints(axis.knots[0], axis.degrees[0])
    while True:
        v = _nodes(axis, per)
        fine = _nodes(axis, 8 * per)  # every node and 7 check points between consecutive nodes
        C = _section_points(frames(axis, fine), cp[:, :2])
        k, t, coef = interpolate(fine[::8], C[::8], joints)
        err = _control_error(k, t, coef, fine, C)
        if err <= tol or len(v) * 2 > _MAX_NODES:
            break
        per *= 2
    if err > tol:
        raise SplineError(f"sweep: {len(v)} interpolation nodes still leave an error of {err:.3g} > tolerance "
                          f"{tol:.3g}; raise the tolerance or simplify the axis")
    surface = _surface(section, k, t, coef)
    return Sweep(surface, axis, None if radius is None else float(radius), err, float(tol))


BEND_MARGIN = 1e-6
"""A section reaching ``r`` from the axis folds where the axis's radius of curvature is r or less: r * curvature
must stay below ``1 - BEND_MARGIN`` at every check point."""


def _check_bend(axis: BSpline, section: BSpline) -> None:
    """Refuse a sweep whose section reaches past the axis's radius of curvature (the tube would fold onto
    itself on the inside of the bend), naming the parameter, the radius of curvature and the section's reach.
    Checked at 32 points per knot span of the axis and 256 of the section."""
    v = _nodes(axis, 32)
    d = axis.derivatives(v[:, None], 2)
    d1, d2 = d[(1,)][:, :3], d[(2,)][:, :3]
    speed = np.linalg.norm(d1, axis=1)
    curvature = np.linalg.norm(np.cross(d1, d2), axis=1) / np.maximum(speed, TINY) ** 3
    t = np.linspace(*section.domain[0], 257)[:-1, None]
    reach = float(np.linalg.norm(section.evaluate(t)[:, :2], axis=1).max())
    i = int(np.argmax(curvature))
    if reach * curvature[i] >= 1.0 - BEND_MARGIN:
        raise SplineError(f"the section reaches {reach:.6g} from the axis, to or past the axis's radius of curvature "
                          f"{1.0 / curvature[i]:.6g} at v = {v[i]:.6g}: the tube would fold onto itself on the "
                          "inside of the bend; use a smaller radius or section, or a gentler axis")


def _control_error(k, t, coef, v, C) -> float:
    """The largest distance between the interpolated control curves and their exact values C (n, m, 3) at v."""
    return float(np.linalg.norm(evaluate(k, t, coef, v) - C, axis=2).max())


def _surface(section: BSpline, k, t, coef) -> BSpline:
    """The tensor-product surface sum_i R_i(u) C_i(v): section basis along u, the control curves along v."""
    P = np.transpose(coef, (1, 0, 2))  # (m, n_v, 3)
    w = None if section.weights is None else np.repeat(section.weights[:, None], P.shape[1], axis=1)
    Us = section.knots[0]
    return BSpline((section.degrees[0], k), [Us, np.asarray(t, float)], P, w)



def box_sweep(axis: BSpline, half_side: float) -> BSpline:
    """A trivariate of square section (side 2 ``half_side``, model units) carried along the curve ``axis`` by
    its rotation-minimising frames (:func:`frames`): lengths (4, 4, n) for an axis of n control points, cubic
    across the section, the axis's knots along w. A map whose tiles follow a curve (Elber 2017, Fig. 4(c))."""
    if not (isinstance(axis, BSpline) and axis.dim == 1 and axis.degrees[0] == 3):
        raise SplineError(f"box_sweep: axis must be a cubic B-spline curve, got {show(axis)}")
    if not (is_real(half_side) and np.isfinite(half_side) and half_side > 0):
        raise SplineError(f"box_sweep: half_side must be a positive number (model units), got {show(half_side)}")
    X, _, N1, N2 = frames(axis, kn.greville(axis.knots[0], 3))
    s = np.linspace(-half_side, half_side, 4)
    P = X[None, None] + s[:, None, None, None] * N1[None, None] + s[None, :, None, None] * N2[None, None]
    U = kn.uniform_knots(3, 1)
    return BSpline((3, 3, 3), [U, U, axis.knots[0]], P)


def trefoil(n: int = 50, half_side: float = 0.25) -> BSpline:
    """The tricubic knot trivariate of Elber 2017, Fig. 4(c): :func:`box_sweep` of half side ``half_side`` along
    the cubic through ``n`` points of the trefoil knot (sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t), t from 0
    to 0.96 of a turn (not quite closed); control lengths (4, 4, n)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 8:
        raise SplineError(f"trefoil: n must be an integer >= 8 (points along the knot), got {show(n)}")
    if not (is_real(half_side) and np.isfinite(half_side) and 0 < half_side < 0.5):
        raise SplineError(f"trefoil: half_side must be a number in (0, 0.5) (the knot's strands are about 1.5 "
                          f"apart), got {show(half_side)}")
    t = np.linspace(0.0, 2 * np.pi * 0.96, int(n))
    points = np.column_stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)])
    return box_sweep(BSpline((3,), [kn.uniform_knots(3, int(n) - 3)], points), half_side)
