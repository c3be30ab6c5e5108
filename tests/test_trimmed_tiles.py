"""Trimmed surfaces as tile members (Elber 2017, Fig. 7): the three concentric trimmed through-cylinders,
exact loops, paved (4, 4, 2) and composed exactly, tessellated, exported to IGES 144 and re-read by OpenCASCADE."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from geometry import BSpline, TrimmedSurface, primitives
from tiling import Tile, TilingError, compose_levels, graded, hierarchical, library, regular
from tiling.members.cylinders import through_cylinders, through_cylinders_area
from tiling.export import boundary_splines, write_iges
from helpers import opencascade

R = 0.25


@pytest.fixture(scope="module")
def tile():
    return through_cylinders(R)  # (built once: its loops are checked on construction)


def _bent_map():
    D = primitives.box((4.0, 4.0, 2.0)).elevate_to((2, 2, 2))
    P = D.control_points.copy()
    P[..., 2] += 0.4 * np.sin(0.8 * P[..., 0]) * (1 + 0.2 * P[..., 1])
    return BSpline(D.degrees, D.knots, P)


def _on_other_cylinders(x):
    """Distance of tile points (N, 3) to the nearest of the three cylinders of radius R about the cell's centre."""
    c = x - 0.5
    d = [np.abs(np.hypot(c[:, j], c[:, k]) - R) for j, k in ((1, 2), (0, 2), (0, 1))]
    return np.sort(np.stack(d, 1), axis=1)


def _to_polyline(poly, tree, x):
    """Distance of points x (N, 3) to the polyline ``poly`` (M, 3) (``tree``: its cKDTree): to the segments on
    either side of the nearest vertex."""
    i = tree.query(x)[1]
    out = np.full(len(x), np.inf)
    for a, b in ((np.maximum(i - 1, 0), i), (i, np.minimum(i + 1, len(poly) - 1))):
        d = poly[b] - poly[a]
        s = np.clip(np.einsum("ij,ij->i", x - poly[a], d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
        out = np.minimum(out, np.linalg.norm(poly[a] + s[:, None] * d - x, axis=1))
    return out


def test_the_fig7_tile_is_six_trimmed_surfaces_whose_loops_are_the_exact_intersection_curves(tile):
    assert tile.patches == [] and len(tile.trimmed) == 6
    rng = np.random.default_rng(3)
    for T in tile.trimmed:
        loop = T.loops[0]
        t = rng.uniform(*loop.domain[0], 4000)
        uv = loop.evaluate(t[:, None])[:, :2]
        x = T.surface.evaluate(uv)[:, :3]
        d = _on_other_cylinders(x)
        assert d[:, 0].max() < 1e-12  # on its own cylinder
        seam = np.min(np.abs(uv[:, :1] - [0.0, 1.0]), axis=1) < 1e-12  # the line s = 0 = 1 of the surface
        wall = np.min(np.abs(uv[:, 1:] - [0.0, 1.0]), axis=1) < 1e-12  # the opening on a cell wall
        curve = ~seam & ~wall
        # the rest of the loop is the Steinmetz curve: on a second cylinder, exactly
        assert curve.mean() > 0.2 and d[curve, 1].max() < 1e-12
        assert np.abs(np.min(np.minimum(np.abs(x[wall]), np.abs(x[wall] - 1)), axis=1)).max() < 1e-12
        # kept points lie outside the other two cylinders, cut-away ones inside one of them
        uv = T.surface.domain[:, 0] + rng.random((4000, 2)) * np.ptp(T.surface.domain, axis=1)
        x = T.surface.evaluate(uv)[:, :3] - 0.5
        dist = np.stack([np.hypot(x[:, j], x[:, k]) for j, k in ((1, 2), (0, 2), (0, 1))], 1)
        own = np.argmin(np.abs(dist - R).max(axis=0))  # the cylinder the member lies on
        near = np.delete(dist, own, axis=1).min(axis=1)  # distance to the nearer other axis
        clear = np.abs(near - R) > 1e-3  # (contains() reads the loops from dense polylines)
        assert clear.mean() > 0.5 and np.array_equal(T.contains(uv)[clear], near[clear] > R)
    # the area of the kept regions is 6 r (pi - 4 sqrt(2) r) in the unit cell (to quadrature accuracy)
    assert sum(T.area(3e-3) for T in tile.trimmed) == pytest.approx(through_cylinders_area(R), rel=1e-9)


def test_paved_4_4_2_in_a_bent_map_composes_every_member_exactly_with_its_loops_carried(tile):
    D = _bent_map()
    ms = regular(D, tile, (4, 4, 2))
    assert ms.n_tiles == 32 and len(ms.trimmed) == 192 and ms.patches == []
    composed = boundary_splines(ms)
    assert len(composed) == 192 and all(isinstance(T, TrimmedSurface) for T in composed)
    rng = np.random.default_rng(4)
    for m, T in zip(ms.trimmed[::17], composed[::17]):
        assert T.loops == m.trimmed.loops  # the loops are carried unaltered
        uv = T.surface.domain[:, 0] + rng.random((200, 2)) * np.ptp(T.surface.domain, axis=1)
        A = m.placed.placement
        direct = D.evaluate(m.trimmed.surface.evaluate(uv)[:, :3] @ A[:, :3].T + A[:, 3])[:, :3]
        assert np.abs(T.surface.evaluate(uv)[:, :3] - direct).max() < 1e-12
    # the boundary mesh draws the members, numbered after the (no) patches, with their levels
    mesh = ms.surface(samples=2)
    assert mesh.n_cells > 0 and set(np.unique(mesh.cell_data["patch"])) == set(range(192))
    assert np.all(mesh.cell_data["level"] == 0)
    lo, hi = np.asarray(mesh.points).min(0), np.asarray(mesh.points).max(0)
    box = np.array([P.evaluate(np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)]))
                    for P in [D]])[0][:, :3]
    assert np.all(lo >= box.min(0) - 0.5) and np.all(hi <= box.max(0) + 0.5)


