"""Bridging trivariates between tile faces in space (Hong and Elber 2021, Sections 3.5-3.6).

In a union the two ends of a bridge belong to different primitives, so the
bridge cannot live in one map's parameters (Section 3.2's bridges do).  It
is built in space instead, from the *composed* faces it joins (exact
B-spline surfaces, :attr:`PlacedPatch.composed`), so both of its end faces
*are* those faces, to round-off:

* :func:`hermite_tube` (one-to-one, Section 3.6): the cubic Hermite blend
  in w of the two end faces, brought to one spline space (degree elevation
  and knot union, both exact); the inner control layers continue each tile's
  last layer (the tile's cross derivative, blended by ``phi`` with the face
  normal), so the sweep axis is the cubic Hermite curve of Section 3.6.
  :meth:`Tube.displace` raises it to a quintic and moves the two new inner
  layers, the paper's collision repulsion.
* two-to-one bridges (Section 3.5): a base (:func:`tiling.vrep.fork.bifurcation_base`)
  and two of these tubes as arms.

Analysis: a bridge is a :class:`PlacedPatch` whose ``outer`` map is its
geometry G on [0, 1]^3 and whose ``spline`` is the identity of [0, 1]^3 in
the *analysis* space (:func:`carrier`): across, the end faces' spaces (those
of the tiles' faces), so every end of a bridge meets its tile face by an
identity interface in the constraint machinery (found by
:func:`geometry.detect_interfaces`, with the orientation), while G keeps the
exact geometry of both faces; along, G's own degree (:func:`tube_space`), so
the analysis is isoparametric along the bridge and an affine field (on affine
maps) is reproduced across it to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.special import comb

from geometry.numbers import TINY
from geometry import BSpline
from geometry import knots as kn
from geometry.spline import SplineFunction
from geometry.faces import FACE_AXIS
from geometry.patches.multipatch import ORIENTATIONS, PlacedPatch
from geometry.maps.regularity import prove_one_signed_many
from geometry.cache import BoundedCache

from ..errors import TilingError
from .repulsion import cross3
from geometry.tolerances import COINCIDENT, ROUNDOFF

__all__ = ["is_regular", "are_regular", "Face", "face_of", "Tube", "hermite_tube", "carrier", "orient",
           "orientation_for", "corner_index", "bridge_patch", "uniform_space", "direction_field", "face_space",
           "tube_space"]

_TOL = COINCIDENT  # composed knots closer than this (x span) are one knot


@dataclass
class Face:
    """A patch face in space: ``surface`` (2-variate, on [0, 1]^2, xyz + channels: the exact composed face),
    ``out`` (same space, xyz: control layer 0 - layer 1, the tile's outward cross direction), the analysis face
    space ``space`` [(U normalised, p)] * 2, and its ``key`` (patch, face) in the model."""

    surface: BSpline
    out: BSpline
    space: list
    key: tuple

    @cached_property
    def _at_centre(self) -> tuple:
        """(point, tangents (3, 2)) at the face's parameter centre, both from one pair of basis evaluations
        contracted with the (polynomial) control net: a general evaluation's set-up cost several times more."""
        S = self.surface
        (su, Nu), (sv, Nv) = [kn.basis_functions(U, p, _MIDDLE, nder=1) for U, p in zip(S.knots, S.degrees)]
        pu, pv = S.degrees
        block = S.control_points[su[0] - pu: su[0] + 1, sv[0] - pv: sv[0] + 1, :3]  # (pu + 1, pv + 1, 3)
        x = np.einsum("i,j,ijk->k", Nu[0, 0], Nv[0, 0], block)
        J = np.stack([np.einsum("i,j,ijk->k", Nu[0, 1], Nv[0, 0], block),
                      np.einsum("i,j,ijk->k", Nu[0, 0], Nv[0, 1], block)], axis=1)
        return x, J

    @property
    def centre(self) -> np.ndarray:
        return self._at_centre[0]

    @cached_property
    def normal(self) -> np.ndarray:
        """Unit normal at the centre, pointing out of the tile (along ``out``)."""
        J = self._at_centre[1]
        n = cross3(J[:, 0], J[:, 1])
        n /= max(np.linalg.norm(n), TINY)
        return n if np.dot(n, self.direction) >= 0 else -n

    @cached_property
    def direction(self) -> np.ndarray:
        """Unit mean outward cross direction (the tile's dT/dw across the face)."""
        d = self.out.points.reshape(-1, 3).mean(0)
        return d / max(np.linalg.norm(d), TINY)

    @cached_property
    def width(self) -> float:
        """Inscribed half-width (model units): half the narrower extent of the face in its principal plane."""
        ring = self.surface.points.reshape(-1, 3)
        ring = ring - ring.mean(0)
        proj = ring @ np.linalg.svd(ring, full_matrices=False)[2][:2].T
        return float(np.abs(proj).max(axis=0).min())


_MIDDLE = np.array([0.5])
_MIDDLE.setflags(write=False)
_CUBIC = np.array([0.0] * 4 + [1.0] * 4)  # a tube's knots along w
_CUBIC.setflags(write=False)


def _net(degrees, knots, net, channels=()) -> BSpline:
    """The polynomial B-spline with the knots and control net made here by exact operations on validated
    splines (elevation, insertion, merged knots, sums of nets): built without re-validation, knots kept
    read-only (each tube makes about 20 of these: 0.1 s of a box-and-cylinder union went to the checks)."""
    return BSpline._trusted(tuple(degrees), knots, net, False, channels=tuple(channels))


def _surface(degrees, knots, net, channels=()) -> BSpline:
    """A face of a composed (validated) patch, its knots mapped onto [0, 1]^2."""
    return _net(degrees, [(U - U[0]) / (U[-1] - U[0]) for U in knots], net, channels)


def face_of(P: PlacedPatch, face: str, key=None) -> Face:
    """The composed face ``face`` of placed patch ``P`` (exact; polynomial maps only)."""
    C = P.composed
    if C.is_rational:
        raise TilingError(f"patch face {key}: union bridges join polynomial faces; the composed patch is rational "
                          "(a rational map or tile); use a polynomial map such as geometry.shapes.examples.cylinder")
    k, s = FACE_AXIS[face]
    cp = C.control_points
    F = np.take(cp, -1 if s else 0, axis=k)
    inner = np.take(cp[..., :3], -2 if s else 1, axis=k)
    rest = [d for d in range(3) if d != k]
    deg = tuple(C.degrees[d] for d in rest)
    kts = [C.knots[d] for d in rest]
    surf = _surface(deg, kts, F, C.channels)
    out = _surface(deg, kts, F[..., :3] - inner)
    return Face(surf, out, face_space(P.spline, face), key)


def face_space(T: BSpline, face: str) -> list:
    """The analysis space [(U normalised to [0, 1], p)] * 2 of the face ``face`` of the patch spline ``T``."""
    k = FACE_AXIS[face][0]
    out = []
    for d in (d for d in range(3) if d != k):
        U = np.asarray(T.knots[d], float)
        out.append(((U - U[0]) / (U[-1] - U[0]), T.degrees[d]))
    return out


def orient(S: BSpline, o: int) -> BSpline:
    """S re-parametrised by orientation ``o`` (index into ORIENTATIONS): S_o(s, t) = S(s', t') with (s', t') =
    (s, t) swapped if swap, then reversed per flip (the convention of :class:`geometry.Interface`)."""
    swap, flip = ORIENTATIONS[o]
    out = S
    for d in (0, 1):
        if flip[d]:
            out = out.reverse(d)
    return out.swap(0, 1) if swap else out


def _corners(S: BSpline) -> np.ndarray:
    """The four corners (00, 10, 01, 11) of a clamped surface: its corner control points."""
    P = S.points
    return np.stack([P[0, 0], P[-1, 0], P[0, -1], P[-1, -1]])


def orientation_for(a: Face, b: Face) -> int:
    """The orientation of b's face seen from a (a bridge from a to b) without a fold or a twist: the bridge's
    Jacobian keeps its sign from end to end, and b's corners follow a's as closely as possible."""
    ja = np.sign(np.dot(_jac_normal(a.surface), a.direction))
    nb = np.sign(np.dot(_jac_normal(b.surface), -b.direction))  # w runs into b's tile there
    best, best_cost = 0, np.inf
    ca = _corners(a.surface) - a.centre
    cb = _corners(b.surface) - b.centre
    for o in range(8):
        swap, flip = ORIENTATIONS[o]
        if nb * (-1) ** (int(swap) + int(flip[0]) + int(flip[1])) != ja:  # each swap or flip turns the normal
            continue
        cost = np.sum((cb[_CORNER_INDEX[o]] - ca) ** 2)
        if cost < best_cost:
            best, best_cost = o, cost
    return best


def corner_index(o: int) -> list:
    """For orientation ``o``: the index of the original corner (00, 10, 01, 11) at each corner of the oriented face."""
    swap, flip = ORIENTATIONS[o]
    idx = []
    for s_, t_ in ((0, 0), (1, 0), (0, 1), (1, 1)):
        s2, t2 = (t_, s_) if swap else (s_, t_)
        idx.append((1 - t2 if flip[1] else t2) * 2 + (1 - s2 if flip[0] else s2))
    return idx


_CORNER_INDEX = [corner_index(o) for o in range(8)]


def _jac_normal(S: BSpline) -> np.ndarray:
    """The face's orientation normal from its corners (the sign of d/ds x d/dt of a regular face)."""
    c = _corners(S)
    return cross3(c[1] - c[0] + c[3] - c[2], c[2] - c[0] + c[3] - c[1])


_ELEVATIONS = BoundedCache(256)  # (knots, degree, times) -> (new knots, matrix): faces of one tile repeat them


def _elevated(S: BSpline, degrees) -> BSpline:
    """S with its degrees raised to ``degrees`` (exact; the elevation matrices are cached)."""
    cp, knots = S.control_points, list(S.knots)
    for d, q in enumerate(degrees):
        t = q - S.degrees[d]
        if t <= 0:
            continue
        key = (np.asarray(knots[d]).tobytes(), S.degrees[d], t)
        knots[d], E = _ELEVATIONS.get(key, lambda U=knots[d], p=S.degrees[d], t=t: kn.elevation_matrix(U, p, t))
        cp = kn.apply_along(cp, d, E)
    return _net(degrees, knots, cp, S.channels)


def _common(surfs: list) -> list:
    """The surfaces in one spline space: degrees raised to the largest, knots merged (both exact)."""
    q = [max(s.degrees[d] for s in surfs) for d in range(2)]
    surfs = [_elevated(s, q) for s in surfs]
    for d in range(2):
        vals, mult = [], []
        for s in surfs:
            v, m = kn.breakpoints(s.knots[d])
            for x, c in zip(v[1:-1], m[1:-1]):
                hit = [i for i, y in enumerate(vals) if abs(y - x) < _TOL]
                if hit:
                    mult[hit[0]] = max(mult[hit[0]], int(c))
                else:
                    vals.append(float(x))
                    mult.append(int(c))
        target = np.sort(np.concatenate([[0.0] * (q[d] + 1), np.repeat(vals, mult), [1.0] * (q[d] + 1)]))
        out = []
        for s in surfs:
            U = s.knots[d]
            ins = []
            for x, c in zip(vals, mult):
                have = int(np.sum(np.abs(U - x) < _TOL))
                ins += [x] * (c - have)
            if ins:
                s = s.insert_knots(d, ins)[0]
            knots = list(s.knots)
            knots[d] = target  # the same values everywhere (the merged ones differ by round-off only)
            out.append(_net(s.degrees, knots, s.control_points, s.channels))
        surfs = out
    return surfs


def direction_field(f: Face, phi: float) -> BSpline:
    """The outward field of a face, unit on average, blended by ``phi`` with the central normal (Fig. 9)."""
    d = f.out.points
    scale = max(float(np.linalg.norm(d.reshape(-1, 3).mean(0))), TINY)
    v = (1 - phi) * d / scale + phi * f.normal
    return _net(f.out.degrees, f.out.knots, v)


@dataclass
class Tube:
    """A one-to-one bridging trivariate in space: control layers (4 cubic, or 6 after :meth:`displace`) in one
    face space ``(degrees, knots)``, channel names, its end faces and inscribed radius."""

    layers: list
    degrees: tuple
    knots: list
    channels: tuple
    a: Face
    b: Face
    radius: float
    shift: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))  # quintic inner-layer offsets
    _cache: tuple = field(default=None, repr=False)
    _quintic: BSpline = field(default=None, repr=False)
    _centres: np.ndarray = field(default=None, repr=False)
    _centres5: np.ndarray = field(default=None, repr=False)  # the centres raised to a quintic (unshifted)

    @property
    def geometry(self) -> BSpline:
        """G on [0, 1]^3: the end faces at w = 0 and w = 1 (cubic, or quintic once displaced)."""
        key = self.shift.tobytes()
        if self._cache is None or self._cache[0] != key:
            self._cache = (key, self._geometry())
        return self._cache[1]

    def _cubic(self) -> BSpline:
        net = np.stack(self.layers, axis=2)
        return _net(self.degrees + (3,), self.knots + [_CUBIC], net, self.channels)

    def _geometry(self) -> BSpline:
        if not np.any(self.shift):
            return self._cubic()
        if self._quintic is None:
            self._quintic = self._cubic().elevate(2, 2)  # two more inner layers to repel with (Section 3.6)
        Q = self._quintic
        cp = Q.control_points.copy()
        cp[:, :, 2, :3] += self.shift[0]
        cp[:, :, 3, :3] += self.shift[1]
        return _net(Q.degrees, Q.knots, cp, self.channels)

    def displace(self, v: np.ndarray) -> None:
        """Move the quintic's two inner layers by ``v`` (3,) (model units)."""
        self.shift = self.shift + np.asarray(v, float)[None]

    def axis(self, r=None) -> np.ndarray:
        """Physical points of the sweep axis (the face centres' curve) at w = r (default 24 samples): the Bezier
        curve of the control layers' centres (a tensor product's centre curve)."""
        r = _AXIS_SAMPLES if r is None else np.asarray(r, float)
        if self._centres is None:
            S = SplineFunction(self.degrees, self.knots, np.concatenate([L[..., :3] for L in self.layers], axis=-1))
            self._centres = S.evaluate(np.array([[0.5, 0.5]]))[0].reshape(len(self.layers), 3)
        c = self._centres
        if np.any(self.shift):  # the repulsion samples a displaced tube's axis at every step: raised once
            if self._centres5 is None:
                self._centres5 = np.stack([c[0], 0.4 * c[0] + 0.6 * c[1], 0.1 * c[0] + 0.6 * c[1] + 0.3 * c[2],
                                           0.3 * c[1] + 0.6 * c[2] + 0.1 * c[3], 0.6 * c[2] + 0.4 * c[3],
                                           c[3]])  # cubic -> quintic
            c = self._centres5.copy()
            c[2] += self.shift[0]
            c[3] += self.shift[1]
        return _bernstein(len(c) - 1, r) @ c


