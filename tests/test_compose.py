"""Exact composition (Elber 2017, Section 2) and the regularity check."""

from fractions import Fraction
from math import comb

from contextlib import contextmanager

import numpy as np
import pytest

import geometry
from geometry import BSpline, SplineError, check_regular, compose, compose_many, map_points, primitives as pr
from geometry import knots as kn
from helpers import random_knots, rel_err


def random_outer(rng, degrees, rational, spans=1, channels=("k",)):
    """A regular map: identity on [0,1]^3 (random knots) with a small control-point perturbation."""
    knots = [random_knots(rng, p, spans - 1, max_mult=1) if spans > 1 else kn.uniform_knots(p, 1) for p in degrees]
    g = [kn.greville(U, p) for U, p in zip(knots, degrees)]
    pts = np.stack(np.meshgrid(*g, indexing="ij"), -1)
    pts = pts + 0.03 * rng.uniform(-1, 1, pts.shape)
    cp = np.concatenate([pts, rng.uniform(1, 2, pts.shape[:-1] + (len(channels),))], -1)
    w = rng.uniform(0.7, 1.5, pts.shape[:-1]) if rational else None
    return BSpline(degrees, knots, cp, w, channels)


def random_inner(rng, dim, degrees, rational, box, channels=("rho",), n_inner=0):
    """An inner spline whose control points lie inside ``box`` (3, 2) of the outer domain."""
    knots = [random_knots(rng, p, n_inner) for p in degrees]
    shape = tuple(len(U) - p - 1 for U, p in zip(knots, degrees))
    pts = box[:, 0] + rng.random(shape + (3,)) * (box[:, 1] - box[:, 0])
    cp = np.concatenate([pts, rng.uniform(0, 1, shape + (len(channels),))], -1)
    w = rng.uniform(0.6, 1.6, shape) if rational else None
    return BSpline(degrees, knots, cp, w, channels)


CASES = [(i, 1 + i % 3) for i in range(50)]  # (seed, inner dimension)


@pytest.mark.parametrize("seed, dim", CASES)
def test_compose_equals_outer_of_inner(seed, dim):
    rng = np.random.default_rng(seed)
    outer_deg = tuple(int(p) for p in rng.integers(1, 4, 3))
    inner_deg = tuple(int(p) for p in rng.integers(1, 4 if dim < 3 else 3, dim))
    spans = 1 if seed % 2 == 0 else 3  # Bezier and multi-span B-spline outer maps
    outer = random_outer(rng, outer_deg, rational=seed % 3 == 0, spans=spans)
    # put the inner spline inside one knot span of the outer map
    box = np.empty((3, 2))
    for k in range(3):
        bp = outer.breakpoints(k)
        e = rng.integers(0, len(bp) - 1)
        box[k] = [bp[e], bp[e + 1]]
    inner = random_inner(rng, dim, inner_deg, rational=seed % 5 == 0, box=box, n_inner=seed % 2)
    c = compose(outer, inner)
    n = sum(outer_deg)
    extra = 1 if (outer.is_rational and inner.channels) else 0  # see geometry.compose docs
    assert c.degrees == tuple((n + extra) * m for m in inner_deg)
    assert c.channels == ("k", "rho")
    x = rng.random((1000, dim))
    v = inner(x)
    ref = np.column_stack([outer(v[:, :3]), v[:, 3:]])
    tol = 1e-10 if max(c.degrees) > 30 else 1e-12
    assert rel_err(c(x), ref) < tol
    # channels: the outer channel is composed, the inner one carried along unaltered
    assert rel_err(c(x)[:, 3], outer(v[:, :3])[:, 3]) < tol
    assert rel_err(c(x)[:, 4], v[:, 3]) < tol


def test_result_degrees_follow_eq_7():
    # Elber 2017, Eq. 7: outer (1, 1, 3) with a (3, 2) surface gives (15, 10); a trivariate (3, 3, 2) gives (15, 15, 10)
    rng = np.random.default_rng(0)
    outer = random_outer(rng, (1, 1, 3), rational=False, channels=())
    box = np.array([[0.1, 0.9]] * 3)
    assert compose(outer, random_inner(rng, 2, (3, 2), False, box, ())).degrees == (15, 10)
    assert compose(outer, random_inner(rng, 3, (3, 3, 2), False, box, ())).degrees == (15, 15, 10)
    assert compose(outer, random_inner(rng, 1, (3,), False, box, ())).degrees == (15,)
    assert geometry.result_degrees((1, 1, 3), (3, 2)) == (15, 10)
    # rational in, rational out, same degrees
    assert compose(random_outer(rng, (1, 1, 3), True, channels=()), random_inner(rng, 2, (3, 2), True, box, ())).degrees == (15, 10)


