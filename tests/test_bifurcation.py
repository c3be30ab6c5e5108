"""Adaptive topological subdivision (Algorithm 1) and layered parametric bifurcation tilings (Massarwi et al. 2018, Section 5)."""

import numpy as np
import pytest

import tiling
from geometry import primitives
from geometry.faces import FACE_NAMES
from iga import HeatProblem
from tiling import TilingError
from tiling.branching.paving import bifurcation, bifurcation_tiles, smooth_levels
from tiling.branching.subdivision import topo_subdiv

AFFINE = primitives.box((2.0, 1.0, 3.0))


@pytest.fixture(scope="module")
def duck():
    return primitives.duck()


def _direct_longest(D, box):
    """Longest chord of the 12 edges of a parameter box, evaluating each edge's two corners on their own."""
    best = 0.0
    for k in range(3):
        rest = [j for j in range(3) if j != k]
        for a in box[rest[0]]:
            for b in box[rest[1]]:
                p, q = np.zeros(3), np.zeros(3)
                p[rest], q[rest] = (a, b), (a, b)
                p[k], q[k] = box[k]
                x = D.evaluate(np.stack([p, q]))[:, :3]
                best = max(best, float(np.linalg.norm(x[1] - x[0])))
    return best


def test_topo_subdiv_bounds_every_cell_and_tiles_the_domain(duck):
    c = topo_subdiv(duck, 0.35)
    assert 20 < len(c) < 500
    rng = np.random.default_rng(0)
    for i in rng.choice(len(c), 20, replace=False):
        assert _direct_longest(duck, c.boxes[i]) < 0.35
    # cells cover the domain without overlap: volumes add up and random points fall in exactly one cell
    vol = np.prod(c.boxes[:, :, 1] - c.boxes[:, :, 0], axis=1).sum()
    assert vol == pytest.approx(np.prod(np.diff(duck.domain, axis=1)), rel=1e-12)
    x = rng.uniform(duck.domain[:, 0], duck.domain[:, 1], (2000, 3))
    inside = np.all((x[:, None, :] > c.boxes[None, :, :, 0]) & (x[:, None, :] < c.boxes[None, :, :, 1]), axis=2)
    assert np.all(inside.sum(axis=1) == 1)
    # each split was needed: the parent (the cell doubled along some direction) would exceed epsilon
    # (Algorithm 1 never splits below the threshold) -- at least one cell per direction is near it
    assert c.longest.max() > 0.35 / 2
    # reproducible
    assert np.array_equal(c.boxes, topo_subdiv(duck, 0.35).boxes)


def test_face_classification_matches_brute_force(duck):
    c = topo_subdiv(duck, 0.35)
    B = c.boxes
    n = len(B)
    for i in range(n):
        for fi, face in enumerate(FACE_NAMES):
            k, side = fi // 2, fi % 2
            rest = [j for j in range(3) if j != k]
            # brute force over every other cell: faces on the same plane, overlapping with positive area
            plane = B[i, k, side]
            nb = [j for j in range(n) if j != i and abs(B[j, k, 1 - side] - plane) < 1e-14
                  and np.all(np.minimum(B[i, rest, 1], B[j, rest, 1]) - np.maximum(B[i, rest, 0], B[j, rest, 0]) > 0)]
            kind, got = c.faces[i][face]
            assert sorted(got) == nb
            if not nb:
                expect = "boundary"
                assert plane == duck.domain[k, side]
            elif len(nb) > 1:
                expect = "complex"
            elif np.allclose(B[nb[0], rest], B[i, rest]):
                expect = "neighbour"
            else:
                expect = "partial" if np.all((B[nb[0], rest, 0] <= B[i, rest, 0]) & (B[nb[0], rest, 1] >= B[i, rest, 1])) \
                    else "complex"
            assert kind == expect
    kinds = c.kinds()
    assert kinds["complex"] > 0 and kinds["partial"] > 0  # the duck needs bifurcations
    assert len(c.adjacency()) > n - 1


def test_layered_subdivision_along_one_direction(duck):
    c = topo_subdiv(duck, 0.35, directions=(2,))
    assert np.all(c.boxes[:, :2, 0] == 0.0) and np.all(c.boxes[:, :2, 1] == 1.0)
    assert set(c.kinds()) and c.kinds()["complex"] == 0
    assert np.all(c.edge_images()[:, 2] < 0.35)