@pytest.mark.slow
def test_the_fig7_paving_goes_to_iges_and_opencascade_reads_the_trimmed_faces(tmp_path, tile):
    """A second reader: gmsh's OpenCASCADE import gives 192 trimmed faces, each our composed surface point for
    point, bounded by our loops' images, with our areas (within OpenCASCADE's own area integration)."""
    D = _bent_map()
    ms = regular(D, tile, (4, 4, 2))
    composed = boundary_splines(ms)
    path = write_iges(tmp_path / "fig7.igs", ms, units="mm")
    flat = regular(primitives.box((2.0, 1.0, 1.0)), tile, (2, 1, 1))  # unit cells: the formula's area each
    flat_path = write_iges(tmp_path / "fig7_flat.igs", flat, units="mm")
    rng = np.random.default_rng(5)
    with opencascade(path) as (gmsh, tags):
        assert len(tags) == 192
        for j in rng.choice(192, 4, replace=False):
            tag, T = tags[j], composed[j]
            uv = T.surface.domain[:, 0] + rng.random((30, 2)) * np.ptp(T.surface.domain, axis=1)
            got = np.array(gmsh.model.getValue(2, tag, uv.ravel())).reshape(-1, 3)
            assert np.abs(got - T.surface.evaluate(uv)[:, :3]).max() < 1e-10
            # the face's boundary, as OpenCASCADE trims it, is our loop: its curves on the surface (pcurves) are
            # our loop in the parameter plane, and its edges in space our loop's image within OpenCASCADE's
            # own approximation of edges from pcurves (measured 4.4e-6 on a model of size 4)
            loop, image = T.loops[0], T.boundary_curves()[0]
            t = np.linspace(*loop.domain[0], 100_001)[:, None]
            flat, dense = np.c_[loop.evaluate(t)[:, :2], np.zeros(len(t))], image.evaluate(t)[:, :3]
            trees = cKDTree(flat), cKDTree(dense)
            for _, c in gmsh.model.getBoundary([(2, tag)], oriented=False):
                lo, hi = gmsh.model.getParametrizationBounds(1, abs(c))
                s = np.linspace(lo[0], hi[0], 25)
                uv = np.array(gmsh.model.reparametrizeOnSurface(1, abs(c), s, tag)).reshape(-1, 2)
                assert _to_polyline(flat, trees[0], np.c_[uv, np.zeros(len(uv))]).max() < 1e-8
                x = np.array(gmsh.model.getValue(1, abs(c), s)).reshape(-1, 3)
                assert _to_polyline(dense, trees[1], x).max() < 1e-5
            # OpenCASCADE integrates rational faces to about 2e-3 (measured on an exact cylinder: +1.75e-3)
            assert gmsh.model.occ.getMass(2, tag) == pytest.approx(T.area(3e-3), rel=3e-3)
    with opencascade(flat_path) as (gmsh, tags):
        total = sum(gmsh.model.occ.getMass(2, t) for t in tags)
    assert total == pytest.approx(2 * through_cylinders_area(R), rel=3e-3)