# ------------------------------------------------------------ exact arithmetic
def _frac(a):
    return np.vectorize(Fraction, otypes=[object])(a)


def _frac_multiply(a, b):
    """Bernstein product in exact arithmetic (object arrays of Fractions), direct formula."""
    pa = [s - 1 for s in a.shape]
    pb = [s - 1 for s in b.shape]
    out = np.empty(tuple(x + y + 1 for x, y in zip(pa, pb)), dtype=object)
    out[...] = Fraction(0)
    for i in np.ndindex(a.shape):
        for j in np.ndindex(b.shape):
            k = tuple(x + y for x, y in zip(i, j))
            w = Fraction(1)
            for ii, jj, p, q in zip(i, j, pa, pb):
                w *= Fraction(comb(p, ii) * comb(q, jj), comb(p + q, ii + jj))
            out[k] += w * a[i] * b[j]
    return out


def _frac_power(a, k):
    out = np.empty((1,) * a.ndim, dtype=object)
    out[...] = Fraction(1)
    for _ in range(k):
        out = _frac_multiply(out, a)
    return out


def _frac_compose(Q, X, W):
    """sum_I Q_I prod_k C(n_k, i_k) X_k^i (W - X_k)^(n_k - i) in exact arithmetic, per component."""
    n = [s - 1 for s in Q.shape[:-1]]
    terms = None
    for I in np.ndindex(Q.shape[:-1]):
        f = None
        for k, i in enumerate(I):
            g = _frac_multiply(_frac_power(X[k], i), _frac_power(W - X[k], n[k] - i)) * comb(n[k], i)
            f = g if f is None else _frac_multiply(f, g)
        contrib = [f * Q[I + (c,)] for c in range(Q.shape[-1])]
        terms = contrib if terms is None else [t + c for t, c in zip(terms, contrib)]
    return terms


@pytest.mark.parametrize(
    "outer_deg, inner_deg, rational",
    [((1, 1, 2), (2, 1), False), ((1, 1, 1), (1, 1, 1), False), ((2, 2, 2), (2,), False), ((1, 1, 2), (2, 1), True)],
)
def test_control_points_equal_exact_rational_arithmetic(outer_deg, inner_deg, rational):
    rng = np.random.default_rng(sum(outer_deg) + len(inner_deg))
    outer = random_outer(rng, outer_deg, rational=False, channels=())
    inner = random_inner(rng, len(inner_deg), inner_deg, rational, np.array([[0.0, 1.0]] * 3), ())
    c = compose(outer, inner)
    assert sum(c.degrees) <= 12
    Q = _frac(outer.control_points)
    Xh = _frac(inner.homogeneous)
    W = Xh[..., -1] if rational else np.full(inner.shape, Fraction(1), dtype=object)
    X = [Xh[..., k] for k in range(3)]
    num = _frac_compose(Q, X, W)
    if rational:
        den = _frac_power(W, sum(outer_deg))
        exact = np.stack([np.vectorize(float)(nk / den) for nk in num], -1)
        exact_w = np.vectorize(float)(den)
        assert rel_err(c.weights, exact_w) < 1e-14
    else:
        exact = np.stack([np.vectorize(float)(nk) for nk in num], -1)
    assert rel_err(c.control_points, exact) < 1e-14


# ---------------------------------------------------------- B-spline outer maps
def test_curve_crossing_knot_lines_is_split_and_merged():
    rng = np.random.default_rng(3)
    outer = pr.annulus(0.5, 1.0, 2.0, angle=np.pi, elements=(3, 2, 2), channels={"k": 3.0})
    t = np.linspace(0, 1, 12)
    cp = np.column_stack([0.5 + 0.45 * np.cos(6 * t), 0.5 + 0.45 * np.sin(6 * t), t, t])
    helix = BSpline((3,), [kn.uniform_knots(3, 9)], cp, channels=("q",))
    c = compose(outer, helix)
    assert c.dim == 1 and c.channels == ("k", "q")
    x = rng.random((1000, 1))
    v = helix(x)
    assert rel_err(c(x), np.column_stack([outer(v[:, :3]), v[:, 3:]])) < 1e-12
    # it is one B-spline on the helix's own parameter domain
    assert np.allclose(c.domain, helix.domain)


