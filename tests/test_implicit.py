"""Random implicit micro-structures (Massarwi et al. 2018, Section 4): reproducibility, continuity, connectivity."""

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import tiling
from geometry import BSpline, SplineFunction, primitives
from tiling import TilingError, canonical_tubes, random_implicit


@pytest.fixture(scope="module")
def duck():
    return primitives.duck()


def _neighbours(counts):
    """Every pair of face-adjacent cells (a, b) with b = a + e_k, and k."""
    for k in range(3):
        for a in np.ndindex(*counts):
            if a[k] + 1 < counts[k]:
                b = list(a)
                b[k] += 1
                yield a, tuple(b), k


def _face_points(s, a, k, rng, n=200):
    """Random parameter points (n, 3) on the face of cell a at its upper end in direction k."""
    box = s.cell_box(a)
    x = rng.uniform(box[:, 0], box[:, 1], (n, 3))
    x[:, k] = box[k, 1]
    return x


@pytest.mark.slow
@pytest.mark.kernel_sensitive
def test_same_seed_gives_identical_mesh_and_another_seed_does_not(duck):
    kw = dict(alpha=0.6, continuity="C1", connectivity=1, cap=True)
    m1 = random_implicit(duck, (2, 2, 4), seed=7, **kw).surface()
    m2 = random_implicit(duck, (2, 2, 4), seed=7, **kw).surface()
    m3 = random_implicit(duck, (2, 2, 4), seed=8, **kw).surface()
    assert np.array_equal(m1.points, m2.points) and np.array_equal(m1.faces, m2.faces)
    assert m1.n_points != m3.n_points or not np.array_equal(m1.points, m3.points)


def test_global_random_state_is_not_used(duck):
    np.random.seed(1)
    a = random_implicit(duck, (2, 2, 2), alpha=0.5, seed=3).field.coefficients
    np.random.seed(2)
    b = random_implicit(duck, (2, 2, 2), alpha=0.5, seed=3).field.coefficients
    assert np.array_equal(a, b)


def test_alpha_zero_gives_the_canonical_tiling(duck):
    p0 = canonical_tubes()
    s = random_implicit(duck, (2, 3, 2), alpha=0.0, seed=5)
    for cell in np.ndindex(2, 3, 2):
        assert np.array_equal(s.cell_coefficients(cell), p0)
    assert sum(s.stats["face_iterations"].values()) == 0 and sum(s.stats["cell_iterations"].values()) == 0
    # and a user canonical tile (any scalar trivariate of the cells' space) is reproduced as given
    user = SplineFunction((2, 2, 2), [np.r_[0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1]] * 3,
                          canonical_tubes(2, 6, radius=0.4)[..., None])
    s = random_implicit(duck, (2, 1, 1), degree=2, controls=6, alpha=0.0, canonical=user)
    assert np.array_equal(s.cell_coefficients((1, 0, 0)), user.coefficients[..., 0])


@pytest.mark.slow
@pytest.mark.parametrize("controls, cap, connectivity, continuity", [(6, False, 1, "C1"), (8, True, 2, "C1"),
                                                                    (8, True, 1, "C0"), (6, False, 2, "C0")])
def test_alpha_zero_does_not_depend_on_the_seed(duck, controls, cap, connectivity, continuity):
    """Eq. 6 at alpha = 0 is f = f0: the seed draws the spanning trees, but faces that change sign already are
    left as they are (with C1 the canonical tubes are made C1 across the faces, Eq. 8, the same for every
    seed), so seeds 1..5 give one field, and no connectivity step does any work."""
    runs = [random_implicit(duck, (4, 4, 3), alpha=0.0, seed=seed, controls=controls, cap=cap,
                            connectivity=connectivity, continuity=continuity) for seed in range(1, 6)]
    for s in runs[1:]:
        assert np.array_equal(s.field.coefficients, runs[0].field.coefficients)
    st = runs[0].stats
    assert sum(st["face_iterations"].values()) == 0 and sum(st["cell_iterations"].values()) == 0
    if continuity == "C0" and not cap:  # the canonical tile itself, in every cell
        p0 = canonical_tubes(3, controls)
        assert all(np.array_equal(runs[0].cell_coefficients(c), p0) for c in np.ndindex(4, 4, 3))


def test_coefficients_follow_eq6_around_the_canonical_tile(duck):
    """p = (1 - alpha) p0 + alpha U(-1, 1): before any adjustment the deviation is bounded by 2 alpha."""
    p0 = canonical_tubes()
    s = random_implicit(duck, (3, 3, 3), alpha=0.1, seed=0)
    dev = [np.abs(s.cell_coefficients(c) - p0).max() for c in np.ndindex(3, 3, 3)]
    assert 0.0 < max(dev) <= 2 * 0.1 + 1e-12