def test_topo_subdiv_bad_input(duck):
    for eps in (0, -1.0, float("nan"), "0.3", True):
        with pytest.raises(TilingError, match="epsilon"):
            topo_subdiv(duck, eps)
    with pytest.raises(TilingError, match="raise epsilon"):
        topo_subdiv(duck, 1e-7)
    with pytest.raises(TilingError, match="directions"):
        topo_subdiv(duck, 0.3, directions=(3,))
    with pytest.raises(TilingError, match="trivariate"):
        topo_subdiv("duck", 0.3)


@pytest.mark.parametrize("kind", ["1-2", "1-4a", "1-4b"])
def test_bifurcation_patch_test(kind):
    ms = bifurcation(AFFINE, levels=[0, 1, 2, 1, 0], tile=kind)
    lin = lambda x: 1 + 2 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]  # noqa: E731
    s = HeatProblem(ms, refine=1, degree_elevation=1).dirichlet("boundary", lin).solve()
    assert s.l2_error(lin) < 1e-9
    assert s.info["constraints"]["branch_rows"] > 0 and s.info["constraints"]["identity_pairs"] > 0
    assert sum(i.kind == "branch" for i in ms.interfaces) > 0
    # tiles per layer follow the levels: (split x, split y)^level cells per layer
    sx, sy = tiling.branching.paving.SPLITS[kind]
    assert ms.n_tiles == sum((sx * sy) ** v for v in ms.info["levels"])


def test_bifurcation_converges_at_rate_p_plus_1():
    ms = bifurcation(AFFINE, levels=[0, 1, 0], tile="1-2")
    T = lambda x: np.sin(x[:, 0]) * np.cos(0.7 * x[:, 1]) * np.exp(0.3 * x[:, 2])  # noqa: E731
    f = lambda x: (1 + 0.49 - 0.09) * T(x)  # noqa: E731  (-lap T)
    errs = [HeatProblem(ms, source=f, degree_elevation=1, refine=r).dirichlet("boundary", T).solve(tol=1e-13)
            .l2_error(T) for r in (1, 2, 3)]
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(rates > 2.7), rates  # p = 2: rate 3


@pytest.mark.kernel_sensitive
def test_bifurcation_in_the_duck_by_epsilon(duck):
    for kind in ("1-2", "1-4a"):
        ms = bifurcation(duck, 0.35, kind)
        lev = np.array(ms.info["levels"])
        assert np.all(np.abs(np.diff(lev)) <= 1) and lev.max() >= 1
        assert not np.any((lev[1:-1] < lev[:-2]) & (lev[1:-1] < lev[2:]))
        s = HeatProblem(ms, conductivity=20.0).dirichlet("wmin", 100.0).dirichlet("wmax", 20.0).solve()
        assert s.info["balance"]["relative_error"] < 1e-9
        assert s.info["components"]["count"] == 1 and not s.info["components"]["idle"]  # one coupled piece: no interface missing
        assert s.flux("wmin") == pytest.approx(-s.flux("wmax"), rel=1e-9) and s.flux("wmin") < 0
        w = tiling.export.watertightness(ms)
        assert w["closed"] and w["components"] == 1


def test_smooth_levels():
    assert smooth_levels([0, 3, 0]).tolist() == [2, 3, 2]
    assert smooth_levels([2, 0, 2]).tolist() == [2, 2, 2]  # no valley: a layer cannot both join and split
    out = smooth_levels(np.random.default_rng(0).integers(0, 5, 30))
    assert np.all(np.abs(np.diff(out)) <= 1)


def test_bifurcation_tiles_are_conforming_shears():
    t = bifurcation_tiles("1-4a", margin=0.25)  # a trunk of 4 blocks and 4 arms
    assert len(t["split"].patches) == 8 and len(t["join"].patches) == 8 and len(t["straight"].patches) == 1
    for p in t["split"].patches:  # each block is a parallelepiped: bottom and top rectangles of equal size
        cp = p.control_points[..., :3]
        assert np.allclose(cp[:, :, 1] - cp[:, :, 0], cp[0, 0, 1] - cp[0, 0, 0])
    with pytest.raises(TilingError, match="trunk"):
        bifurcation_tiles("1-2", trunk=1.0)


