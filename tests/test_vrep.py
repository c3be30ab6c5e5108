"""V-rep Boolean models (Hong and Elber 2021, Section 3.1): membership, tile classification, kept tiles."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from geometry.shapes.examples import cylinder
from tiling import TilingError
from tiling import library as L
from helpers import face_params
from tiling.vrep import (INSIDE, INTERSECTING, MARGIN, OUTSIDE, TO_BE_BRIDGED, Primitive, classify,
                         vrep_microstructure)


def _cylinders(counts=(3, 3, 6)):
    A = Primitive(cylinder(1.0, 4.0, 0), L.cross(), counts, priority=3, name="A")
    B = Primitive(cylinder(1.0, 4.0, 1), L.cross(), counts, priority=2, name="B")
    C = Primitive(cylinder(0.8, 4.0, 2), L.cross(), counts, priority=1, name="C")
    return A, B, C


def _random_points(prim, cls, tiles, n, rng):
    """n random physical points in each of the given tiles' cells (uniform in parameters)."""
    boxes = cls.cells[tiles]  # (T, 3, 2)
    u = rng.random((len(tiles), n, 3))
    params = boxes[:, None, :, 0] + u * (boxes[:, None, :, 1] - boxes[:, None, :, 0])
    return prim.D.evaluate(params.reshape(-1, 3))[:, :3].reshape(len(tiles), n, 3)


@pytest.mark.parametrize("op", ["union", "subtract"])
def test_classification_agrees_with_brute_force_membership(op):
    A, B, C = _cylinders()
    model = (A | B | C) if op == "union" else (A - B - C)
    rng = np.random.default_rng(7)
    for prim in model.positive():
        cls = classify(model, prim)
        for state, want in ((INSIDE, True), (TO_BE_BRIDGED, True), (OUTSIDE, False)):
            tiles = np.flatnonzero(cls.state == state)
            if not len(tiles):
                continue
            pick = rng.choice(tiles, size=min(12, len(tiles)), replace=False)
            pts = _random_points(prim, cls, pick, 150, rng)
            inside = model.territory(prim, pts.reshape(-1, 3)).reshape(len(pick), -1)
            assert np.all(inside == want), (prim.name, state)
        # an intersecting tile really straddles a trimming surface (dense samples on both sides)
        tiles = np.flatnonzero(cls.state == INTERSECTING)
        if len(tiles):
            pick = rng.choice(tiles, size=min(8, len(tiles)), replace=False)
            pts = _random_points(prim, cls, pick, 400, rng)
            inside = model.territory(prim, pts.reshape(-1, 3)).reshape(len(pick), -1)
            assert np.all(inside.any(axis=1) & ~inside.all(axis=1))


@pytest.mark.slow
@pytest.mark.kernel_sensitive
def test_a_subtraction_keeps_no_tile_inside_the_subtracted_primitives():
    A, B, C = _cylinders()
    res = vrep_microstructure(A - B - C)
    ms = res.microstructure
    assert len(ms.patches) > 0 and set(res.counts()) == {"A"}
    first_bridge = min(p for p, _ in ms.tags["bridge"])
    rng = np.random.default_rng(3)

    def points(patches, r_max=1.0):
        return np.concatenate([P.image(P.spline.domain[:, 0] + rng.random((20, 3)) * np.ptp(P.spline.domain, axis=1)
                                       * [1.0, 1.0, r_max]) for P in patches])

    pts = points(ms.patches[:first_bridge])
    assert not B.contains(pts).any() and not C.contains(pts).any()
    assert A.contains(pts).all()
    # bridges end on the trimming surface (their far section is snapped onto it through A's map): they enter
    # the subtracted primitives by at most a second-order sliver, 0.1% of the cylinders' diameter
    from geometry.faces import FACE_NAMES
    from geometry.maps.inversion import invert

    pts = points(ms.patches[first_bridge:])
    for Q in (B, C):
        inside = pts[Q.contains(pts)]
        if len(inside):
            depth = np.min([invert(Q.D.boundary(f), inside).distance for f in FACE_NAMES], axis=0)
            assert depth.max() < 2e-3