@pytest.mark.parametrize("continuity", ["C0", "C1"])
def test_continuity_across_every_shared_cell_face(duck, continuity):
    rng = np.random.default_rng(0)
    s = random_implicit(duck, (2, 3, 3), alpha=0.8, seed=4, continuity=continuity, connectivity=1, cap=True)
    n = s.controls - 1
    G = s.field.coefficients[..., 0]
    for a, b, k in _neighbours(s.counts):
        fa, fb = s.cell_coefficients(a), s.cell_coefficients(b)
        # Eq. 7: the shared layer is one set of coefficients
        assert np.array_equal(np.take(fa, -1, axis=k), np.take(fb, 0, axis=k))
        # values from both cells' own trivariates agree at random points of the face
        x = _face_points(s, a, k, rng)
        A, B = s.cell_field(a), s.cell_field(b)
        assert np.allclose(A.evaluate(x), B.evaluate(x), atol=1e-12)
        if continuity == "C1":
            # Eq. 8: symmetric inner layers, hence equal normal derivatives (cells of equal size)
            b0 = (a[k] + 1) * n
            Gk = np.moveaxis(G, k, 0)
            assert np.allclose(Gk[b0 + 1] - Gk[b0], Gk[b0] - Gk[b0 - 1], atol=1e-12)
            order = tuple(int(j == k) for j in range(3))
            assert np.allclose(A.derivative(x, order), B.derivative(x, order), atol=1e-9)
    # the global field is the cells' fields glued (checked at random interior points)
    for cell in [(0, 0, 0), (1, 2, 1)]:
        box = s.cell_box(cell)
        x = rng.uniform(box[:, 0], box[:, 1], (100, 3))
        assert np.allclose(s.field.evaluate(x), s.cell_field(cell).evaluate(x), atol=1e-12)


@pytest.mark.slow
def test_c0_structures_are_generally_not_c1(duck):
    rng = np.random.default_rng(1)
    s = random_implicit(duck, (2, 1, 1), alpha=0.9, seed=2, continuity="C0")
    x = _face_points(s, (0, 0, 0), 0, rng)
    jump = s.cell_field((0, 0, 0)).derivative(x, (1, 0, 0)) - s.cell_field((1, 0, 0)).derivative(x, (1, 0, 0))
    assert np.abs(jump).max() > 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("continuity,seed", [("C0", 0), ("C0", 3), ("C1", 1), ("C1", 2)])
def test_capped_connectivity_one_is_a_closed_single_solid(duck, continuity, seed):
    s = random_implicit(duck, (3, 3, 4), alpha=0.7, seed=seed, continuity=continuity, connectivity=1, cap=True)
    w = s.watertightness()
    assert w["closed"] and w["manifold"] and w["components"] == 1, w
    # every vertex is mapped exactly through D
    m = s.surface()
    params = np.c_[m["u"], m["v"], m["w"]]
    assert np.allclose(m.points, duck.evaluate(params)[:, :3], atol=1e-12)
    # and lies on the exact zero set of the spline field (snapped along its marching-cubes edge)
    assert np.abs(s.field.evaluate(params)).max() < 1e-10 * np.abs(s.field.coefficients).max()
    # while the unsnapped marching-cubes vertices are only near it
    raw = s.surface(snap=False)
    assert np.abs(s.field.evaluate(np.c_[raw["u"], raw["v"], raw["w"]])).max() > 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("connectivity", [1, 2])
def test_tree_faces_have_a_non_empty_zero_set(duck, connectivity):
    s = random_implicit(duck, (3, 3, 3), alpha=0.9, seed=11, connectivity=connectivity)
    assert s.stats["trees"] == connectivity == len(s.trees)
    n_cells = 27
    seen = set()
    for tree in s.trees:
        assert len(tree) == n_cells - 1  # spanning: n - 1 edges, one component
        g = coo_matrix((np.ones(len(tree)), tuple(tree.T)), shape=(n_cells, n_cells))
        assert connected_components(g, directed=False)[0] == 1
        pairs = {tuple(e) for e in tree}
        assert not pairs & seen  # edge-disjoint
        seen |= pairs
    for a, b in seen:
        ca, cb = np.unravel_index(a, s.counts), np.unravel_index(b, s.counts)
        k = int(np.flatnonzero(np.subtract(cb, ca))[0])
        lo = ca if ca[k] < cb[k] else cb
        box = s.cell_box(lo)
        # sample the face on a grid 4x finer than the build's checks: both signs occur, so f = 0 crosses it
        t = [np.linspace(*box[j], 4 * s.resolution + 1) if j != k else np.array([box[k, 1]]) for j in range(3)]
        v = s.field.evaluate_grid(t)
        assert v.max() > 0 > v.min()