_AXIS_SAMPLES = np.linspace(0.0, 1.0, 24)  # the default axis samples (read-only, shared)
_AXIS_SAMPLES.setflags(write=False)


def _bernstein(n: int, r: np.ndarray) -> np.ndarray:
    """(len(r), n + 1) Bernstein basis of degree n at r (the default 24 samples cached per degree)."""
    return _BERNSTEIN.get((n, r.tobytes()), lambda: np.stack([comb(n, i) * r**i * (1 - r) ** (n - i)
                                                               for i in range(n + 1)], 1))


_BERNSTEIN = BoundedCache(64)


def hermite_tube(a: Face, b: Face, beta: float = 0.5, phi: float = 0.0) -> Tube:
    """The one-to-one bridge from face ``a`` to face ``b`` (Section 3.6): cubic Hermite in w, end tangents the
    tiles' cross directions (``phi`` blends to the face normals), of length ``beta`` x the centres' distance."""
    o = orientation_for(a, b)
    sb = orient(b.surface, o)
    ob = orient(direction_field(b, phi), o)
    oa = direction_field(a, phi)
    L = float(np.linalg.norm(b.centre - a.centre))
    nc = len(a.surface.channels)
    if tuple(sb.channels) != tuple(a.surface.channels):
        raise TilingError(f"faces {a.key} and {b.key}: the primitives' maps carry different channels "
                          f"({list(a.surface.channels)} and {list(sb.channels)}); give every primitive the same ones")
    # each end with its direction field as three more components: one elevation and insertion per end
    ends = [_net(S.degrees, S.knots, np.concatenate([S.control_points, F.points], -1),
                 S.channels + ("~dx", "~dy", "~dz")) for S, F in ((a.surface, oa), (sb, ob))]
    fa, fb = _common(ends)
    A, B = fa.control_points[..., : 3 + nc], fb.control_points[..., : 3 + nc]
    L1, L2 = A.copy(), B.copy()
    L1[..., :3] += beta * L * fa.control_points[..., 3 + nc :]
    L2[..., :3] += beta * L * fb.control_points[..., 3 + nc :]
    return Tube([A, L1, L2, B], fa.degrees, list(fa.knots), a.surface.channels, a, b, min(a.width, b.width))


