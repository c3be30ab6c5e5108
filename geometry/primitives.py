"""Primitive spline shapes and volume constructors.

Every constructor returns a :class:`BSpline` on the parameter domain
``[0, 1]^d`` (unless it takes the domain from its input).  Coordinates are in
model units (e.g. metres).  ``channels`` arguments are ``{name: constant}``
dictionaries, so a material field can be attached at construction.

Conventions for trivariate shells (annulus, revolution): u runs along the
angle, v along the radius, w along the axis (z).
"""

from __future__ import annotations

from math import ceil, cos, pi, sin, tan

import numpy as np

from . import knots as kn
from .bspline import BSpline
from .errors import SplineError
from .faces import FACE_AXIS, FACE_NAMES
from geometry.composition.products import multiply
from geometry.shapes.examples import with_channels, cylinder, duck  # example shapes live in their own module
from .spline import SplineFunction
from .errors import show
from .tolerances import ON_DOMAIN

__all__ = [
    "box",
    "annulus",
    "arc",
    "twisted",
    "tapered",
    "extrude",
    "ruled",
    "skin",
    "revolve",
    "coons_volume",
    "make_compatible",
    "refined",
    "duck",
    "cylinder",
]


def refined(spline: BSpline, elements) -> BSpline:
    """Insert uniform knots so each direction has ``elements[k]`` equal spans per existing span."""
    out = spline
    for k, ne in enumerate(elements):
        ne = int(ne)
        if ne < 1:
            raise SplineError(f"element count along direction {k} must be >= 1, got {ne}")
        if ne > 1:
            b = out.breakpoints(k)
            new = (b[:-1, None] + (b[1:] - b[:-1])[:, None] * (np.arange(1, ne) / ne)).ravel()
            out, _ = out.insert_knots(k, new)
    return out


def box(size=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), degrees=(1, 1, 1), elements=(1, 1, 1), channels=None) -> BSpline:
    """Axis-aligned box ``origin + [0, size]`` as a trivariate (identity map when defaults)."""
    size = np.asarray(size, float)
    origin = np.asarray(origin, float)
    if size.shape != (3,) or np.any(~np.isfinite(size)) or np.any(size <= 0):
        raise SplineError(f"box size must be three positive numbers, got {size.tolist()}")
    g = np.stack(np.meshgrid([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], indexing="ij"), axis=-1)
    cp, names = with_channels(origin + g * size, channels)
    U = kn.uniform_knots(1, 1)
    out = BSpline((1, 1, 1), [U, U, U], cp, channels=names)
    out = out.elevate_to(degrees)
    return refined(out, elements)


def arc(radius: float, angle: float, start: float = 0.0, exact: bool = True):
    """Planar circular arc (z = 0) as (degree, knots, points (n, 3), weights or None).

    ``exact``: quadratic NURBS, one segment per <= 90 degrees (exact circle).
    Otherwise a cubic polynomial B-spline, one C1 segment per <= 90 degrees,
    with the standard ``4/3 tan(theta/4)`` handles (radial error 2.7e-4 r for
    90-degree segments, smaller for shorter ones).
    """
    if not (np.isfinite(angle) and 0 < angle <= 2 * pi + ON_DOMAIN):
        raise SplineError(f"arc angle must be in (0, 2 pi] radians, got {show(angle)}")
    if not (np.isfinite(radius) and radius > 0):
        raise SplineError(f"arc radius must be positive, got {show(radius)}")
    nseg = max(1, ceil(angle / (pi / 2) - 1e-9))
    theta = angle / nseg
    breaks = np.linspace(0.0, 1.0, nseg + 1)
    if exact:
        pts, w = [], []
        for s in range(nseg):
            a0 = start + s * theta
            am = a0 + theta / 2
            if s == 0:
                pts.append([cos(a0), sin(a0)]); w.append(1.0)
            r = 1.0 / cos(theta / 2)
            pts.append([r * cos(am), r * sin(am)]); w.append(cos(theta / 2))
            pts.append([cos(a0 + theta), sin(a0 + theta)]); w.append(1.0)
        knots = np.concatenate([[0, 0, 0], np.repeat(breaks[1:-1], 2), [1, 1, 1]])
        P = radius * np.array(pts)
        return 2, knots, np.column_stack([P, np.zeros(len(P))]), np.array(w)
    k = 4.0 / 3.0 * tan(theta / 4)
    pts = []
    for s in range(nseg):
        a0 = start + s * theta
        a1 = a0 + theta
        c0, c1 = np.array([cos(a0), sin(a0)]), np.array([cos(a1), sin(a1)])
        t0, t1 = np.array([-sin(a0), cos(a0)]), np.array([-sin(a1), cos(a1)])
        if s == 0:
            pts.append(c0)
        pts += [c0 + k * t0, c1 - k * t1, c1]
    knots = np.concatenate([[0, 0, 0, 0], np.repeat(breaks[1:-1], 3), [1, 1, 1, 1]])
    P = radius * np.array(pts)
    return 3, knots, np.column_stack([P, np.zeros(len(P))]), None


