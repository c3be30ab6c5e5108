"""Built-in tiles (public API names).

==================== =====================================================
``heat_sink_t1()``   one trivariate, one discontinuity along u: a solid base
                     that splits into 2 fins (Massarwi et al. 2018, Fig. 11, T1)
``heat_sink_t2()``   one trivariate, discontinuities along u and v: a base
                     splitting into 2 x 2 pins (Massarwi et al. 2018, Fig. 11, T2)
``skinned_branching()`` (2, 1)-discontinuity tile skinned from four surfaces,
                     six branch-out faces (Massarwi et al. 2018, Fig. 2)
``fractal()``        three trivariates: a trunk (branch-in S0) and two bent
                     wings whose tops are branch-out S1, S2 (Massarwi et al. 2018, Fig. 3)
``hollow_box()``     six bilinear surfaces, the walls of the cell (Elber 2017, Fig. 2)
``cross()``          seven trivariates: a centre block and six arms reaching
                     every face of the cell; opposite faces match (periodic)
``face_graded_cross()`` a cross with its own arm width on each of the six faces (grading in 3 directions)
``face_graded_heat_sink()`` T2 with the pins' widths given on its four sides (heat sinks graded in u and v)
``hollow_cross()``   24 bilinear surfaces: the walls of the cross's arms, open
                     where the arms meet the cell faces (a surface tile to cap)
``helix()``          a cubic curve winding around the cell's axis (Elber 2017, Fig. 10)
``helical_tubes()``  four bicubic tubes, quarter turns of helices (Elber 2017, Fig. 4(a))
``stitch()``         one sine period through the thickness: stitched fibres (Elber 2017, Fig. 8)
``struts(kind)``     straight beam axes, body-centred (``bcc``) or ``cubic``, for round-strut lattices
``bent_cross()``     the cross at degrees (3, 3, 2) with bent insides (Massarwi et al. 2018, Fig. 10)
``through_cylinders()`` three concentric trimmed through-cylinders, six trimmed
                     surfaces (Elber 2017, Fig. 7; :mod:`tiling.members.cylinders`)
``oblique_tubes()``  square tubes along (1, 0, 1/2), cut by the cell's planes: walls
                     that cross the cell boundary obliquely (:mod:`tiling.sealing.clipping`)
==================== =====================================================

Discontinuity tiles use a C0 knot at w = 0.4 below which both sides of every
discontinuity coincide, so the base is solid material (Massarwi et al. 2018, Section 3.1:
"partial" discontinuities); above it each discontinuity opens a slot.  Their
outer sides stay on the cell walls, so neighbouring tiles share whole faces
(conforming identity interfaces, a solid base plate or ring).  Branch-out
faces are derived from the knot structure (:func:`tiling.discontinuity_branches`).
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline, knots as kn, primitives as pr

from .errors import TilingError
from tiling.sealing.clipping import clip_walls
from tiling.members.cylinders import through_cylinders
from .tile import BranchFace, Tile, discontinuity_branches
from geometry.errors import show
from geometry.tolerances import ON_DOMAIN
from geometry.numbers import is_real

_W_KNOTS = np.array([0, 0, 0, 0.4, 0.4, 1, 1, 1.0])  # quadratic, C0 at 0.4: solid base below
_Z_LAYERS = np.array([0.0, 0.2, 0.4, 0.7, 1.0])  # Greville abscissae of _W_KNOTS: z linear in w
_SPLIT = np.array([0.0, 0.0, 0.0, 0.03, 0.05])  # half-gap opened at each layer


def _split_coordinate(layer_gap: float) -> np.ndarray:
    """Coordinates of the 6 control points across one discontinuity at 0.5 (two quadratic pieces).

    The outer sides stay on the cell walls (0 and 1), so neighbouring tiles share whole faces and
    the base is one solid; the discontinuity opens a slot of width 2 g in the middle.
    """
    g = layer_gap
    return np.array([0.0, (0.5 - g) / 2, 0.5 - g, 0.5 + g, (1.5 + g) / 2, 1.0])


def _disc_knots():
    return np.array([0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1.0])


def heat_sink_t1(scale: float = 0.5) -> Tile:
    """T1: degrees (2, 1, 2); one discontinuity along u; 2 fins (branch-out faces) on top."""
    cp = np.zeros((6, 2, 5, 3))
    for k, (z, g) in enumerate(zip(_Z_LAYERS, _SPLIT)):
        cp[:, :, k, 0] = _split_coordinate(g)[:, None]
        cp[:, :, k, 1] = np.array([0.0, 1.0])[None, :]
        cp[:, :, k, 2] = z
    T = BSpline((2, 1, 2), [_disc_knots(), kn.uniform_knots(1, 1), _W_KNOTS], cp)
    return Tile([T], (0, "wmin"), discontinuity_branches(T), scale=scale, name="heat_sink_t1")


def heat_sink_t2(scale: float = 0.5) -> Tile:
    """T2: degrees (2, 2, 2); discontinuities along u and v; 4 pins (branch-out faces) on top."""
    cp = np.zeros((6, 6, 5, 3))
    for k, (z, g) in enumerate(zip(_Z_LAYERS, _SPLIT)):
        c = _split_coordinate(g)
        cp[:, :, k, 0] = c[:, None]
        cp[:, :, k, 1] = c[None, :]
        cp[:, :, k, 2] = z
    T = BSpline((2, 2, 2), [_disc_knots(), _disc_knots(), _W_KNOTS], cp)
    return Tile([T], (0, "wmin"), discontinuity_branches(T), scale=scale, name="heat_sink_t2")


def face_graded_heat_sink(umin: float = 0.45, umax: float = 0.45, vmin: float = 0.45, vmax: float = 0.45,
                          wmin: float | None = None, wmax: float | None = None) -> Tile:
    """T2 whose pins have their own width on each side of the cell: the width of the pins' tops (a fraction of the
    cell, in (0, 0.5); T2's own is 0.45) along v where the tile meets its ``umin`` and ``umax`` sides, along u
    where it meets ``vmin`` and ``vmax``, linear in between (the control columns' share of the way across), the
    slots tapering to nothing at the base as in T2 (half-gaps 0.6 g and g on its two upper layers).  A side's
    control points depend on that side's value alone, so paved with the values of a field taken on every shared
    wall (:func:`tiling.field_graded`) neighbouring cells meet face to face; the pins become quadrilaterals whose
    widths follow the field across the sink.  ``wmin`` and ``wmax`` are accepted (a field gives every wall a
    value) and shape nothing: the bottom is the solid base, the top the pins' ends.  Its bottom is T2's branch-in
    face (unchanged by the widths), so it can be the last level of a hierarchical sink, carried by a parent's pin
    (:func:`tiling.leaf_graded`); it has no branch-out faces (the pins' tops are no longer rectangles a child
    could be placed on)."""
    widths = {"umin": umin, "umax": umax, "vmin": vmin, "vmax": vmax}
    for face, v in widths.items():
        if not (is_real(v) and 0 < v < 0.5):
            raise TilingError(f"face_graded_heat_sink: the pins' width on {face} must be in (0, 0.5) (a fraction "
                              f"of the cell; T2's is 0.45), got {show(v)}")
    for face, v in (("wmin", wmin), ("wmax", wmax)):
        if v is not None and not is_real(v):
            raise TilingError(f"face_graded_heat_sink: {face} must be a number (it shapes nothing), got {show(v)}")
    share = np.array([0.0, 0.25, 0.5, 0.5, 0.75, 1.0])  # each control column's share of the way across the cell
    taper = _SPLIT / _SPLIT[-1]  # the half-gap on each layer, relative to the top's

    def across(lo: float, hi: float) -> np.ndarray:
        """The split coordinates (6 columns, 5 layers, 6 control points) between the sides' widths lo and hi."""
        gap = (0.5 - ((1 - share) * lo + share * hi))[:, None] * taper[None, :]  # (column, layer) half-gaps
        return np.stack([np.zeros_like(gap), (0.5 - gap) / 2, 0.5 - gap, 0.5 + gap, (1.5 + gap) / 2,
                         np.ones_like(gap)], -1)

    cp = np.empty((6, 6, 5, 3))
    cp[..., 0] = across(float(vmin), float(vmax)).transpose(2, 0, 1)  # x of (i, j, k): column j on its way along v
    cp[..., 1] = across(float(umin), float(umax)).transpose(0, 2, 1)  # y of (i, j, k): column i on its way along u
    cp[..., 2] = _Z_LAYERS[None, None, :]
    T = BSpline((2, 2, 2), [_disc_knots(), _disc_knots(), _W_KNOTS], cp)
    name = ", ".join(f"{float(v):g}" for v in widths.values())
    return Tile([T], (0, "wmin"), name=f"face_graded_heat_sink({name})")


#: its control points are affine in the four widths (the parameter sensitivities take one derivative for all cells)
face_graded_heat_sink.affine_in_values = True


def skinned_branching(scale: float = 0.5) -> Tile:
    """Fig. 2 of Massarwi et al. 2018: four (2, 2) surfaces skinned (control meshes stacked) into a (2, 2, 3) tile.

    S0 and S1 are continuous, S2 and S3 split at two u and one v
    discontinuities: (2 + 1)(1 + 1) = 6 branch-out faces.
    """
    Ku = np.array([0, 0, 0, 1 / 3, 1 / 3, 1 / 3, 2 / 3, 2 / 3, 2 / 3, 1, 1, 1.0])
    Kv = _disc_knots()

    def coords(n_pieces, gap):
        out = []
        for i in range(n_pieces):  # slots between pieces; the outer sides stay on the cell walls
            a = i / n_pieces + (gap if i > 0 else 0.0)
            b = (i + 1) / n_pieces - (gap if i < n_pieces - 1 else 0.0)
            out += [a, 0.5 * (a + b), b]
        return np.array(out)

    surfaces = []
    for z, gap in zip([0.0, 1 / 3, 2 / 3, 1.0], [0.0, 0.0, 0.03, 0.05]):
        cp = np.zeros((9, 6, 3))
        cp[..., 0] = coords(3, gap)[:, None]
        cp[..., 1] = coords(2, gap)[None, :]
        cp[..., 2] = z
        surfaces.append(BSpline((2, 2), [Ku, Kv], cp))
    T = pr.skin(surfaces, degree=3)
    return Tile([T], (0, "wmin"), discontinuity_branches(T), scale=scale, name="skinned_branching")


def _hexa(corners: dict) -> BSpline:
    """Trilinear trivariate from its 8 corners {(i, j, k): xyz}."""
    cp = np.zeros((2, 2, 2, 3))
    for (i, j, k), x in corners.items():
        cp[i, j, k] = x
    U = kn.uniform_knots(1, 1)
    return BSpline((1, 1, 1), [U, U, U], cp)


def fractal(scale: float = 2 / 3) -> Tile:
    """Fig. 3 of Massarwi et al. 2018: a trunk and two bent wings, all trilinear; S0 = trunk bottom, S1/S2 = wing tops.

    The wings are glued to the trunk's side faces (whole faces, so the tile is
    conforming); their tops (width 0.2) are 2/3 of the trunk's base (0.3).
    """
    trunk = pr.box((0.3, 1.0, 0.5), (0.35, 0.0, 0.0))

    def wing(attach_x, lower_top_x, upper_top_x):
        # u = 0: the attachment's lower edge -> the outer end of the top; u = 1: upper edge -> inner end
        c = {}
        for j, y in ((0, 0.0), (1, 1.0)):
            c[(0, j, 0)] = (attach_x, y, 0.0)
            c[(1, j, 0)] = (attach_x, y, 0.5)
            c[(0, j, 1)] = (lower_top_x, y, 1.0)
            c[(1, j, 1)] = (upper_top_x, y, 1.0)
        return _hexa(c)

    left = wing(0.35, 0.05, 0.25)
    right = wing(0.65, 0.95, 0.75).reverse(0)  # mirrored so its top face runs along +x
    return Tile([trunk, left, right], (0, "wmin"), [BranchFace(1, "wmax"), BranchFace(2, "wmax")],
                scale=scale, name="fractal")


def hollow_box() -> Tile:
    """Six bilinear surfaces: the walls of the unit cell (Elber 2017, Fig. 2)."""
    cube = pr.box()
    return Tile([cube.boundary(f) for f in ("umin", "umax", "vmin", "vmax", "wmin", "wmax")], name="hollow_box")


def cube() -> Tile:
    """The solid unit cell, one trilinear block: a paving of it is the map's domain cut into cells (a solid
    part, or a macro model whose cells carry a channel)."""
    return Tile([pr.box()], name="cube")


def cross(arm: float = 0.3) -> Tile:
    """Seven trilinear blocks: centre [a, b]^3 (b - a = ``arm``) and six arms to the cell faces."""
    if not 0 < arm < 1:
        raise TilingError(f"cross: arm width must be in (0, 1), got {show(arm)}")
    a, b = 0.5 - arm / 2, 0.5 + arm / 2
    blocks = [pr.box((arm,) * 3, (a,) * 3)]
    for k in range(3):
        for lo, hi in ((0.0, a), (b, 1.0)):
            size = np.full(3, arm)
            org = np.full(3, a)
            size[k], org[k] = hi - lo, lo
            blocks.append(pr.box(tuple(size), tuple(org)))
    return Tile(blocks, name="cross")


def graded_cross(bottom: float = 0.2, top: float = 0.4) -> Tile:
    """A cross whose vertical arm tapers from ``bottom`` (its width on the cell's bottom face) to ``top`` (on its
    top face): centre and horizontal arms of the mean width, the two vertical arms frusta from the end widths to
    the centre's.  Stacked along w with matching end widths (:func:`tiling.graded`), neighbouring layers meet
    face to face, so a lattice can be graded (Massarwi et al. 2018, Section 6.1: heterogeneous structures)."""
    for what, v in (("bottom", bottom), ("top", top)):
        if not (is_real(v) and 0 < v < 1):
            raise TilingError(f"graded_cross: the {what} arm width must be in (0, 1), got {show(v)}")
    mid = 0.5 * (bottom + top)
    a, b = 0.5 - mid / 2, 0.5 + mid / 2
    blocks = [pr.box((mid,) * 3, (a,) * 3)]
    for k in (0, 1):
        for lo, hi in ((0.0, a), (b, 1.0)):
            size, org = np.full(3, mid), np.full(3, a)
            size[k], org[k] = hi - lo, lo
            blocks.append(pr.box(tuple(size), tuple(org)))

    def frustum(z0, w0, z1, w1):  # square sections of width w0 at z0 and w1 at z1, centred on the cell's axis
        corners = {(i, j, k): (0.5 + (i - 0.5) * w, 0.5 + (j - 0.5) * w, z)
                   for k, (z, w) in enumerate(((z0, w0), (z1, w1))) for i in (0, 1) for j in (0, 1)}
        return _hexa(corners)

    blocks += [frustum(0.0, bottom, a, mid), frustum(b, mid, 1.0, top)]
    return Tile(blocks, name=f"graded_cross({bottom:g}, {top:g})")


def face_graded_cross(umin: float = 0.3, umax: float = 0.3, vmin: float = 0.3, vmax: float = 0.3,
                      wmin: float = 0.3, wmax: float = 0.3) -> Tile:
    """A cross whose arm towards each face of the cell has its own width there (``umin`` .. ``wmax``, in (0, 1)):
    a centre block of the six widths' mean and six frusta from the centre's faces to square sections of the given
    widths on the cell's faces.  Paved with the widths of a field taken on every shared face
    (:func:`tiling.field_graded`), neighbouring cells meet face to face in all three directions."""
    widths = {"umin": umin, "umax": umax, "vmin": vmin, "vmax": vmax, "wmin": wmin, "wmax": wmax}
    for face, v in widths.items():
        if not (is_real(v) and 0 < v < 1):
            raise TilingError(f"face_graded_cross: the {face} arm width must be in (0, 1), got {show(v)}")
    mid = float(np.mean(list(widths.values())))
    a, b = 0.5 - mid / 2, 0.5 + mid / 2
    blocks = [pr.box((mid,) * 3, (a,) * 3)]
    for k, axis in enumerate("uvw"):
        rest = [j for j in range(3) if j != k]
        for side in (0, 1):
            w = float(widths[f"{axis}{'max' if side else 'min'}"])
            ends = ((0.0, w), (a, mid)) if side == 0 else ((b, mid), (1.0, w))  # (coordinate, width), along +axis
            corners = {}
            for m, (along, width) in enumerate(ends):
                for i in (0, 1):
                    for j in (0, 1):
                        x, key = np.empty(3), [0, 0, 0]
                        x[k], x[rest[0]], x[rest[1]] = along, 0.5 + (i - 0.5) * width, 0.5 + (j - 0.5) * width
                        key[k], key[rest[0]], key[rest[1]] = m, i, j
                        corners[tuple(key)] = tuple(x)
            blocks.append(_hexa(corners))
    name = ", ".join(f"{v:g}" for v in widths.values())
    return Tile(blocks, name=f"face_graded_cross({name})")


#: its control points are affine in the six widths (the parameter sensitivities take one derivative for all cells)
face_graded_cross.affine_in_values = True


def hollow(tile: Tile) -> Tile:
    """The boundary of a volumetric tile as a surface tile: every face of its trivariates that no other of its
    trivariates shares and that does not lie on a cell wall (where neighbours continue it), oriented outwards.

    Paved, the surfaces of neighbouring tiles meet at the cell walls; capped (``seal="cap"``) on D's
    boundary, the result is a closed surface (Elber 2017, Fig. 2(d); Massarwi et al. 2018, Fig. 9(a, b)).
    """
    from geometry import MultiPatch
    from geometry.faces import FACE_NAMES

    vols = [p for p in tile.patches if p.dim == 3]
    if not vols:
        raise TilingError(f"hollow: tile {show(tile.name)} has no trivariates to take the boundary of")
    model = MultiPatch.from_splines(vols)
    glued = {itf.a for itf in model.interfaces} | {itf.b for itf in model.interfaces}
    walls = []
    for i, p in enumerate(vols):
        centre = p.evaluate(p.domain.mean(1)[None])[0, :3]
        for f in FACE_NAMES:
            face = p.boundary(f)
            pts = face.points.reshape(-1, 3)
            if (i, f) in glued or np.any(np.all(np.abs(pts - np.round(pts)) < ON_DOMAIN, axis=0)
                                         & np.all(np.abs(pts - pts[0]) < ON_DOMAIN, axis=0)):
                continue  # shared inside the tile, or on a cell wall
            mid = face.domain.mean(1)[None]
            x = face.evaluate(mid)[0, :3]
            h = 1e-6 * np.ptp(face.domain, axis=1)  # a forward difference gives the normal's side
            du = face.evaluate(mid + [[h[0], 0.0]])[0, :3] - x
            dv = face.evaluate(mid + [[0.0, h[1]]])[0, :3] - x
            if np.dot(np.cross(du, dv), x - centre) < 0:  # make the normal point out of the block
                face = face.reverse(0)
            walls.append(face)
    return Tile(walls, name=f"hollow {tile.name}")


def hollow_cross(arm: float = 0.3) -> Tile:
    """:func:`hollow` of :func:`cross`: the 24 walls of its six arms, open at the cell faces."""
    t = hollow(cross(arm))
    t.name = "hollow_cross"
    return t


def bent_cross(degrees=(3, 3, 2), bend: float = 0.02) -> Tile:
    """The cross at ``degrees`` with every block's inner control points moved by ``bend``: a non-affine tile.

    Its faces stay those of :func:`cross` (neighbours conform); composed into a map of degrees
    (1, 1, 2) its patches have degrees (12, 12, 8), the setting of Massarwi et al. 2018, Fig. 10.
    """
    blocks = []
    for p in cross().patches:
        e = p.elevate_to(tuple(degrees))
        c = e.control_points.copy()
        c[1:-1, 1:-1, 1:-1, :] += bend
        blocks.append(BSpline(e.degrees, e.knots, c))
    return Tile(blocks, name="bent cross")


def helix(turns: float = 2.0, radius: float = 0.3, n: int = 16) -> Tile:
    """A cubic curve winding ``turns`` times around the cell's vertical axis (Elber 2017, Fig. 10)."""
    t = np.linspace(0.0, 1.0, n)
    ang = 2 * np.pi * turns * t
    cp = np.column_stack([0.5 + radius * np.cos(ang), 0.5 + radius * np.sin(ang), t])
    return Tile([BSpline((3,), [kn.uniform_knots(3, n - 3)], cp)], name="helix")


def _cubic_through(points: np.ndarray, spans: int, closed: bool = False) -> BSpline:
    """The cubic B-spline of ``spans`` uniform spans interpolating ``spans + 3`` points at the Greville
    abscissae (``closed``: the last control point set to the first, the points being a closed loop)."""
    from scipy.interpolate import make_interp_spline

    U = kn.uniform_knots(3, spans)
    c = make_interp_spline(kn.greville(U, 3), points, k=3, t=U).c
    if closed:
        c[-1] = c[0]
    return BSpline((3,), [U], c)


def helical_tubes(radius: float = 0.22, tube: float = 0.12) -> Tile:
    """Four bicubic tubes, each a quarter turn of a helix about the cell's vertical axis at ``radius`` swept by a
    circle of radius ``tube`` (the algebraic sum of the two curves; Elber 2017, Fig. 4(a)): a tube enters at the
    bottom face where the next one leaves at the top, so stacked copies join into four helices (Fig. 4(c))."""
    for name, v in (("radius", radius), ("tube", tube)):
        if not (is_real(v) and np.isfinite(v) and v > 0):
            raise TilingError(f"helical_tubes: {name} must be a positive number (cell units), got {show(v)}")
    if radius + tube >= 0.5:
        raise TilingError(f"helical_tubes: radius + tube = {radius + tube:g} must stay below 0.5 (the tubes "
                          "inside the cell)")
    u = np.linspace(0.0, 1.0, 7)
    a = np.linspace(0.0, 2 * np.pi, 9)
    circle = _cubic_through(np.column_stack([tube * np.cos(a), tube * np.sin(a), 0 * a]), 6, closed=True)
    surfaces = []
    for k in range(4):
        ang = k * np.pi / 2 + u * np.pi / 2
        axis = _cubic_through(np.column_stack([0.5 + radius * np.cos(ang), 0.5 + radius * np.sin(ang), u]), 4)
        cp = axis.control_points[:, None, :] + circle.control_points[None, :, :]  # the algebraic sum
        surfaces.append(BSpline((3, 3), [axis.knots[0], circle.knots[0]], cp))
    return Tile(surfaces, name="helical tubes")


def struts(kind: str = "bcc") -> Tile:
    """Straight beam axes (degree-1 curves) for round-strut lattices (:func:`tiling.members.struts.round_struts`).

    ``"bcc"``: the eight half-diagonals from the cell's centre to its corners (body-centred
    cubic); ``"cubic"``: the six segments from the centre to the face centres, so that
    neighbouring cells' struts continue each other in a straight line.
    """
    c = np.full(3, 0.5)
    if kind == "bcc":
        ends = np.array(np.meshgrid([0.0, 1.0], [0.0, 1.0], [0.0, 1.0], indexing="ij")).reshape(3, -1).T
    elif kind == "cubic":
        ends = c + 0.5 * np.vstack([np.eye(3), -np.eye(3)])
    else:
        raise TilingError(f"unknown strut lattice {show(kind)}; use 'bcc' or 'cubic'")
    return Tile([BSpline((1,), [[0.0, 0.0, 1.0, 1.0]], np.array([c, e])) for e in ends], name=f"{kind} struts")


def stitch(amplitude: float = 0.35, n: int = 12) -> Tile:
    """One period of a sine along u through the cell's thickness w (a stitched fibre, Elber 2017, Fig. 8),
    as a cubic curve whose end tangents agree, so that the stitches of neighbouring cells continue each other."""
    t = np.linspace(0.0, 1.0, n)
    cp = np.column_stack([t, np.full(n, 0.5), 0.5 + amplitude * np.sin(2 * np.pi * t)])
    return Tile([BSpline((3,), [kn.uniform_knots(3, n - 3)], cp)], name="stitch")


def oblique_tubes(width: float = 0.16) -> Tile:
    """Square tubes of side ``width`` along (1, 0, 1/2), periodic in x and z (the lines z = 1/4 + x/2 + j/2
    through the cell: three pieces of tube per cell), their planar walls cut by the cell's six planes
    (:func:`tiling.sealing.clipping.clip_walls`): they cross the walls x = 0, x = 1, z = 0 and z = 1 obliquely, and
    neighbouring cells' pieces meet edge to edge.  Sealed with ``seal="cap"``: the Boolean variant of
    Elber 2017, Section 2 (cut by the planes, the cut capped), the tube walls' angles kept."""
    if not (is_real(width) and 0 < width < 0.3):
        raise TilingError(f"oblique_tubes: width must be in (0, 0.3) of a cell, got {show(width)}")
    d = np.array([1.0, 0.0, 0.5])
    e1 = np.array([0.0, 1.0, 0.0])
    e2 = np.array([-0.5, 0.0, 1.0]) / np.linalg.norm([-0.5, 0.0, 1.0])
    a, reach = width / 2, 3.0  # half-side; tube half-length (the pieces reach well beyond the cell)
    walls = []
    for offset in (-0.5, 0.0, 0.5):
        p = np.array([0.5, 0.5, 0.5 + offset])
        for n, u in ((e1, e2), (-e1, e2), (e2, e1), (-e2, e1)):  # outward normal n, the other section axis u
            v = d if np.dot(np.cross(u, d), n) > 0 else -d  # u x v along n: the wall faces out of the tube
            c = p + a * n
            cp = np.array([[c - a * u - reach * v, c - a * u + reach * v], [c + a * u - reach * v, c + a * u + reach * v]])
            walls.append(BSpline((1, 1), [np.array([0.0, 0.0, 1.0, 1.0])] * 2, cp))
    return clip_walls(walls, name=f"oblique_tubes({width:g})")


#: the built-in tiles by name (what ``[tile] library = ...`` of a pipeline may name)
TILES = {f.__name__: f for f in (heat_sink_t1, heat_sink_t2, skinned_branching, fractal, hollow_box, cube, cross, helix,
                                 helical_tubes, bent_cross, hollow_cross, graded_cross, face_graded_cross, face_graded_heat_sink, struts,
                                 stitch, through_cylinders,
                                 oblique_tubes)}