@pytest.mark.slow
def test_union_tiles_each_v_cell_from_the_primitive_of_highest_priority():
    A, B, C = _cylinders((2, 2, 4))
    res = vrep_microstructure(A | B | C)
    counts = res.counts()
    assert counts["A"]["outside"] == counts["A"]["intersecting"] == 0  # A is first: all its tiles stay
    for name in "BC":  # they lose the tiles of what A already tiles
        assert counts[name]["outside"] + counts[name]["intersecting"] > 0
    ms = res.microstructure
    for name in "ABC":
        assert ms.tags[name]
    assert ms.tags["anchor"] and not ms.tags["anchor:A"]  # only B and C are cut by higher priorities
    # every anchoring face is glued to exactly one bridge (an identity interface), every bridge to one face
    first = min(p for p, _ in ms.tags["bridge"])
    partner = {}
    for i in ms.interfaces:
        for (p, f), (q, _) in ((i.a, i.b), (i.b, i.a)):
            if p < first <= q:
                partner.setdefault((p, f), []).append(q)
    assert all(len(partner.get(a, [])) <= 1 for a in ms.tags["anchor"])
    glued = sum(len(partner.get(a, [])) for a in ms.tags["anchor"])
    rep = res.bridges
    assert rep.union.anchors > 0 and rep.union.two_to_one + rep.union.one_to_one > 0
    assert len(ms.patches) - first == rep.bridges == rep.surface_bridges + sum(len(u.patches) for u in res.unions)
    # an anchor is glued to a bridge to the surface, to a union bridge, or left open (unmatched or eliminated)
    assert glued == rep.surface_bridges + rep.union.anchors - rep.union.open_anchors
    assert (rep.surface_bridges + rep.collisions.eliminated + rep.folded + rep.surface.dropped
            + rep.union.anchors == len(ms.tags["anchor"]))


def test_a_margin_purges_bridged_tiles_too_close_to_the_surface():
    A, B, C = _cylinders()
    model = A - B
    plain, purged = classify(model, A), classify(model, A, margin=0.4)
    assert np.sum(purged.state == MARGIN) > 0 and np.sum(purged.state == TO_BE_BRIDGED) > 0
    assert np.sum(purged.state == TO_BE_BRIDGED) + np.sum(purged.state == MARGIN) == np.sum(plain.state == TO_BE_BRIDGED)
    # independent check: dense points of the kept bridged tiles stay at least the margin away from B
    rng = np.random.default_rng(5)
    kept = np.flatnonzero(purged.state == TO_BE_BRIDGED)
    pts = _random_points(A, purged, kept, 100, rng).reshape(-1, 3)
    assert B.distance(pts).min() >= 0.4 - 0.05  # samples of 4^3 per tile bound the distance within a tile's step


def test_distance_to_a_primitive_is_the_distance_to_its_boundary_and_within_agrees_with_it():
    from scipy.spatial import cKDTree

    from geometry.faces import FACE_NAMES

    _, B, _ = _cylinders()
    rng = np.random.default_rng(11)
    lo, hi = B.D.bounding_box().T
    pts = rng.uniform(lo - 0.6, hi + 0.6, (1500, 3))
    # independent: the nearest of dense samples of the six boundary surfaces (an upper bound, h-accurate)
    g = np.linspace(0.0, 1.0, 241)
    st = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    dense = np.concatenate([B.D.boundary(f).evaluate(st)[:, :3] for f in FACE_NAMES])
    upper, _ = cKDTree(dense).query(pts)
    d = B.distance(pts)
    inside = B.contains(pts)
    assert inside.sum() > 100 and np.all(d[inside] == 0.0)
    out = ~inside
    assert np.all(d[out] <= upper[out] * (1 + 1e-6))  # not beyond a point of the boundary (a stall stops at 1e-6)
    assert np.all(d[out] >= upper[out] - 0.02)  # and within the dense samples' spacing of the nearest one
    for r in (0.05, 0.3):
        w = B.within(pts, r)
        clear = np.abs(d - r) > 1e-9
        assert np.array_equal(w[clear], (d < r)[clear]) and w[inside].all()
    for bad in (0.0, -1.0, float("nan"), "0.3", True):
        with pytest.raises(TilingError, match="positive number"):
            B.within(pts[:3], bad)