@pytest.mark.parametrize("kind", ["1-2", "1-4a", "1-4b"])
def test_every_volumetric_bifurcation_is_one_closed_manifold(kind, duck, tmp_path):
    """Massarwi et al. 2018, Fig. 15 setting (the duck at epsilon 0.35) and a box: the boundary, exported to STL
    and read back with its points merged, has no open and no non-manifold edge (the arms part on the trunk's
    top, not at a boundary face), one component, and it is oriented (every edge used once each way)."""
    import pyvista as pv

    from geometry import primitives as pr

    for D, kw in ((duck, dict(epsilon=0.35)), (pr.box((1.0, 1.0, 4.0)), dict(levels=[0, 1, 1, 0]))):
        ms = bifurcation(D, tile=kind, **kw)
        assert ms.levels >= 2
        path = tiling.export.write_surfaces(tmp_path / "b.stl", ms)
        mesh = pv.read(path).clean()
        w = tiling.export.mesh_watertightness(mesh)
        assert w["closed"] and w["manifold"] and w["components"] == 1, (kind, w)
        tris = mesh.faces.reshape(-1, 4)[:, 1:]
        directed = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
        assert len(np.unique(directed, axis=0)) == len(directed)  # no edge twice the same way: oriented


def test_bifurcation_bad_input(duck):
    cases = [(dict(epsilon=0.0), "epsilon"), (dict(epsilon=-1.0), "epsilon"), (dict(), "give epsilon"),
             (dict(epsilon=0.3, levels=[0, 1]), "give epsilon"), (dict(epsilon=0.3, tile="1-3"), "1-2"),
             (dict(epsilon=0.3, direction=3), "direction"), (dict(levels=[0, 1, 2]), "multiple of 5"),
             (dict(levels=[0, -1, 0, 0, 0]), "levels"), (dict(epsilon=0.3, margin=0.5), "margin"),
             (dict(epsilon=1e-6), "raise epsilon"), (dict(epsilon=0.3, surfaces="yes"), "surfaces")]
    for kw, match in cases:
        with pytest.raises(TilingError, match=match):
            bifurcation(duck, **kw)


# ------------------------------------------------------------------ implicit bifurcation (Section 5.1)
from tiling.branching.implicit import implicit_bifurcation, merge_pieces  # noqa: E402


@pytest.fixture(scope="module")
def implicit_duck(duck):
    return implicit_bifurcation(duck, 0.35, alpha=0.65, seed=3)


def test_implicit_bifurcation_is_closed_connected_and_exact(implicit_duck, duck):
    s = implicit_duck
    assert s.cells.kinds()["complex"] > 0  # real bifurcations
    w = s.watertightness()
    assert w["closed"] and w["manifold"] and w["components"] == 1
    m = s.surface()
    params = np.c_[m["u"], m["v"], m["w"]]
    scale = max(np.abs(f.coefficients).max() for f in s.fields)
    assert np.abs(s.evaluate(params)).max() < 1e-10 * scale  # vertices on the exact zero set
    assert np.allclose(m.points, duck.evaluate(params)[:, :3], atol=1e-12)
    # the random draw was used (not every amplitude halved to the canonical pattern)
    assert min(s.stats["cell_halvings"].values()) == 0 and min(s.stats["face_halvings"].values()) == 0


def test_the_cells_edge_restrictions_equal_their_fields_along_the_edges(implicit_duck):
    # the restrictions of all cells, computed together in the cells' unit cubes, against each cell's own field
    from tiling.implicit.surface import EdgeSplines

    s, rng = implicit_duck, np.random.default_rng(5)
    boxes = s.cells.boxes
    cell = rng.integers(0, len(boxes), 3000)
    axis = rng.integers(0, 3, 3000)
    a = rng.uniform(boxes[cell, :, 0], boxes[cell, :, 1])
    b = a.copy()
    rows = np.arange(3000)
    a[rows, axis] = boxes[cell, axis, 0] + rng.uniform(0, 0.5, 3000) * (boxes[cell, axis, 1] - boxes[cell, axis, 0])
    b[rows, axis] = boxes[cell, axis, 1]
    assert len({f.coefficients.shape for f in s.fields}) > 1  # several kinds of cell spline
    E = EdgeSplines.of_cells(s.fields, cell, a, b, axis)
    t = rng.uniform(0, 1, 3000)
    x = a.copy()
    x[rows, axis] = a[rows, axis] + t * (b[rows, axis] - a[rows, axis])
    direct = np.array([s.fields[c].evaluate(x[j : j + 1])[0, 0] for j, c in enumerate(cell)])
    scale = max(np.abs(f.coefficients).max() for f in s.fields)
    assert np.abs(E(rows, x[rows, axis]) - direct).max() < 1e-12 * scale