_GRID = np.stack(np.meshgrid(*([np.linspace(0.0, 1.0, 6)] * 2 + [np.linspace(0.0, 1.0, 9)]), indexing="ij"),
                 -1).reshape(-1, 3)


def is_regular(G) -> bool:
    """Whether the trivariate G's Jacobian keeps one sign: a 6 x 6 x 9 sample screen (ends included) rejects
    samples of both signs at once; otherwise the exact Bernstein proof decides, the one
    :func:`iga.discretisation.regularity.prove_regular` runs on every patch before the analysis assembles
    (:func:`geometry.maps.regularity.prove_one_signed`; undecided counts as regular there and here).  The screen
    alone is not a proof: a trimming-surface bridge of the duck minus a hole had all its samples of one sign
    (within a factor 10 of each other) and a fold near one face."""
    return are_regular([G])[0]


def are_regular(Gs) -> list[bool]:
    """:func:`is_regular` of each of the trivariates ``Gs``, the exact proofs of those the screen passes run
    together (:func:`geometry.maps.regularity.prove_one_signed_many`: the tubes of a union share their degrees)."""
    screened = []
    for G in Gs:
        dom = G.domain
        # the compiled kernel even for these 324 points: the V-rep builder has loaded it for its inversions,
        # and SciPy's four passes per tube cost 0.3 ms (a hundred tubes per union)
        _, J = G._value_jacobian(dom[:, 0] + _GRID * (dom[:, 1] - dom[:, 0]), values=False, checked=True,
                                 compiled=True)
        det = np.linalg.det(J[:, :3, :])
        # samples of both signs beyond round-off (ROUNDOFF x the largest |det J|, a stated margin) reject at
        # once; a sample within it is a zero, which only the exact proof can place
        floor = ROUNDOFF * float(np.abs(det).max())
        screened.append(not (np.any(det > floor) and np.any(det < -floor)))
    proofs = iter(prove_one_signed_many([G for G, ok in zip(Gs, screened) if ok]))
    return [next(proofs).status != "singular" if ok else False for ok in screened]