@pytest.mark.kernel_sensitive
@pytest.mark.parametrize("damped", [False, True])
def test_the_nearest_boundary_surface_is_the_one_every_inversion_would_choose(damped):
    from geometry.errors import SplineError
    from geometry.faces import FACE_NAMES
    from geometry.maps.inversion import invert, invert_nearest

    _, B, _ = _cylinders()
    faces = [B.D.boundary(f) for f in FACE_NAMES]
    rng = np.random.default_rng(5)
    lo, hi = B.D.bounding_box().T
    pts = np.concatenate([rng.uniform(lo - 0.6, hi + 0.6, (600, 3)),  # around and inside the cylinder
                          faces[0].evaluate(rng.random((50, 2)))[:, :3]])  # on a face: ties broken as argmin does
    invs = [invert(S, pts, damped=damped) for S in faces]  # every point into every face: the reference
    dist = np.stack([v.distance for v in invs])
    near, inv = invert_nearest(faces, pts, damped=damped)
    # the reference choice: the lowest index within the stated tie margin of the least distance, so the choice
    # does not rest on the last bits (COINCIDENT x the faces' size)
    from geometry.tolerances import COINCIDENT
    boxes = np.array([S.bounding_box() for S in faces])
    margin = COINCIDENT * float(np.max(boxes[:, :, 1].max(0) - boxes[:, :, 0].min(0)))
    ref = np.argmax(dist <= dist.min(axis=0) + margin, axis=0)
    assert np.array_equal(near, ref) and np.any(ref != np.argmin(dist, axis=0))  # the points on face 0 tie
    assert np.array_equal(inv.distance, dist[ref, np.arange(len(pts))])
    assert np.all(inv.distance <= dist.min(axis=0) + margin)
    assert np.array_equal(inv.params, np.stack([v.params for v in invs])[near, np.arange(len(pts))])
    assert np.array_equal(inv.inside, np.stack([v.inside for v in invs])[near, np.arange(len(pts))])
    with pytest.raises(SplineError, match="finite array of shape"):
        invert_nearest(faces, np.array([[0.0, np.nan, 1.0]]))
    with pytest.raises(SplineError, match="one or more splines of one dimension"):
        invert_nearest([], pts[:2])
    with pytest.raises(SplineError, match="one or more splines of one dimension"):
        invert_nearest(faces + [B.D], pts[:2])
    empty, none = invert_nearest(faces, np.zeros((0, 3)))
    assert empty.shape == (0,) and none.params.shape == (0, 2)


def test_v_model_bad_input():
    A, B, C = _cylinders()
    far = Primitive(cylinder(0.5, 1.0, 2, centre=(10.0, 10.0, 0.0)), L.cross(), (2, 2, 2), priority=5, name="far")
    with pytest.raises(TilingError, match="intersection.*empty"):
        vrep_microstructure(A & far)
    same = Primitive(cylinder(1.0, 4.0, 1), L.cross(), (2, 2, 2), priority=3, name="B3")
    with pytest.raises(TilingError, match="'A' and 'B3' overlap and have the same priority 3"):
        vrep_microstructure(A | same)
    with pytest.raises(TilingError, match="names must be distinct"):
        vrep_microstructure(A | Primitive(cylinder(1.0, 4.0, 1), L.cross(), (2, 2, 2), priority=1, name="A"))
    with pytest.raises(TilingError, match="operands"):
        A | "cylinder"
    with pytest.raises(TilingError, match="no primitive that carries tiles|V-model"):
        vrep_microstructure(A)
    floating = tiling.Tile([pr.box((0.5, 0.5, 0.5), (0.25, 0.25, 0.25))], name="floating block")
    F = Primitive(cylinder(1.0, 4.0, 0), floating, (3, 3, 6), priority=3, name="F")
    with pytest.raises(TilingError, match="'F'.*'floating block' has no patch face on the cell walls"):
        vrep_microstructure(F - B)
    with pytest.raises(TilingError, match="priority must be an integer"):
        Primitive(cylinder(), L.cross(), (2, 2, 2), priority=1.5, name="bad")


def _angle_deg(a, b):
    c = np.abs(np.sum(a * b, axis=-1)) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _oriented(st, swap, flip):
    """Face b's parameters of face a's st under an interface orientation (geometry.Interface's convention)."""
    out = st[:, ::-1].copy() if swap else st.copy()
    for d in (0, 1):
        if flip[d]:
            out[:, d] = 1.0 - out[:, d]
    return out