def test_surface_crossing_a_knot_line_raises():
    outer = pr.box(elements=(2, 1, 1))
    surf = pr.box((0.6, 0.5, 1e-9), (0.2, 0.2, 0.5)).boundary("wmin")
    with pytest.raises(SplineError, match="crosses the outer map's knot line u = 0.5"):
        compose(outer, surf)


def test_compose_many_matches_compose_and_batches_pieces():
    rng = np.random.default_rng(4)
    outer = random_outer(rng, (2, 2, 3), rational=True, spans=3)
    tile = random_inner(rng, 3, (2, 1, 2), False, np.array([[0.0, 1.0]] * 3))
    P = []
    for _ in range(3):  # placements scattered over the knot spans of the outer map
        e = [int(rng.integers(0, len(outer.breakpoints(j)) - 1)) for j in range(3)]
        lo = np.array([outer.breakpoints(j)[e[j]] for j in range(3)])
        hi = np.array([outer.breakpoints(j)[e[j] + 1] for j in range(3)])
        M = np.zeros((3, 4))
        M[:, :3] = np.diag(hi - lo) * 0.5
        M[:, 3] = lo + 0.25 * (hi - lo)
        P.append(M)
    res = compose_many(outer, tile, np.array(P))
    x = rng.random((500, 3))
    for r, M in zip(res, P):
        placed = tile.affine(M[:, :3], M[:, 3])
        assert rel_err(r(x), compose(outer, placed)(x)) < 1e-12
        v = placed(x)
        assert rel_err(r(x)[:, :3], outer(v[:, :3])[:, :3]) < 1e-12