_CARRIERS = BoundedCache(64)


def carrier(space: list) -> BSpline:
    """The identity of [0, 1]^3 in the analysis space ``space`` [(U normalised, p)] * 3 (control points at the
    Greville abscissae: exact for degree >= 1); one object per space, so patches share it."""
    def make():
        g = [kn.greville(np.asarray(U, float), p) for U, p in space]
        net = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1)
        return BSpline(tuple(p for _, p in space), [np.asarray(U, float) for U, _ in space], net)

    return _CARRIERS.get(tuple((np.asarray(U, float).tobytes(), int(p)) for U, p in space), make)


def uniform_space(p: int, n: int):
    """(U, p): an open uniform knot vector on [0, 1] with ``n`` elements."""
    return np.r_[[0.0] * p, np.linspace(0.0, 1.0, n + 1), [1.0] * p], p


def tube_space(t: Tube) -> list:
    """A tube's analysis space: its start face's (the end face's, oriented, is the same or refused by the
    interface search), and in w the geometry's own degree (cubic, quintic once displaced; at least the faces'),
    on elements about as long as the face is wide: the tube's Bezier geometry in w lies in that space, so
    along the tube the analysis is isoparametric and an affine field is reproduced."""
    p = max(max(d for _, d in t.a.space), t.geometry.degrees[2])
    length = float(np.linalg.norm(t.b.centre - t.a.centre))
    n = int(np.clip(round(length / max(2 * t.radius, TINY)), 1, 4))
    return [t.a.space[0], t.a.space[1], uniform_space(p, n)]


def bridge_patch(G: BSpline, space: list, tile: int) -> PlacedPatch:
    """A bridging patch: analysis ``space`` (carrier), geometry G (its own outer map, already composed).

    A left-handed G is reversed in w (and its w space with it): the analysis checks the Jacobian's sign over
    batches of patches, so every patch is right-handed like the tiles.  Its faces keep their images, and the
    interface search finds their new orientation."""
    _, J = G.value_and_jacobian(np.array([[0.5, 0.5, 0.5]]))
    if np.linalg.det(J[0, :3, :]) < 0:
        G = G.reverse(2)
        U, p = space[2]
        space = [space[0], space[1], (1.0 - np.asarray(U, float)[::-1], p)]
    P = PlacedPatch(carrier(space), None, G, tile, 0, 0)
    P.set_composed(G)
    return P