@pytest.mark.kernel_sensitive
def test_every_cell_inside_region_is_one_component_at_the_build_sampling(duck):
    from scipy import ndimage

    s = random_implicit(duck, (2, 2, 3), alpha=1.0, seed=9, connectivity=1)
    for cell in np.ndindex(*s.counts):
        box = s.cell_box(cell)
        v = s.cell_field(cell).evaluate_grid([np.linspace(*box[j], s.resolution + 1) for j in range(3)])[..., 0]
        assert ndimage.label(v > 0)[1] == 1
    assert sum(s.stats["cell_iterations"].values()) > 0  # alpha = 1: pure noise needs work


def test_cap_keeps_the_zero_set_beyond_lemma1_distance(duck):
    """Lemma 1: f < 0 in the band of the bound's width along every boundary face (direct evaluation)."""
    rng = np.random.default_rng(3)
    s = random_implicit(duck, (2, 2, 3), alpha=0.8, seed=6, cap=True)
    dist = s.cap_distance()
    assert np.all(dist > 0)
    dom = duck.domain
    for k in range(3):
        for end in (0, 1):
            x = rng.uniform(dom[:, 0], dom[:, 1], (2000, 3))
            depth = rng.uniform(0, 1, 2000) * dist[k]
            x[:, k] = dom[k, 0] + depth if end == 0 else dom[k, 1] - depth
            assert s.field.evaluate(x).max() < 0
    with pytest.raises(TilingError, match="cap=True"):
        random_implicit(duck, (1, 1, 1)).cap_distance()


def test_shell_closes_the_structure_with_the_boundary_of_D(duck):
    s = random_implicit(duck, (2, 2, 3), alpha=0.5, seed=3, shell=0.2)
    w = s.watertightness()
    assert w["closed"] and w["triangles"] > 1000
    # every vertex is on the zero set or on D's boundary (the closing surfaces)
    m = s.surface()
    params = np.c_[m["u"], m["v"], m["w"]]
    on_boundary = np.any(np.isclose(params, duck.domain[:, 0]) | np.isclose(params, duck.domain[:, 1]), axis=1)
    on_zero = np.abs(s.field.evaluate(params)[:, 0]) < 1e-10 * np.abs(s.field.coefficients).max()
    assert np.all(on_boundary | on_zero) and on_boundary.any() and on_zero.any()
    # the whole boundary layer of coefficients is inside (positive)
    G = s.field.coefficients[..., 0]
    assert G[0].min() >= 1.0 and G[:, -1].min() >= 1.0


def test_materials_and_map_channels_are_point_data(duck):
    cp = duck.control_points
    T = 20.0 + 10.0 * cp[..., 2:3]  # a temperature channel of the map, linear in z
    D = BSpline(duck.degrees, duck.knots, np.concatenate([cp, T], -1), duck.weights, channels=("T",))
    k = np.linspace(1.0, 3.0, 8)[:, None, None] * np.ones((8, 8, 8))
    s = random_implicit(D, (2, 2, 2), alpha=0.4, seed=1, cap=True, materials={"k": k})
    m = s.surface()
    params = np.c_[m["u"], m["v"], m["w"]]
    assert np.allclose(m["T"], D.evaluate(params)[:, 3])
    assert np.allclose(m["k"], s.materials.evaluate(params)[:, 0])
    assert 1.0 - 1e-12 <= m["k"].min() < m["k"].max() <= 3.0 + 1e-12
    with pytest.raises(TilingError, match="material 'k'"):
        random_implicit(D, (1, 1, 1), materials={"k": np.ones((4, 4, 4))})
    with pytest.raises(TilingError, match="clashes"):
        random_implicit(D, (1, 1, 1), materials={"T": k})


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply", ".vtp", ".vtu"])
def test_write_surface_formats(duck, tmp_path, suffix):
    import pyvista as pv

    s = random_implicit(duck, (1, 1, 2), alpha=0.5, seed=0, cap=True)
    path = s.write(tmp_path / f"random{suffix}")
    back = pv.read(path)
    assert back.n_cells == s.surface().n_cells