def annulus(
    r_inner: float = 0.5,
    r_outer: float = 1.0,
    height: float = 1.0,
    angle: float = pi / 2,
    start: float = 0.0,
    exact: bool = True,
    elements=(1, 1, 1),
    channels=None,
) -> BSpline:
    """Cylindrical shell sector: u along the angle, v from ``r_inner`` to ``r_outer``, w along z.

    ``exact=True`` gives the exact NURBS (quadratic in u), otherwise a cubic
    polynomial approximation (see :func:`arc`).  ``angle`` in radians, up to a
    full turn (then the u-ends coincide).
    """
    if not (0 < r_inner < r_outer) or not np.isfinite(r_outer):
        raise SplineError(f"annulus needs 0 < r_inner < r_outer, got r_inner={show(r_inner)}, r_outer={show(r_outer)}")
    if not (np.isfinite(height) and height > 0):
        raise SplineError(f"annulus height must be positive, got {show(height)}")
    p, U, P, w = arc(1.0, angle, start, exact)
    radii = np.array([r_inner, r_outer])
    z = np.array([0.0, height])
    cp = np.empty((len(P), 2, 2, 3))
    cp[..., 0] = P[:, None, None, 0] * radii[None, :, None]
    cp[..., 1] = P[:, None, None, 1] * radii[None, :, None]
    cp[..., 2] = z[None, None, :]
    W = None if w is None else np.broadcast_to(w[:, None, None], cp.shape[:-1])
    cp, names = with_channels(cp, channels)
    L = kn.uniform_knots(1, 1)
    out = BSpline((p, 1, 1), [U, L, L], cp, W, names)
    return refined(out, elements)


def twisted(spline: BSpline, angle: float, axis_point=(0.0, 0.0)) -> BSpline:
    """Twist about the vertical axis through ``axis_point`` (x, y).

    Each control point is rotated by ``angle * (z - z_min) / (z_max - z_min)``
    radians.  This twists the control net, the usual modelling operation (the
    result is smooth and twisted; it is not the exact pointwise rotation of
    the surface, which no polynomial of the same degree can represent).
    """
    cp = spline.control_points.copy()
    z = cp[..., 2]
    zr = z.max() - z.min()
    if zr <= 0:
        raise SplineError("twisted() needs a spline with extent along z")
    t = angle * (z - z.min()) / zr
    c = np.asarray(axis_point, float)
    x, y = cp[..., 0] - c[0], cp[..., 1] - c[1]
    cp[..., 0] = c[0] + np.cos(t) * x - np.sin(t) * y
    cp[..., 1] = c[1] + np.sin(t) * x + np.cos(t) * y
    return BSpline(spline.degrees, spline.knots, cp, spline.weights, spline.channels)


def _scale_along(spline: BSpline, direction: int, factor: SplineFunction, components) -> BSpline:
    """Multiply the given components by a univariate factor of parameter ``direction`` (exact)."""
    hom = np.moveaxis(spline.homogeneous, direction, 0)
    rest = hom.shape[1:]
    U = spline.knots[direction]
    p = spline.degrees[direction]
    flat = SplineFunction((p,), [U], hom.reshape(hom.shape[0], -1))
    scaled = multiply(flat, factor)  # every component times the factor
    elevated = flat.elevate(0, factor.degrees[0])
    mask = np.zeros(rest, bool)
    mask[..., list(components)] = True
    new = np.where(mask.reshape(1, -1), scaled.coefficients, elevated.coefficients)
    if not np.array_equal(scaled.knots[0], elevated.knots[0]):
        raise SplineError("internal: product and elevation spaces differ")
    new = np.moveaxis(new.reshape((new.shape[0],) + rest), 0, direction)
    degrees = list(spline.degrees)
    degrees[direction] = scaled.degrees[0]
    knots = list(spline.knots)
    knots[direction] = scaled.knots[0]
    return BSpline._from_hom(degrees, knots, new, spline.is_rational, channels=spline.channels)