@pytest.mark.slow
@pytest.mark.kernel_sensitive
def test_bridges_start_g1_at_their_tiles_and_end_orthogonal_on_the_trimming_surface():
    """Every bridge (in map parameters, or rebuilt in space where D's knot lines cut it) is glued to its tile by
    an identity interface, its face equal to the tile's point by point and G1 across it, and ends on the
    trimming surface, orthogonal to it."""
    from geometry.patches.chain import patch_geometry_points
    from geometry.faces import FACE_AXIS, FACE_NAMES
    from geometry.maps.inversion import invert

    A, B, C = _cylinders()
    res = vrep_microstructure(A - B)
    ms = res.microstructure
    assert res.bridges.bridges == res.bridges.surface.anchoring_faces > 0
    first = min(p for p, _ in ms.tags["bridge"])
    rng = np.random.default_rng(11)
    faces = [B.D.boundary(f) for f in FACE_NAMES]
    for j in range(first, len(ms.patches)):  # every bridge
        links = [(i.a, i.b, i.swap, i.flip) if i.a[0] < first else (i.b, i.a, i.swap, i.flip[::-1] if i.swap else i.flip)
                 for i in ms.interfaces if j in (i.a[0], i.b[0])]
        assert len(links) == 1 and links[0][0][0] < first  # glued to one tile face, nothing else
        (tp, tface), (_, bface), swap, flip = links[0]
        st = rng.random((15, 2))
        xt, Jt, _ = patch_geometry_points(ms.patches[tp], face_params(ms.patches[tp], tface, st))
        xb, Jb, _ = patch_geometry_points(ms.patches[j], face_params(ms.patches[j], bface, _oriented(st, swap, flip)))
        assert np.abs(xt - xb).max() < 1e-10  # the same face, point by point
        kt, kb = FACE_AXIS[tface][0], FACE_AXIS[bface][0]
        assert _angle_deg(Jt[:, :, kt], Jb[:, :, kb]).max() < 1e-6  # G1: cross derivatives parallel
        # the other end lies on the trimming surface (B's boundary), the bridge arriving along its normal
        far = "wmax" if bface == "wmin" else "wmin"
        xe, Je, _ = patch_geometry_points(ms.patches[j], face_params(ms.patches[j], far, np.array([[0.5, 0.5]])))
        best = min((invert(G, xe) for G in faces), key=lambda r: r.distance[0])
        G = faces[[invert(G, xe).distance[0] for G in faces].index(best.distance[0])]
        width = float(np.ptp(xt, axis=0).max())
        assert best.distance[0] < 1e-2 * width  # control points on the surface; the face between them within 1%
        _, J = G.value_and_jacobian(best.params)
        assert _angle_deg(Je[0, :, 2], np.cross(J[0, :3, 0], J[0, :3, 1])) < 1.0
    assert any(b.geometry is not None for b in res.bridge_objects)  # D's knot lines cut some: rebuilt in space


def _bridge_objects(model):
    from tiling.vrep.bridges import build_bridges

    res = vrep_microstructure(model, bridges=False)
    cls = res.classifications[0]
    ms = res.microstructure
    return build_bridges(model, cls.primitive, cls, ms.patches, ms.tags[f"anchor:{cls.primitive.name}"])[0]


@pytest.mark.slow
@pytest.mark.kernel_sensitive
def test_colliding_bridges_are_separated_or_eliminated():
    from tiling.vrep.bridges import _snap, axis_samples, resolve_collisions

    A, B, C = _cylinders()
    bridges = _bridge_objects(A - B)
    # cross two neighbouring bridges by exchanging their far ends: their tubes now intersect
    a, b = bridges[0], min(bridges[1:], key=lambda x: np.linalg.norm(x.axis[0] - bridges[0].axis[0]))
    a.axis[2:], b.axis[2:] = b.axis[2:].copy(), a.axis[2:].copy()
    a.axis[2], b.axis[2] = a.axis[2] + 0.3 * (b.axis[3] - a.axis[3]), b.axis[2] + 0.3 * (a.axis[3] - b.axis[3])
    _snap([a, b])
    kept, counts = resolve_collisions(bridges)
    assert counts.collisions >= 1 and counts.swapped + counts.repelled + counts.eliminated >= 1
    # every kept bridge's control net follows its final axis (the moved ones are snapped in one batch at the end)
    nets = [x.spline.control_points.copy() for x in kept]
    _snap(kept)
    assert max(np.abs(x.spline.control_points - n).max() for x, n in zip(kept, nets)) < 1e-12
    for i, x in enumerate(kept):
        for y in kept[i + 1:]:
            if np.linalg.norm(x.axis[0] - y.axis[0]) > 3.0:
                continue
            d = np.linalg.norm(axis_samples(x)[:, None] - axis_samples(y)[None], axis=2).min()
            assert d >= (x.radius + y.radius) * (1 - 1e-9)


def test_v_cells_name_their_primitives_owner_and_trimming_surfaces():
    A, B, C = _cylinders((1, 1, 4))
    cells = (A | B).cells()
    sig = {tuple(p.name for p in c.inside): c for c in cells}
    assert set(sig) == {("A",), ("B",), ("A", "B")}  # A - B, B - A and A n B
    assert sig[("A", "B")].owner is A and sig[("B",)].owner is B  # the shared cell is tiled by the higher priority
    assert {p.name for p in sig[("A",)].trimmed_by} == {"A", "B"}
    assert [tuple(p.name for p in c.inside) for c in (A - B).cells()] == [("A",)]