@pytest.mark.kernel_sensitive
def test_batches_composed_on_several_cores_equal_the_serial_composition(monkeypatch):
    from geometry.composition import core as composition

    rng = np.random.default_rng(8)
    outer = random_outer(rng, (2, 2, 2), rational=True, spans=2)
    tile = random_inner(rng, 3, (2, 2, 2), False, np.array([[0.0, 1.0]] * 3), n_inner=1)
    lo = rng.uniform(0.05, 0.45, (40, 3))  # each placement inside one knot span (the spans split at 0.5)
    lo[20:] += 0.5
    P = np.concatenate([np.stack([np.diag(rng.uniform(0.02, 0.04, 3))] * 40), lo[:, :, None]], axis=2)
    from threadpoolctl import threadpool_info

    held = composition.one_blas_thread
    used = []

    @contextmanager
    def watched():
        with held():
            used.append([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"])
            yield

    monkeypatch.setattr(composition, "one_blas_thread", watched)
    monkeypatch.setattr(composition, "usable_cores", lambda: 2)  # two workers, whatever this machine has
    parallel = compose_many(outer, tile, P)
    monkeypatch.setattr(composition, "usable_cores", lambda: 1)
    serial = compose_many(outer, tile, P)
    # BLAS on one thread in both runs (the pool's and the serial one), so the sums are split alike whatever
    # the machine's thread count: the results are equal to the bit, on every OpenBLAS kernel
    assert len(used) == 2 and all(set(u) == {1} for u in used)
    x = rng.random((200, 3))
    for a, b, M in zip(parallel, serial, P):
        assert np.array_equal(a.control_points, b.control_points) and a.knots[0].tobytes() == b.knots[0].tobytes()
        v = tile.affine(M[:, :3], M[:, 3])(x)
        assert rel_err(a(x)[:, :3], outer(v[:, :3])[:, :3]) < 1e-12


def test_surface_into_surface():
    rng = np.random.default_rng(5)
    sheet = pr.annulus(0.5, 1.0, 1.0, elements=(2, 1, 1)).boundary("wmin")  # a planar ring sector
    strip = BSpline((2, 1), [kn.uniform_knots(2, 1), kn.uniform_knots(1, 1)],
                    np.array([[[0.1, 0.1, 0], [0.1, 0.4, 0]], [[0.3, 0.2, 0], [0.3, 0.3, 0]], [[0.45, 0.1, 0], [0.45, 0.4, 0]]]))
    c = compose(sheet, strip)
    x = rng.random((500, 2))
    assert c.degrees == (2 * 3, 1 * 3)
    assert rel_err(c(x), sheet(strip(x)[:, :2])) < 1e-12


def test_compose_input_errors():
    outer = pr.box(channels={"k": 1.0})
    tile = pr.box((0.5, 0.5, 0.5), channels={"k": 2.0})
    with pytest.raises(SplineError, match="both define channel"):
        compose(outer, tile)
    with pytest.raises(SplineError, match="shape \\(P, 3, 4\\)"):
        compose_many(outer, tile.without_channels(), np.zeros((2, 3, 3)))
    P = np.zeros((1, 3, 4)); P[0, :, :3] = np.eye(3); P[0, :, 3] = 0.8
    with pytest.raises(SplineError, match="placement 0 reaches parameters .* outside the outer domain"):
        compose_many(outer, tile.without_channels(), P)
    with pytest.raises(SplineError, match="surface or a trivariate"):
        compose(tile.boundary("umin").boundary("umin"), tile)


def test_map_points_is_the_approximate_vertex_mode():
    rng = np.random.default_rng(6)
    outer = pr.annulus(elements=(2, 1, 1))
    verts = rng.random((50, 3))
    assert np.array_equal(map_points(outer, verts), outer(verts))
    # the mapped straight edge is not the image of the edge (that is why compose() exists)
    a, b = verts[0], verts[1]
    mid_true = outer(((a + b) / 2)[None])[0, :3]
    mid_poly = (map_points(outer, a[None])[0, :3] + map_points(outer, b[None])[0, :3]) / 2
    assert np.linalg.norm(mid_true - mid_poly) > 1e-6


# ------------------------------------------------------------------ regularity
def test_identity_box_and_annulus_are_regular():
    r = check_regular(pr.box())
    assert r.regular and r.status == "regular" and r.orientation == 1 and bool(r)
    a = check_regular(pr.annulus(elements=(3, 2, 2)))  # exact NURBS, left-handed (angle, radius, z)
    assert a.regular and a.orientation == -1
    assert check_regular(pr.annulus(exact=False)).orientation == -1


def test_nearly_separable_maps_are_decided_by_diagonal_dominance_exactly():
    from geometry.maps import sign_net as N

    rng = np.random.default_rng(12)
    decided = 0
    for trial in range(40):
        degs = tuple(int(p) for p in rng.integers(1, 4, 3))
        knots = [kn.uniform_knots(p, int(rng.integers(1, 5))) for p in degs]
        ns = [len(U) - p - 1 for U, p in zip(knots, degs)]
        lines = [np.cumsum(rng.uniform(-0.2 if trial % 2 else 0.05, 1.0, n)) * rng.choice([-1, 1]) for n in ns]
        cross = rng.uniform(-1, 1, tuple(ns) + (3,)) * 10.0 ** rng.uniform(-16, -1)  # small cross terms
        S = BSpline(degs, knots, np.stack(np.meshgrid(*lines, indexing="ij"), -1) + cross)
        signs = N._separable_signs(S)
        if signs is None:  # not dominant somewhere: the general bound decides (or the Bernstein form)
            continue
        decided += 1
        x = rng.random((3000, 3))
        det = np.linalg.det(S.jacobian(x)[:, :3, :])
        el = tuple(np.minimum((x[:, k] * (len(np.unique(knots[k])) - 1)).astype(int), signs.shape[k] - 1)
                   for k in range(3))
        assert np.all(signs != 0) and np.all(np.sign(det) == signs[el])  # the proven sign, at random points
        assert check_regular(S).status == ("regular" if np.all(signs == signs.flat[0]) else "singular")
    assert decided >= 10
    assert N._separable_signs(pr.twisted(pr.box(), 0.5)) is None  # cross terms of order one: not this path
    cube = pr.box(degrees=(2, 2, 2), elements=(30, 30, 30))  # round-off cross terms (1e-17), decided here
    assert np.array_equal(N._separable_signs(cube), np.ones((30, 30, 30), int))


def test_stacked_net_signs_and_batched_proofs_equal_each_spline_alone():
    from geometry.maps import sign_net as N
    from geometry.maps.regularity import check_regular_many

    rng = np.random.default_rng(21)
    degs, knots = (2, 1, 3), [kn.uniform_knots(2, 3), kn.uniform_knots(1, 2), kn.uniform_knots(3, 2)]
    base = BSpline(degs, knots, np.stack(np.meshgrid(*[kn.greville(U, p) for U, p in zip(knots, degs)],
                                                     indexing="ij"), -1))
    splines = []
    for i, scale in enumerate((1e-17, 1e-3, 0.02, 0.025, 0.03, 0.3)):  # separable, nearly affine, mixed, folded
        for _ in range(4):
            cp = base.control_points + scale * rng.standard_normal(base.control_points.shape)
            cp[..., 0] *= (-1) ** i  # left-handed ones too
            splines.append(BSpline(degs, knots, cp))
    other = pr.twisted(pr.box(degrees=(2, 2, 2), elements=(2, 2, 2)), 0.7)  # another space in the same call
    stacked = N.nearly_affine_stacked(np.stack([s.points for s in splines]), knots, degs)
    alone = [N.nearly_affine(s) for s in splines]
    assert all(np.array_equal(a, b) for a, b in zip(stacked, alone))
    with pytest.raises(SplineError, match="control points must have shape"):
        N.nearly_affine_stacked(np.stack([s.points for s in splines])[:, :-1], knots, degs)
    assert set(np.concatenate([a.ravel() for a in alone]).tolist()) == {-1, 0, 1}
    assert any(np.any(a == 0) and np.any(a != 0) for a in alone)  # partly decided nets among them
    together = check_regular_many(splines + [other], 8, allow_zeros=True)
    for s, r in zip(splines + [other], together):
        one = check_regular(s, 8, allow_zeros=True)
        assert (r.status, r.orientation, r.depth) == (one.status, one.orientation, one.depth)
        assert np.array_equal(r.boxes, one.boxes)
    assert {r.status for r in together} >= {"regular", "singular"}


def test_folded_control_net_is_singular_with_a_box_around_the_fold():
    bx = pr.box(degrees=(2, 1, 1))
    cp = bx.control_points.copy()
    cp[1, :, :, 0] = 1.6  # x(u) = 3.2 u - 2.2 u^2 folds back at u = 3.2 / 4.4
    r = check_regular(BSpline(bx.degrees, bx.knots, cp))
    assert r.status == "singular" and not r
    fold = 3.2 / 4.4
    assert np.any((r.boxes[:, 0, 0] <= fold) & (r.boxes[:, 0, 1] >= fold))
    assert np.all(r.boxes[:, 0, 1] > 0.6)  # nothing reported far from the fold on the regular side


def test_planar_surfaces_in_any_plane_are_proven_in_their_own_plane():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    box, ring = pr.box(degrees=(2, 2, 2), elements=(2, 2, 2)), pr.annulus(elements=(3, 2, 2))
    flat = BSpline(box.boundary("wmin").degrees, box.boundary("wmin").knots, box.boundary("wmin").control_points.copy())
    cp = flat.control_points.copy()
    cp[1, 1, 0] = 5.0  # folds the xy square over itself
    folded = BSpline(flat.degrees, flat.knots, cp)
    for face in ("umin", "umax", "vmin", "vmax", "wmin", "wmax"):  # every face of a box: planes x, y, z = const
        assert check_regular(box.boundary(face)).regular
    assert check_regular(ring.boundary("wmin")).regular  # a rational ring in z = 0
    xy = check_regular(folded)
    assert xy.status == "singular"
    for _ in range(3):  # the same surfaces moved into a random plane: the same verdicts, the same fold boxes
        R, b = Rotation.random(random_state=rng).as_matrix(), rng.uniform(-5, 5, 3)
        assert check_regular(ring.boundary("wmin").affine(R, b)).regular
        r = check_regular(folded.affine(R, b))
        assert r.status == "singular" and np.allclose(r.boxes, xy.boxes)
        assert abs(check_regular(flat.affine(R, b)).orientation) == 1
    bent = flat.control_points.copy()
    bent[1, 1, 2] = 0.3  # one control point out of the plane: a surface in space, not a planar map
    with pytest.raises(SplineError, match="leave their best plane by 0.26"):
        check_regular(BSpline(flat.degrees, flat.knots, bent))


def test_composed_tile_regularity_and_collapsed_map():
    outer = pr.annulus(elements=(2, 1, 1))
    tile = pr.box((0.4, 0.8, 0.8), (0.05, 0.1, 0.1), degrees=(2, 1, 1))
    assert check_regular(compose(outer, tile)).regular
    cp = pr.box().control_points.copy()
    cp[0] = cp[0, 0, 0]  # the umin face collapses to a point
    assert check_regular(BSpline((1, 1, 1), pr.box().knots, cp)).status == "singular"
    with pytest.raises(SplineError, match="planar surface or a trivariate"):
        check_regular(pr.box().boundary("umin").boundary("umin"))


@pytest.mark.parametrize("rational", [False, True])
def test_axis_aligned_boxes_compose_to_the_restricted_map(rational):
    # a box placed by a scaled permutation (with reflections) is the outer map restricted to a
    # sub-box: exact at the outer degrees, permuted to the inner parameter order
    rng = np.random.default_rng(7)
    outer = random_outer(rng, (3, 2, 4), rational, spans=2)
    box = pr.box((0.2, 0.1, 0.15), degrees=(1, 2, 1), elements=(2, 1, 3))
    perms = [np.eye(3), np.eye(3)[[2, 0, 1]], np.diag([-1.0, 0.5, 1.0])[[1, 2, 0]]]
    P = np.zeros((3, 3, 4))
    for i, A in enumerate(perms):
        P[i, :, :3] = A
        lo = (A @ np.stack(np.meshgrid(*[[0, s] for s in (0.2, 0.1, 0.15)], indexing="ij"), -1).reshape(-1, 3).T).min(1)
        P[i, :, 3] = 0.05 - lo  # inside the first knot span in every direction
    res = compose_many(outer, box, P)
    for i, r in enumerate(res):
        xi = rng.random((300, 3)) * (box.domain[:, 1] - box.domain[:, 0]) + box.domain[:, 0]
        ref = outer.evaluate(box.evaluate(xi)[:, :3] @ P[i, :, :3].T + P[i, :, 3])
        assert rel_err(r.evaluate(xi), ref) < 1e-12
        assert r.channels == outer.channels
        assert sorted(r.degrees) == sorted(outer.degrees)  # the outer degrees, not Eq. (7)'s
    assert res[1].degrees == (outer.degrees[1], outer.degrees[2], outer.degrees[0])
    # a rotated box is not axis-aligned: the general product path, Eq. (7) degrees, still exact
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.zeros((1, 3, 4))
    R[0, :, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    R[0, :, 3] = [0.1, 0.05, 0.05]
    rot = compose_many(outer, box, R)[0]
    assert rot.degrees == geometry.result_degrees(outer.degrees, box.degrees)
    xi = rng.random((300, 3)) * (box.domain[:, 1] - box.domain[:, 0]) + box.domain[:, 0]
    ref = outer.evaluate(box.evaluate(xi)[:, :3] @ R[0, :, :3].T + R[0, :, 3])
    assert rel_err(rot.evaluate(xi), ref) < 1e-12


@pytest.mark.slow
@pytest.mark.long
def test_walls_on_knot_planes_flat_placements_and_split_curves_compose_exactly():
    import tiling
    from geometry import knots as kn
    from tiling import library as L

    rng = np.random.default_rng(11)
    # hollow cells in a map with two knot spans along u: the walls on u = 0.5 lie on the knot plane
    D = pr.box(degrees=(2, 2, 2), elements=(2, 1, 1))
    D = BSpline(D.degrees, D.knots, D.control_points + 0.03 * rng.standard_normal(D.control_points.shape))
    ms = tiling.regular(D, L.hollow_box(), (2, 1, 1))
    for P, C in zip(ms.patches, ms.compose_all()):
        t = rng.random((30, 2))
        y = P.spline.evaluate(t)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]
        assert np.abs(C.evaluate(t)[:, :3] - D.evaluate(y)[:, :3]).max() < 1e-12
    # a flat placement: a wall mapped into the plane w = 0.5, the knot plane of a map with two spans along w
    Dw = pr.box(degrees=(2, 2, 2), elements=(1, 1, 2))
    M = np.array([[[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0.5]]])
    wall = L.hollow_box().patches[4]
    [C] = compose_many(Dw, wall, M)
    t = rng.random((30, 2))
    y = wall.evaluate(t)[:, :3] @ M[0, :, :3].T + M[0, :, 3]
    assert np.abs(C.evaluate(t)[:, :3] - Dw.evaluate(y)[:, :3]).max() < 1e-12
    # cubic curves crossing knot lines: split at the crossings, each piece located by its image, not its hull
    D3 = pr.box(degrees=(2, 2, 2), elements=(3, 3, 3))
    D3 = BSpline(D3.degrees, D3.knots, D3.control_points + 0.05 * rng.standard_normal(D3.control_points.shape))
    for _ in range(100):
        c = BSpline((3,), [kn.uniform_knots(3, 3)], rng.uniform(0.02, 0.98, (6, 3)))
        r = compose(D3, c)
        t = np.linspace(0, 1, 97)[:, None]
        assert np.abs(r.evaluate(t)[:, :3] - D3.evaluate(c.evaluate(t)[:, :3])[:, :3]).max() < 1e-11


@pytest.mark.parametrize("rational", [False, True])
def test_a_curve_whose_joint_lies_on_a_knot_line_is_cut_there(rational):
    """Regression: the crossing roots were taken strictly inside the curve's segments, so a C0 joint exactly on
    the outer map's knot line was not a cut and the whole piece was composed with the wrong span's polynomial
    (0.28 off on the trimming loops of the Fig. 7 tile)."""
    p, U, P, w = pr.arc(0.25, 2 * np.pi)  # knots at 0.25, 0.5, 0.75 along s
    cp = np.zeros((len(P), 2, 3))
    cp[..., :2] = 0.5 + P[:, None, :2]
    cp[..., 2] = [0.0, 1.0]
    W = np.repeat(w.reshape(-1, 1), 2, axis=1) if rational else None
    S = BSpline((p, 1), [U, np.array([0.0, 0.0, 1.0, 1.0])], cp, W)
    # a polyline in S's parameters with its joints on s = 0.25 and s = 0.5 exactly
    pts = np.array([[0.1, 0.2, 0], [0.25, 0.9, 0], [0.5, 0.3, 0], [0.7, 0.6, 0]])
    curve = BSpline((1,), [np.r_[0.0, 0.0, 1.0, 2.0, 3.0, 3.0]], pts)
    t = np.random.default_rng(12).uniform(0, 3, 500)[:, None]
    direct = S.evaluate(curve.evaluate(t)[:, :2])[:, :3]
    assert np.abs(compose(S, curve).evaluate(t)[:, :3] - direct).max() < 1e-12


def _affine_outer(rng, degrees, spans, rational, channels=("k",)):
    """An affine map (a sheared, rotated, scaled box with affine channels) at ``degrees``, on random knots."""
    knots = [random_knots(rng, p, spans - 1, max_mult=1) if spans > 1 else kn.uniform_knots(p, 1) for p in degrees]
    g = np.stack(np.meshgrid(*[kn.greville(U, p) for U, p in zip(knots, degrees)], indexing="ij"), -1)
    M = np.eye(3) * rng.uniform(0.5, 2.0, 3) + 0.3 * rng.uniform(-1, 1, (3, 3))
    x = g @ M.T + rng.uniform(-1, 1, 3)
    ch = g @ rng.uniform(-1, 1, (3, len(channels))) + 2.0
    w = np.full(g.shape[:-1], 1.7) if rational else None  # equal weights: still affine
    return BSpline(degrees, knots, np.concatenate([x, ch], -1), w, channels)


@pytest.mark.parametrize("seed", range(12))
def test_an_affine_map_keeps_the_inner_degrees_exactly(seed):
    rng = np.random.default_rng(100 + seed)
    outer = _affine_outer(rng, tuple(int(p) for p in rng.integers(1, 4, 3)), 1 + seed % 3, seed % 4 == 1)
    dim = 1 + seed % 3
    inner = random_inner(rng, dim, tuple(int(p) for p in rng.integers(1, 4, dim)), seed % 2 == 0,
                         np.array([[0.1, 0.9]] * 3), n_inner=seed % 2)
    lo = np.array([outer.breakpoints(k)[0] for k in range(3)])  # the first knot span
    hi = np.array([outer.breakpoints(k)[1] for k in range(3)])
    A = np.zeros((3, 4))
    A[:, :3] = np.diag(0.6 * (hi - lo)) @ rotation(rng)  # rotated (not an axis-aligned box), inside the span
    A[:, 3] = 0.5 * (lo + hi) - A[:, :3] @ np.full(3, 0.5)
    [c] = compose_many(outer, inner, A[None])
    assert c.degrees == inner.degrees and c.channels == outer.channels + inner.channels
    x = rng.random((400, dim)) * (inner.domain[:, 1] - inner.domain[:, 0]) + inner.domain[:, 0]
    v = inner.evaluate(x)
    ref = np.column_stack([outer.evaluate(v[:, :3] @ A[:, :3].T + A[:, 3]), v[:, 3:]])
    assert rel_err(c.evaluate(x), ref) < 1e-13


def test_a_map_affine_on_one_piece_only_composes_each_placement_on_its_own_path():
    rng = np.random.default_rng(7)
    outer = _affine_outer(rng, (2, 2, 2), 2, False, channels=())
    cp = outer.coefficients.copy()
    cp[-1, :, :, 0] += 0.05  # the last control plane in u moves: the second piece in u is curved, the first is not
    first = outer.breakpoints(0)[1]
    assert np.all(outer.knots[0][:3] == 0.0) and 0 < first < 1
    outer = BSpline(outer.degrees, outer.knots, cp)
    inner = random_inner(rng, 3, (2, 1, 2), False, np.array([[0.1, 0.9]] * 3), channels=())
    (v0, v1), (w0, w1) = outer.breakpoints(1)[:2], outer.breakpoints(2)[:2]
    P = np.zeros((2, 3, 4))
    for i, (a, b) in enumerate([(0.0, first), (first, 1.0)]):
        P[i, :, :3] = np.diag([0.6 * (b - a), 0.6 * (v1 - v0), 0.6 * (w1 - w0)]) @ rotation(rng)
        P[i, :, 3] = [0.5 * (a + b), 0.5 * (v0 + v1), 0.5 * (w0 + w1)] - P[i, :, :3] @ np.full(3, 0.5)
    flat, curved = compose_many(outer, inner, P)
    assert flat.degrees == inner.degrees and curved.degrees == geometry.result_degrees(outer.degrees, inner.degrees)
    x = rng.random((400, 3))
    for c, A in zip((flat, curved), P):
        assert rel_err(c.evaluate(x), outer.evaluate(inner.evaluate(x) @ A[:, :3].T + A[:, 3])) < 1e-12
    # off affine by more than round-off: the general path, whatever the size of the deviation
    cp = outer.coefficients.copy()
    cp[0, 0, 0, 1] += 1e-11
    near = compose_many(BSpline(outer.degrees, outer.knots, cp), inner, P[:1])[0]
    assert near.degrees == geometry.result_degrees(outer.degrees, inner.degrees)


def rotation(rng) -> np.ndarray:
    """A random rotation (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def test_a_curve_whose_polygon_crosses_a_knot_plane_while_the_curve_does_not_composes_in_one_piece():
    # the control polygon reaches u = 0.62 past D's knot plane u = 0.5, the curve only 0.41: no cut, one piece
    # (an IndexError on the empty list of cuts took stitched strips and struts down with it)
    D = pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2), elements=(2, 1, 1))
    C = BSpline((2,), [kn.uniform_knots(2, 1)], np.array([[0.2, 0.2, 0.5], [0.62, 0.5, 0.5], [0.2, 0.8, 0.5]]))
    c = compose(D, C)
    x = np.random.default_rng(2).random((200, 1))
    assert c.knots[0].size == 2 * (c.degrees[0] + 1)  # one Bezier piece
    assert rel_err(c.evaluate(x)[:, :3], D.evaluate(C.evaluate(x)[:, :3])[:, :3]) < 1e-12


def test_the_helical_tubes_join_when_stacked_and_compose_exactly_into_the_trefoil():
    from geometry.errors import SplineError
    from geometry.shapes.sweep import box_sweep, trefoil
    from tiling import TilingError, regular
    from tiling.library import helical_tubes

    tubes = helical_tubes(0.22, 0.12).patches
    rng = np.random.default_rng(3)
    t = rng.random(40)
    for k in range(4):  # tube k enters where tube k - 1 leaves one cell lower: stacked copies are four helices
        enter = tubes[k].evaluate(np.column_stack([np.zeros_like(t), t]))
        leave = tubes[k - 1].evaluate(np.column_stack([np.ones_like(t), t]))
        assert np.abs(enter - (leave - [0.0, 0.0, 1.0])).max() < 1e-12
    D = trefoil(12, 0.2)
    corners = D.control_points[[0, 3, 0], [0, 0, 3]]  # the square section at every control layer
    assert np.allclose(np.linalg.norm(corners[1] - corners[0], axis=-1), 0.4)
    assert np.allclose(np.einsum("ij,ij->i", corners[1] - corners[0], corners[2] - corners[0]), 0.0, atol=1e-12)
    ms = regular(D, helical_tubes(), (1, 1, 1))
    for P, C in zip(ms.patches[:8], ms.compose_all()[:8]):  # exact: D(A S + b) at random parameters
        st = rng.random((20, 2))
        y = P.spline.evaluate(st)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]
        assert np.abs(C.evaluate(st)[:, :3] - D.evaluate(y)[:, :3]).max() < 1e-11
    for bad in ({"n": 3}, {"n": 2.5}, {"half_side": 0.7}, {"half_side": float("nan")}):
        with pytest.raises(SplineError, match="trefoil"):
            trefoil(**bad)
    with pytest.raises(SplineError, match="box_sweep: axis must be a cubic B-spline curve"):
        box_sweep(pr.box(), 0.1)
    with pytest.raises(SplineError, match="box_sweep: half_side"):
        box_sweep(BSpline((3,), [kn.uniform_knots(3, 1)], np.eye(4, 3)), -1.0)
    for bad in ({"radius": 0.4}, {"tube": -0.1}, {"radius": "0.2"}):
        with pytest.raises(TilingError, match="helical_tubes"):
            helical_tubes(**bad)