def tapered(spline: BSpline, top_scale: float, axis_point=(0.0, 0.0), direction: int = 2) -> BSpline:
    """Scale x, y about the vertical axis linearly from 1 (parameter start) to ``top_scale`` (end).

    Exact: the coordinates are multiplied by the linear function of the
    ``direction`` parameter, raising that degree by one.
    """
    if not (np.isfinite(top_scale) and top_scale > 0):
        raise SplineError(f"top_scale must be positive, got {show(top_scale)}")
    c = np.asarray(axis_point, float)
    moved = spline.translate([-c[0], -c[1], 0.0])
    U = spline.knots[direction]
    f = SplineFunction((1,), [[U[0], U[0], U[-1], U[-1]]], [[1.0], [top_scale]])
    return _scale_along(moved, direction, f, components=[0, 1]).translate([c[0], c[1], 0.0])


def extrude(surface: BSpline, vector) -> BSpline:
    """Trivariate swept linearly from ``surface`` (w = 0) to ``surface + vector`` (w = 1)."""
    if surface.dim != 2:
        raise SplineError(f"extrude needs a surface, got a {surface.dim}-variate spline")
    v = np.asarray(vector, float)
    if v.shape != (3,) or not np.any(v):
        raise SplineError(f"extrusion vector must be a non-zero 3-vector, got {show(vector)}")
    top = surface.translate(v)
    return ruled(surface, top)


def _unify(items):
    """Common degree and knot vector for (spline, direction) pairs (exact).

    Every spline is elevated to the largest degree along its direction, then
    every knot vector gets the union of the breakpoints with their largest
    multiplicity.  The directions' domains must already agree.  Returns the
    splines in the same order.
    """
    p = max(s.degrees[k] for s, k in items)
    items = [(s.elevate(k, p - s.degrees[k]), k) for s, k in items]
    target = {}
    for s, k in items:
        vals, mults = kn.breakpoints(s.knots[k])
        for v, m in zip(vals, mults):
            target[v] = max(target.get(v, 0), m)
    out = []
    for s, k in items:
        vals, mults = kn.breakpoints(s.knots[k])
        have = dict(zip(vals, mults))
        ins = [v for v, m in target.items() for _ in range(m - have.get(v, 0))]
        out.append(s.insert_knots(k, ins)[0] if ins else s)
    return out


def make_compatible(splines, directions=None):
    """Bring splines of equal parametric dimension to common degrees and knot vectors.

    Domains are first mapped onto the first spline's domain, then degrees are
    raised to the maximum and knot vectors merged (exact).
    """
    splines = list(splines)
    d = splines[0].dim
    if any(s.dim != d for s in splines):
        raise SplineError("make_compatible needs splines of the same parametric dimension")
    directions = range(d) if directions is None else directions
    dom = splines[0].domain.copy()
    out = []
    for s in splines:
        box = s.domain.copy()
        for k in directions:
            box[k] = dom[k]
        out.append(s.reparametrize(box))
    for k in directions:
        out = _unify([(s, k) for s in out])
    return out


def _stack(layers, degree: int, knots=None) -> BSpline:
    """Trivariate whose w-layers of control points are the (compatible) surfaces' nets."""
    layers = make_compatible(layers)
    channels = layers[0].channels
    if any(s.channels != channels for s in layers):
        raise SplineError("surfaces to stack must carry the same channels")
    n = len(layers)
    if knots is None:
        knots = kn.uniform_knots(degree, n - degree)
    rational = any(s.is_rational for s in layers)
    hom = np.stack(
        [s.homogeneous if s.is_rational or not rational else np.concatenate([s.homogeneous, np.ones(s.shape + (1,))], -1) for s in layers],
        axis=2,
    )
    s0 = layers[0]
    return BSpline._from_hom(s0.degrees + (degree,), list(s0.knots) + [knots], hom, rational, channels=channels)