def test_implicit_bifurcation_is_c0_across_every_face_including_complex_ones(implicit_duck):
    s, c = implicit_duck, implicit_duck.cells
    rng = np.random.default_rng(1)
    checked = {"neighbour": 0, "partial": 0}
    for i in range(len(c)):
        for fi, f in enumerate(FACE_NAMES):
            kind, nb = c.faces[i][f]
            if kind not in checked:
                continue
            k, side = divmod(fi, 2)
            box = c.boxes[i]  # the smaller (or equal) face: points on it lie on the neighbour's face too
            x = rng.uniform(box[:, 0], box[:, 1], (40, 3))
            x[:, k] = box[k, side]
            a = s.fields[i].evaluate(x)[:, 0]
            b = s.fields[nb[0]].evaluate(x)[:, 0]
            assert np.abs(a - b).max() < 1e-12 * max(1.0, np.abs(a).max())
            checked[kind] += 1
    assert checked["neighbour"] > 10 and checked["partial"] > 10


def test_merge_pieces_is_exact():
    from geometry import SplineFunction
    from geometry import knots as kn

    rng = np.random.default_rng(2)
    U = kn.uniform_knots(3, 5)
    rects = [((0, 0.5), (0, 1)), ((0.5, 1), (0, 0.5)), ((0.5, 0.75), (0.5, 1)), ((0.75, 1), (0.5, 1))]
    pieces = []
    for r in rects:
        c = rng.uniform(-1, 1, (8, 8))
        c[[0, -1], :] = -0.5
        c[:, [0, -1]] = -0.5
        pieces.append(SplineFunction((3, 3), [r[0][0] + (r[0][1] - r[0][0]) * U, r[1][0] + (r[1][1] - r[1][0]) * U],
                                     c[..., None]))
    merged = merge_pieces(pieces, 3)
    for p, r in zip(pieces, rects):
        x = np.c_[rng.uniform(*r[0], 200), rng.uniform(*r[1], 200)]
        assert np.abs(merged.evaluate(x) - p.evaluate(x)).max() < 1e-12


def test_implicit_bifurcation_reproducible_and_bad_input(duck):
    a = implicit_bifurcation(duck, 0.5, alpha=0.5, seed=4)
    b = implicit_bifurcation(duck, 0.5, alpha=0.5, seed=4)
    assert all(np.array_equal(f.coefficients, g.coefficients) for f, g in zip(a.fields, b.fields))
    for kw, match in [(dict(alpha=1.5), "alpha"), (dict(resolution=7), "even"), (dict(radius=0.6), "radius"),
                      (dict(controls=3), "controls"), (dict(seed="a"), "seed"), (dict(cap=1), "cap")]:
        with pytest.raises(TilingError, match=match):
            implicit_bifurcation(duck, 0.5, **kw)
    with pytest.raises(TilingError, match="epsilon"):
        implicit_bifurcation(duck, -0.5)
    with pytest.raises(TilingError, match="domain"):
        a.evaluate(np.array([[0.5, 0.5, 1.5]]))