def test_builders_that_do_not_place_trimmed_members_say_so(tile):
    D = primitives.box()
    with pytest.raises(TilingError, match="trimmed surface members, which seal='cap'"):
        regular(D, tile, (2, 2, 2), seal="cap")
    with pytest.raises(TilingError, match="which the graded paving does not place"):
        graded(D, lambda lo, hi: tile, (1, 1, 2), lambda s: 0.2 + 0.1 * s)
    branching = library.heat_sink_t1()
    mixed = Tile(branching.patches + tile.trimmed, branching.branch_in,
                 [(b.patch, b.face, b.box) for b in branching.branch_outs], name="mixed")
    with pytest.raises(TilingError, match="which the hierarchical paving does not place"):
        hierarchical(primitives.box(), mixed, (1, 1), 2)


def test_two_level_compose_carries_the_trimmed_members(tile):
    first = regular(primitives.box((2.0, 1.0, 1.0)), library.cross(), (1, 1, 1))
    ms = compose_levels(first, tile, (1, 1, 1), degree=None)
    assert len(ms.trimmed) == 6 * len(first.patches) and ms.n_tiles == len(first.patches)
    assert len(boundary_splines(ms)) == len(ms.trimmed)


def test_bad_trimmed_members_and_radii_are_refused(tile):
    T = tile.trimmed[0]
    big = TrimmedSurface.with_loops_of(T, T.surface.affine(2 * np.eye(3), np.zeros(3)))  # twice the cell
    with pytest.raises(TilingError, match="trimmed member 0 leaves the unit cube"):
        Tile([big])
    with pytest.raises(TilingError, match="trimmed member 0 is a str"):
        Tile([], trimmed=["x"])
    with pytest.raises(TilingError, match="has no patches"):
        Tile([])
    for r in (0.0, 0.5, -1, float("nan"), "0.2", True):
        with pytest.raises(TilingError, match="radius must be a number in"):
            through_cylinders(r)


def test_the_members_weld_along_their_shared_curves_into_one_network_open_only_on_d(tile):
    """The cylinders' shared intersection curves are stitched (each side takes the other's samples), so the
    triangle mesh is open only at the tubes' openings on D's boundary, one connected network."""
    from tiling.export import watertightness

    size = np.array([2.0, 2.0, 1.0])
    ms = regular(primitives.box(tuple(size)), tile, (2, 2, 1))
    w = watertightness(ms, samples=2)
    assert w["nonmanifold_edges"] == 0 and w["components"] == 1
    mesh = ms.surface(samples=2)
    rim = mesh.extract_feature_edges(boundary_edges=True, feature_edges=False, manifold_edges=False,
                                     non_manifold_edges=False)
    x = np.asarray(rim.points)
    assert rim.n_cells > 0 and np.min(np.minimum(np.abs(x), np.abs(x - size)), axis=1).max() < 1e-9
    # 4 + 4 + 2 * 4 openings on the sides of D: 16 closed rims, polygons inscribed in circles of radius 1/4
    assert rim.connectivity().point_data["RegionId"].max() + 1 == 16
    length = rim.compute_cell_sizes()["Length"].sum()
    assert 0.97 * 16 * 2 * np.pi * R < length < 16 * 2 * np.pi * R