def ruled(bottom: BSpline, top: BSpline) -> BSpline:
    """Trivariate linear in w between two surfaces (made compatible first).

    Rational surfaces with different weights are brought to a common
    denominator (exact, degree grows); equal weights are stacked directly.
    """
    if bottom.dim != 2 or top.dim != 2:
        raise SplineError("ruled() needs two surfaces")
    a, b = make_compatible([bottom, top])
    if a.is_rational != b.is_rational or (a.is_rational and not np.allclose(a.weights, b.weights, rtol=1e-14)):
        wa = SplineFunction(a.degrees, a.knots, (a.weights if a.is_rational else np.ones(a.shape))[..., None])
        wb = SplineFunction(b.degrees, b.knots, (b.weights if b.is_rational else np.ones(b.shape))[..., None])
        na = SplineFunction(a.degrees, a.knots, a.homogeneous[..., : a.n_components])
        nb = SplineFunction(b.degrees, b.knots, b.homogeneous[..., : b.n_components])
        A, B, W = multiply(na, wb), multiply(nb, wa), multiply(wa, wb)
        a = BSpline(A.degrees, A.knots, A.coefficients / W.coefficients, W.coefficients[..., 0], a.channels)
        b = BSpline(B.degrees, B.knots, B.coefficients / W.coefficients, W.coefficients[..., 0], b.channels)
    return _stack([a, b], 1)


def skin(surfaces, degree: int | None = None) -> BSpline:
    """Skinning by stacking control meshes (Massarwi et al. 2018, Fig. 2): surfaces become the w-layers.

    Intermediate surfaces are *not* interpolated (as in Massarwi et al. 2018).  ``degree``
    along w defaults to ``min(len(surfaces) - 1, 3)``; the w knot vector is
    open uniform on [0, 1].
    """
    surfaces = list(surfaces)
    if len(surfaces) < 2 or any(s.dim != 2 for s in surfaces):
        raise SplineError("skin() needs at least two surfaces")
    degree = min(len(surfaces) - 1, 3) if degree is None else int(degree)
    if not 1 <= degree <= len(surfaces) - 1:
        raise SplineError(f"skinning degree must be in 1..{len(surfaces) - 1}, got {degree}")
    return _stack(surfaces, degree)


def revolve(profile: BSpline, angle: float = 2 * pi, start: float = 0.0) -> BSpline:
    """Exact volume of revolution of a surface lying in the xz half-plane (x >= 0) about z.

    u is the angular direction (quadratic NURBS), v and w the profile's.
    """
    if profile.dim != 2:
        raise SplineError("revolve() needs a surface profile")
    P = profile.points
    if np.max(np.abs(P[..., 1])) > ON_DOMAIN * max(1.0, np.abs(P).max()) or np.min(P[..., 0]) < 0:
        raise SplineError("revolve() profile must lie in the xz half-plane (y = 0, x >= 0)")
    p, U, A, wa = arc(1.0, angle, start, exact=True)
    wp = profile.weights if profile.is_rational else np.ones(profile.shape)
    r = P[..., 0]
    cp = np.empty((len(A),) + profile.shape + (profile.n_components,))
    cp[..., 0] = A[:, None, None, 0] * r[None]
    cp[..., 1] = A[:, None, None, 1] * r[None]
    cp[..., 2] = P[None, ..., 2]
    cp[..., 3:] = profile.control_points[None, ..., 3:]
    W = wa[:, None, None] * wp[None]
    return BSpline((p,) + profile.degrees, [U] + list(profile.knots), cp, W, profile.channels)