@pytest.mark.slow
@pytest.mark.kernel_sensitive
def test_bicubic_surface_bifurcation_tiles(duck):
    t = bifurcation_tiles("1-4b", surfaces=True)
    assert all(p.dim == 2 and p.degrees == (3, 3) for k in t for p in t[k].patches)
    assert len(t["split"].patches) == 16 + 10  # 4 walls of 4 arms, the trunk's outer walls (4 x 2 + 2)
    ms = bifurcation(duck, 0.35, "1-4a", surfaces=True)
    assert all(p.spline.dim == 2 for p in ms.patches) and not ms.interfaces
    w = tiling.export.watertightness(ms)
    assert w["manifold"] and w["components"] == 1 and w["open_edges"] > 0  # open tubes, one connected network
    # open only at D's growth ends: the rims of neighbouring walls are sampled at each other's points, so the
    # tubes weld across every level change (no T-junction inside)
    from scipy.spatial import cKDTree

    m = ms.surface(4).clean()
    e = m.extract_feature_edges(boundary_edges=True, non_manifold_edges=False, feature_edges=False,
                                manifold_edges=False)
    g, dom = np.linspace(0.0, 1.0, 300), duck.domain
    uu, vv = np.meshgrid(dom[0, 0] + g * np.ptp(dom[0]), dom[1, 0] + g * np.ptp(dom[1]), indexing="ij")
    ends = np.concatenate([duck.evaluate(np.column_stack([uu.ravel(), vv.ravel(), np.full(uu.size, dom[2, s])]))[:, :3]
                           for s in (0, 1)])
    size = float(np.ptp(m.points, axis=0).max())
    assert cKDTree(ends).query(e.points)[0].max() < 1e-3 * size
    # the walls pass through the exact composition: a wall's corner lands where D maps it
    P = ms.patches[0]
    corner = P.placement[:, :3] @ P.spline.control_points[0, 0, :3] + P.placement[:, 3]
    assert np.allclose(P.composed.control_points[0, 0, :3], duck.evaluate(corner[None])[0, :3], atol=1e-12)


def test_user_bifurcation_tiles(duck):
    own = bifurcation_tiles("1-2", margin=0.2)
    ms = bifurcation(AFFINE, levels=[0, 0, 1, 0, 0], tile={"kind": "1-2", **own})
    lin = lambda x: 1 + 2 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]  # noqa: E731
    assert HeatProblem(ms, refine=1, degree_elevation=1).dirichlet("boundary", lin).solve().l2_error(lin) < 1e-9
    # a tile without branch faces: a block that does not reach the top of its cell
    from geometry import primitives as pr
    short = tiling.Tile([pr.box((0.4, 0.4, 0.5), origin=(0.3, 0.3, 0.0))], name="short column")
    with pytest.raises(TilingError, match="no branch-out face"):
        bifurcation(AFFINE, levels=[0, 1, 0, 0, 0], tile={"kind": "1-2", **own, "straight": short})
    with pytest.raises(TilingError, match="kind"):
        bifurcation(AFFINE, levels=[0, 1, 0, 0, 0], tile={"kind": "1-3", **own})
    with pytest.raises(TilingError, match="Tile of trivariates"):
        bifurcation(AFFINE, levels=[0, 1, 0, 0, 0], tile={"kind": "1-2", **own, "join": "x"})


def test_face_classification_by_sweep_equals_all_pairs_on_an_adaptive_subdivision():
    from geometry.faces import FACE_NAMES
    from geometry.tolerances import ON_DOMAIN
    from tiling.branching.subdivision import classify_faces, topo_subdiv

    from geometry import primitives as pr

    D = pr.tapered(pr.box((1.0, 1.0, 2.0), degrees=(1, 1, 2)), 0.3)
    boxes = topo_subdiv(D, 0.25).boxes
    got = classify_faces(boxes, D.domain)
    tol = ON_DOMAIN * float(np.abs(D.domain).max() + 1.0)
    for k in range(3):  # brute force: every pair of cells whose faces lie on one plane and overlap with area
        rest = [j for j in range(3) if j != k]
        on_plane = np.abs(boxes[:, None, k, 1] - boxes[None, :, k, 0]) <= tol
        lo = np.maximum(boxes[:, None, rest, 0], boxes[None, :, rest, 0])
        hi = np.minimum(boxes[:, None, rest, 1], boxes[None, :, rest, 1])
        touch = on_plane & np.all(hi - lo > tol, axis=-1)
        for i in range(len(boxes)):
            assert set(got[i][FACE_NAMES[2 * k + 1]][1]) == set(np.flatnonzero(touch[i]).tolist())
            assert set(got[i][FACE_NAMES[2 * k]][1]) == set(np.flatnonzero(touch[:, i]).tolist())
    kinds = {kind for cell in got for kind, _ in cell.values()}
    assert {"boundary", "neighbour"} <= kinds and len(kinds) >= 3  # the subdivision is adaptive: partial faces