def test_the_primitives_materials_reach_the_patches():
    from geometry import BSpline
    from geometry.patches.chain import patch_geometry_points

    def with_k(D, k):
        cp = np.concatenate([D.control_points, np.full(D.control_points.shape[:-1] + (1,), k)], -1)
        return BSpline(D.degrees, D.knots, cp, D.weights, ("k",))

    A = Primitive(with_k(cylinder(1.0, 4.0, 0), 205.0), L.cross(), (1, 1, 6), priority=2, name="aluminium")
    B = Primitive(with_k(cylinder(1.0, 4.0, 1), 54.0), L.cross(), (1, 1, 6), priority=1, name="steel")
    ms = vrep_microstructure(A | B).microstructure
    for name, k in (("aluminium", 205.0), ("steel", 54.0)):
        p, _ = ms.tags[name][0]
        P = ms.patches[p]
        _, _, chans = patch_geometry_points(P, P.spline.domain.mean(1)[None])
        assert "k" in P.channels and chans["k"][0] == pytest.approx(k)


def test_after_collision_handling_no_two_bridges_intersect():
    from tiling.vrep.bridges import axis_samples

    A, B, C = _cylinders((1, 1, 12))
    res = vrep_microstructure((A | B) - C)  # bridges of A and B converge on C: collisions happen
    assert res.bridges.collisions.collisions > 0
    ms = res.microstructure
    first = min(p for p, _ in ms.tags["bridge"])
    # the tubes' centre lines, sampled in space, against the sum of the inscribed radii (as the handling does)
    kept = res.bridge_objects
    assert len(kept) == len(ms.patches) - first
    for i, x in enumerate(kept):
        px = axis_samples(x)
        for y in kept[i + 1:]:
            d = np.linalg.norm(px[:, None] - axis_samples(y)[None], axis=2).min()
            assert d >= (x.radius + y.radius) * (1 - 1e-9)


def test_v_models_and_primitives_print_as_their_expression():
    from tiling.vrep import examples as ex

    m = ex.winged_duck()
    assert repr(m) == "VModel(((body | wingL) | wingR) - hole)"
    assert repr(m.primitives()[0]).startswith("Primitive('body': tile 'cross' x (10, 10, 12), priority 1")


@pytest.mark.slow
@pytest.mark.kernel_sensitive
@pytest.mark.long
def test_a_v_model_with_bridges_across_knot_lines_composes_exactly_and_exports_to_iges(tmp_path):
    """(A u B) - C: some bridges to C cross knot lines of their map; rebuilt in space, every patch composes into
    one exact B-spline (compose_all), every bridge's composed spline equals its chain-rule evaluation at random
    points, and the boundary goes to IGES."""
    from geometry.patches.chain import patch_geometry_points
    from geometry.io.iges import write_iges
    from tiling.export import boundary_splines
    from tiling.vrep.spatial import crosses_knot_lines

    A, B, C = _cylinders((1, 1, 12))  # Hong and Elber 2021, Figs. 13-14 (tiling.vrep.examples.cylinders)
    res = vrep_microstructure((A | B) - C)
    ms = res.microstructure
    crossing = [b for b in res.bridge_objects if crosses_knot_lines(b)]
    assert crossing and all(b.geometry is not None for b in crossing)
    # no bridge of this model folds: a decision that rested on round-off gave one up on some OpenBLAS kernels
    # (collisions resolved in the KD-tree's order, the nearest trimming face chosen on a near tie); .ci/run
    # runs this test under a second kernel
    assert res.bridges.folded == 0 and res.bridges.surface_bridges == res.bridges.surface.built
    composed = ms.compose_all()
    first = min(p for p, _ in ms.tags["bridge"])
    rng = np.random.default_rng(5)
    for j in range(first, len(ms.patches)):
        P = ms.patches[j]
        x = P.spline.domain[:, 0] + rng.random((30, 3)) * np.ptp(P.spline.domain, axis=1)
        direct = patch_geometry_points(P, x)[0]
        assert np.abs(composed[j].evaluate(x)[:, :3] - direct).max() <= 1e-12 * np.abs(direct).max()
    path = write_iges(tmp_path / "model.igs", boundary_splines(ms))
    assert path.stat().st_size > 0