def test_stitching_closes_two_samplings_of_one_edge():
    from geometry.shapes.stitch import stitch_boundaries
    from geometry.patches.sampling import weld

    # two unit squares side by side, the shared edge x = 1 split in 3 on the left and in 4 on the right
    def strip(x0, n):
        y = np.linspace(0.0, 1.0, n + 1)
        pts = np.concatenate([np.c_[np.full(n + 1, x0), y, np.zeros(n + 1)],
                              np.c_[np.full(n + 1, x0 + 1), y, np.zeros(n + 1)]])
        i = np.arange(n)
        tris = np.concatenate([np.c_[i, i + n + 1, i + n + 2], np.c_[i, i + n + 2, i + 1]])
        return pts, tris

    (p1, t1), (p2, t2) = strip(0.0, 3), strip(1.0, 4)
    pts = np.concatenate([p1, p2])
    tris = np.concatenate([t1, t2 + len(p1)])
    part = np.r_[np.zeros(len(p1), int), np.ones(len(p2), int)]
    P, T, _ = stitch_boundaries(pts, tris, part, 1e-9)
    P, T, _, _ = weld(P, T, {})
    e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    _, uses = np.unique(e, axis=0, return_counts=True)
    assert np.all(uses <= 2) and np.sum(uses == 1) == 3 + 4 + 2 + 2  # only the outer rectangle is open
    d1, d2 = P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]
    area = 0.5 * np.cross(d1, d2)[:, 2]
    assert np.all(area > 0) and area.sum() == pytest.approx(2.0, rel=1e-14)


def test_members_sampling_a_shared_edge_differently_are_stitched():
    """Two trimmed planes meeting along x = 0.8, z = 0.5 (an L), whose loops break that edge at different
    points: their own samplings differ, and the stitched mesh is open only on the L's outer rim."""
    from geometry.shapes.trimmed import join_curves
    from tiling.export import surface

    def plane(corners):  # a bilinear plane (corners in order) with a polygon loop in its parameters
        c = np.asarray(corners, float)
        return BSpline((1, 1), [np.array([0.0, 0.0, 1.0, 1.0])] * 2, np.array([[c[0], c[3]], [c[1], c[2]]]))

    def polygon(uv):
        uv = np.asarray(uv + [uv[0]], float)
        return join_curves([BSpline((1,), [[0.0, 0.0, 1.0, 1.0]], np.c_[uv[i:i + 2], np.zeros(2)])
                            for i in range(len(uv) - 1)])

    floor = TrimmedSurface(plane([[0.2, 0.2, 0.5], [0.8, 0.2, 0.5], [0.8, 0.8, 0.5], [0.2, 0.8, 0.5]]),
                           [polygon([(0, 0), (1, 0), (1, 1), (0, 1)])])
    wall = TrimmedSurface(plane([[0.8, 0.2, 0.5], [0.8, 0.8, 0.5], [0.8, 0.8, 0.8], [0.8, 0.2, 0.8]]),
                          [polygon([(0, 0), (0.25, 0), (1, 0), (1, 1), (0, 1)])])  # the shared edge broken at 1/4
    ms = regular(primitives.box(), Tile([floor, wall], name="L"), (1, 1, 1))
    mesh = surface(ms, samples=1)
    rim = mesh.extract_feature_edges(boundary_edges=True, feature_edges=False, manifold_edges=False,
                                     non_manifold_edges=False)
    mid = np.asarray(rim.cell_centers().points)
    on_fold = (np.abs(mid[:, 0] - 0.8) < 1e-12) & (np.abs(mid[:, 2] - 0.5) < 1e-12)
    assert rim.n_cells > 0 and not on_fold.any()
    from tiling.export import mesh_watertightness

    w = mesh_watertightness(mesh)
    assert w["components"] == 1 and w["nonmanifold_edges"] == 0