def coons_volume(faces: dict, tol: float = 1e-9) -> BSpline:
    """Trivariate Boolean sum (volumetric Coons patch) from six boundary surfaces.

    ``faces`` maps ``umin, umax, vmin, vmax, wmin, wmax`` to polynomial
    surfaces parametrised like :meth:`BSpline.boundary` returns them
    (umin/umax over (v, w), vmin/vmax over (u, w), wmin/wmax over (u, v)).
    The result is ``P_u + P_v + P_w - P_uv - P_vw - P_uw + P_uvw`` computed on
    control nets with Greville abscissae, which is exact because splines
    reproduce linear functions.  Faces must agree on shared edges.
    """
    names = FACE_NAMES
    missing = [n for n in names if n not in faces]
    if missing:
        raise SplineError(f"coons_volume needs all six faces; missing {missing}")
    F = {n: faces[n] for n in names}
    for n, s in F.items():
        if s.dim != 2:
            raise SplineError(f"face {n} must be a surface")
        if s.is_rational:
            raise SplineError(f"face {n} is rational; coons_volume supports polynomial faces")
    F = {n: s.reparametrize([[0, 1], [0, 1]]) for n, s in F.items()}
    # face parameter directions -> volume directions
    dirs = {n: tuple(d for d in range(3) if d != FACE_AXIS[n][0]) for n in names}
    deg, kv = [], []
    for k in range(3):
        users = [(n, dirs[n].index(k)) for n in names if k in dirs[n]]
        for (n, _), s in zip(users, _unify([(F[n], j) for n, j in users])):
            F[n] = s
        deg.append(F[users[0][0]].degrees[users[0][1]])
        kv.append(F[users[0][0]].knots[users[0][1]])
    channels = F["umin"].channels
    if any(s.channels != channels for s in F.values()):
        raise SplineError("all six faces must carry the same channels")
    C = {n: s.control_points for n, s in F.items()}
    scale = max(np.abs(c).max() for c in C.values()) + 1.0
    pairs = [("umin", "vmin", C["umin"][0, :], C["vmin"][0, :]), ("umin", "wmin", C["umin"][:, 0], C["wmin"][0, :]),
             ("vmin", "wmin", C["vmin"][:, 0], C["wmin"][:, 0]), ("umax", "vmax", C["umax"][-1, :], C["vmax"][-1, :]),
             ("umax", "wmax", C["umax"][:, -1], C["wmax"][-1, :]), ("vmax", "wmax", C["vmax"][:, -1], C["wmax"][:, -1]),
             ("umin", "vmax", C["umin"][-1, :], C["vmax"][0, :]), ("umax", "vmin", C["umax"][0, :], C["vmin"][-1, :]),
             ("umin", "wmax", C["umin"][:, -1], C["wmax"][0, :]), ("umax", "wmin", C["umax"][:, 0], C["wmin"][-1, :]),
             ("vmin", "wmax", C["vmin"][:, -1], C["wmax"][:, 0]), ("vmax", "wmin", C["vmax"][:, 0], C["wmin"][:, -1])]
    for a, b, ea, eb in pairs:
        if ea.shape != eb.shape or np.abs(ea - eb).max() > tol * scale:
            raise SplineError(f"faces {a} and {b} do not agree on their shared edge; fix the boundary surfaces")
    g = [(kn.greville(kv[k], deg[k]) - kv[k][0]) / (kv[k][-1] - kv[k][0]) for k in range(3)]
    gu, gv, gw = (x.reshape(s) for x, s in zip(g, [(-1, 1, 1, 1), (1, -1, 1, 1), (1, 1, -1, 1)]))
    Pu = (1 - gu) * C["umin"][None] + gu * C["umax"][None]
    Pv = (1 - gv) * C["vmin"][:, None] + gv * C["vmax"][:, None]
    Pw = (1 - gw) * C["wmin"][:, :, None] + gw * C["wmax"][:, :, None]
    # edges along w (u, v fixed), along v (u, w fixed), along u (v, w fixed)
    Ew = {(i, j): C["umin" if i == 0 else "umax"][0 if j == 0 else -1, :] for i in (0, 1) for j in (0, 1)}
    Ev = {(i, k): C["umin" if i == 0 else "umax"][:, 0 if k == 0 else -1] for i in (0, 1) for k in (0, 1)}
    Eu = {(j, k): C["vmin" if j == 0 else "vmax"][:, 0 if k == 0 else -1] for j in (0, 1) for k in (0, 1)}
    lu, lv, lw = [(1 - gu), gu], [(1 - gv), gv], [(1 - gw), gw]
    Puv = sum(lu[i] * lv[j] * Ew[i, j][None, None] for i in (0, 1) for j in (0, 1))
    Puw = sum(lu[i] * lw[k] * Ev[i, k][None, :, None] for i in (0, 1) for k in (0, 1))
    Pvw = sum(lv[j] * lw[k] * Eu[j, k][:, None, None] for j in (0, 1) for k in (0, 1))
    corner = {(i, j, k): C["umin" if i == 0 else "umax"][0 if j == 0 else -1, 0 if k == 0 else -1]
              for i in (0, 1) for j in (0, 1) for k in (0, 1)}
    Puvw = sum(lu[i] * lv[j] * lw[k] * corner[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1))
    cp = Pu + Pv + Pw - Puv - Puw - Pvw + Puvw
    return BSpline(tuple(deg), kv, cp, channels=channels)