def test_bad_input_names_the_input(duck, tmp_path):
    cases = [
        (dict(alpha=-0.1), "alpha"), (dict(alpha=1.5), "alpha"), (dict(alpha=float("nan")), "alpha"),
        (dict(alpha="half"), "alpha"), (dict(continuity="C2"), "continuity"), (dict(connectivity=0), "connectivity"),
        (dict(connectivity=4), "connectivity"), (dict(degree=0), "degree"), (dict(controls=3), "controls"),
        (dict(resolution=0), "resolution"), (dict(shell=0.7), "shell"), (dict(seed="x"), "seed"),
        (dict(seed=-1), "seed"), (dict(cap="yes"), "cap"),
        (dict(canonical=np.zeros((7, 8, 8))), r"\(8, 8, 8\)"),
        (dict(canonical=np.full((8, 8, 8), np.nan)), "finite"),
        (dict(canonical=canonical_tubes(2, 8), degree=3, controls=6), r"\(6, 6, 6\)"),
        (dict(canonical=SplineFunction((3, 3, 3), [np.r_[0, 0, 0, 0, 0.1, 0.2, 0.3, 0.4, 1, 1, 1, 1]] * 3,
                                       canonical_tubes()[..., None])), "knots"),
    ]
    for kw, match in cases:
        with pytest.raises(TilingError, match=match):
            random_implicit(duck, (2, 2, 2), **kw)
    with pytest.raises(TilingError, match="counts"):
        random_implicit(duck, (2, 0, 2))
    with pytest.raises(TilingError, match="trivariate"):
        random_implicit(primitives.box().boundary("umin"), (1, 1, 1))  # a bivariate map: a surface, not a volume
    # more trees than the cell graph holds: the message says how many can exist
    with pytest.raises(TilingError, match=r"at most 1 can exist\); 1 found; use connectivity=1"):
        random_implicit(duck, (2, 2, 2), connectivity=2)
    # a grid of cells never has 3 (that needs 3 (cells - 1) shared faces; a grid has fewer)
    with pytest.raises(TilingError, match=r"at most 2 can exist\); 2 found; use connectivity=2"):
        random_implicit(duck, (3, 3, 3), connectivity=3)
    s = random_implicit(duck, (1, 1, 1), seed=0)
    for res in (0, -3, 2.5, True):
        with pytest.raises(TilingError, match="resolution"):
            s.surface(res)
    with pytest.raises(TilingError, match="cannot export"):
        s.write(tmp_path / "random.docx")
    assert not (tmp_path / "random.docx").exists()


def test_exported_from_tiling():
    assert tiling.random_implicit is random_implicit and "ImplicitStructure" in tiling.__all__


@pytest.mark.slow
def test_uncapped_solid_is_one_region_without_enclosed_voids(duck):
    """Open structures: the sampled solid is one 6-connected region and every void reaches D's boundary."""
    from scipy import ndimage

    s = random_implicit(duck, (3, 3, 4), alpha=0.9, seed=5, continuity="C1", connectivity=2)
    F = s.sample_values()
    assert ndimage.label(F > 0)[1] == 1
    label, n = ndimage.label(np.pad(F, 1, constant_values=-1.0) <= 0)
    assert n == 1


def test_render_surface_and_trees(duck, tmp_path):
    s = random_implicit(duck, (2, 2, 3), alpha=0.5, seed=0, connectivity=1)
    for name, kw in [("surface.png", {"color_by": "w"}), ("trees.png", {"trees": True, "surface": False})]:
        path = s.render_png(tmp_path / name, window=(300, 240), **kw)
        assert path.stat().st_size > 2000 and path.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(TilingError, match="color_by"):
        s.render_png(tmp_path / "x.png", color_by="nope")
    with pytest.raises(TilingError, match="nothing to render"):
        s.render_png(tmp_path / "x.png", surface=False)
    assert not (tmp_path / "x.png").exists()


def test_duck_map_is_long_tapered_regular_and_nearly_singular_at_the_ends(duck):
    from geometry import check_regular

    pts = duck.control_points[..., :3].reshape(-1, 3)
    assert 2.0 <= np.ptp(pts[:, 0]) <= 2.2  # length about 2 along x
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 1, (2000, 3))
    J = duck.jacobian(x)[:, :3, :]
    assert np.all(np.linalg.det(J) > 0)
    assert bool(check_regular(duck))  # proven exactly (Bernstein form of det J)
    # cross-section area near the ends is a small fraction of the body's (nearly singular ends)
    def width(w):
        g = np.linspace(0, 1, 9)
        uv = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        p = duck.evaluate(np.c_[uv, np.full(len(uv), w)])[:, :3]
        return np.ptp(p[:, 1])
    assert width(0.0) < 0.15 * width(0.4) and width(1.0) < 0.15 * width(0.4)
    from geometry import SplineError

    with pytest.raises(SplineError, match="length"):
        primitives.duck(length=-1)
