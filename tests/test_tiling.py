"""Tiles, regular and hierarchical paving, the Microstructure model."""

import numpy as np
import pytest

import geometry
from geometry import BSpline, SplineError, primitives as pr
import tiling
from tiling import BranchFace, Tile, TilingError, library as L
from helpers import face_params, rel_err


def curved_map():
    """A regular, curved, multi-span deformation map (polynomial annulus shell, cubic arcs)."""
    return pr.annulus(1.0, 2.0, 1.0, exact=False, elements=(2, 1, 1)).elevate(1, 1)


def face_eval(P, face, st):
    """Points of a placed patch face in D's parameter domain at face parameters st (N, 2) in [0, 1]^2."""
    return P.spline.evaluate(face_params(P, face, st))[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]


def assert_identity_coincides(D, ms, itf, st):
    """Face a at (s, t) and face b at the interface's mapped parameters are one physical point."""
    Pa, Pb = ms.patches[itf.a[0]], ms.patches[itf.b[0]]
    s2 = st[:, ::-1] if itf.swap else st.copy()
    s2 = np.column_stack([1 - s2[:, 0] if itf.flip[0] else s2[:, 0], 1 - s2[:, 1] if itf.flip[1] else s2[:, 1]])
    assert np.abs(D(face_eval(Pa, itf.a[1], st))[:, :3] - D(face_eval(Pb, itf.b[1], s2))[:, :3]).max() < 1e-10


@pytest.mark.parametrize("make", [L.heat_sink_t1, L.heat_sink_t2, L.skinned_branching, L.fractal, L.hollow_box, L.cross, L.helix])
def test_library_tiles_are_valid(make):
    t = make()
    assert isinstance(t, Tile) and t.patches
    for p in t.patches:
        assert p.points.min() >= -1e-12 and p.points.max() <= 1 + 1e-12
        if p.dim == 3:
            assert geometry.check_regular(p).regular


def test_discontinuity_tiles_have_n_plus_1_times_m_plus_1_branches():
    assert len(L.heat_sink_t1().branch_outs) == 2
    assert len(L.heat_sink_t2().branch_outs) == 4
    assert len(L.skinned_branching().branch_outs) == 6  # (2 + 1) (1 + 1)


@pytest.mark.parametrize("make, counts, levels, per_level", [
    (L.heat_sink_t2, (2, 1), 3, [2, 8, 32]),
    (L.heat_sink_t1, (4, 1), 3, [4, 8, 16]),
    (L.skinned_branching, (1, 1), 3, [1, 6, 36]),
    (L.fractal, (1, 1), 7, [1, 2, 4, 8, 16, 32, 64]),
])
def test_hierarchical_counts(make, counts, levels, per_level):
    ms = tiling.hierarchical(pr.box(degrees=(2, 2, 2)), make(), counts, levels)
    assert ms.tiles_per_level() == per_level
    assert sum(i.kind == "branch" for i in ms.interfaces) == sum(per_level) - per_level[0]
    assert len(ms.tags["branch-in"]) == per_level[0]


def test_composed_patches_equal_D_of_placement():
    rng = np.random.default_rng(0)
    D = curved_map()
    for ms in (tiling.hierarchical(D, L.heat_sink_t1(), (2, 1), 2), tiling.regular(D, L.cross(), (1, 1, 1))):
        composed = ms.compose_all()
        for P, C in zip(ms.patches, composed):
            x = rng.random((200, P.spline.dim))
            y = P.spline.evaluate(x)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]
            assert rel_err(C(x), D(y)) < 1e-12
        assert ms.patches[0].composed is composed[0]  # cached


def test_interfaces_coincide_and_branch_matrices_reproduce_parent_faces():
    rng = np.random.default_rng(1)
    D = curved_map()
    ms = tiling.hierarchical(D, L.heat_sink_t2(), (2, 1), 3)
    st = rng.random((100, 2))
    kinds = {i.kind for i in ms.interfaces}
    assert kinds == {"branch", "identity"}  # neighbouring tiles share their outer walls
    for itf in ms.interfaces:
        Pa, Pb = ms.patches[itf.a[0]], ms.patches[itf.b[0]]
        if itf.kind == "identity":
            assert_identity_coincides(D, ms, itf, st)
            continue
        # the child's face at (s, t) is the parent's face at box-mapped (s, t), in physical space
        box = np.array(itf.box)
        pa_dom = Pa.spline.boundary(itf.a[1]).domain
        st_parent = (box[:, 0] + st * (box[:, 1] - box[:, 0]) - pa_dom[:, 0]) / (pa_dom[:, 1] - pa_dom[:, 0])
        xa, xb = D(face_eval(Pa, itf.a[1], st_parent))[:, :3], D(face_eval(Pb, itf.b[1], st))[:, :3]
        assert np.abs(xa - xb).max() < 1e-10
        # R maps the parent's face coefficients onto the child's face space, reproducing the parent face
        fa, fb = Pa.spline.boundary(itf.a[1]), Pb.spline.boundary(itf.b[1])
        cp_child = (itf.R @ fa.points.reshape(-1, 3)).reshape(fb.shape + (3,))
        sub = BSpline(fb.degrees, fb.knots, cp_child)
        child_params = fb.domain[:, 0] + st * (fb.domain[:, 1] - fb.domain[:, 0])
        parent_params = pa_dom[:, 0] + st_parent * (pa_dom[:, 1] - pa_dom[:, 0])
        assert rel_err(sub(child_params), fa(parent_params)) < 1e-12


def test_branch_faces_of_one_configuration_share_one_read_only_refinement():
    from geometry.faces import face_knots, nested_refinement

    ms = tiling.hierarchical(curved_map(), L.heat_sink_t2(), (2, 1), 3)
    branch = [i for i in ms.interfaces if i.kind == "branch"]
    shared = {id(i.R) for i in branch}
    assert len(shared) < len(branch)  # 40 links, a handful of configurations
    for itf in branch:  # each equals its own refinement, computed afresh
        fresh = nested_refinement(face_knots(ms.patches[itf.a[0]].spline, itf.a[1]), itf.box,
                                  face_knots(ms.patches[itf.b[0]].spline, itf.b[1]))
        assert (abs(itf.R - fresh)).max() == 0 and itf.R.nnz == fresh.nnz
        with pytest.raises(ValueError):
            itf.R.data[0] = 1.0  # shared: nothing may write into it


def test_regular_cross_paving_interfaces_and_free_faces():
    rng = np.random.default_rng(2)
    D = curved_map()
    ms = tiling.regular(D, L.cross(), (3, 3, 1))  # two u spans x 3, one v span x 3, one w span x 1
    n = (6, 3, 1)
    tiles = np.prod(n)
    inner = 6 * tiles  # centre-arm per tile
    between = (n[0] - 1) * n[1] * n[2] + n[0] * (n[1] - 1) * n[2] + n[0] * n[1] * (n[2] - 1)
    assert len(ms.interfaces) == inner + between
    assert all(i.kind == "identity" for i in ms.interfaces)
    # no free face inside: every free face is an arm side (internal) or lies on D's boundary
    assert len(ms.tags["internal"]) == tiles * 6 * 4
    for name, cnt in zip(("umin", "umax", "vmin", "vmax", "wmin", "wmax"), (3, 3, 6, 6, 18, 18)):
        assert len(ms.tags[name]) == cnt, name
    st = rng.random((50, 2))
    for itf in ms.interfaces[::7]:
        assert_identity_coincides(D, ms, itf, st)


def test_free_faces_are_the_faces_no_interface_glues_slot_and_branch_faces_included():
    from geometry.patches.multipatch import free_face_mask, free_faces

    D = pr.box((2.0, 1.0, 1.0))
    models = [tiling.regular(D, L.cross(), (2, 2, 1), seal="cap"), tiling.hierarchical(D, L.heat_sink_t2(), (2, 1), 3)]
    slotted = [m for m in models if any(not isinstance(k[1], str) or k[1] not in ("umin", "umax", "vmin", "vmax",
                                                                                     "wmin", "wmax")
                                        for k in m.tags["internal"])]
    for ms in models:
        glued = {e for itf in ms.interfaces for e in (itf.a, itf.b)}  # the definition, one face at a time
        want = [(i, f) for i, P in enumerate(ms.patches) if P.spline.dim == 3
                for f in ("umin", "umax", "vmin", "vmax", "wmin", "wmax") if (i, f) not in glued]
        assert free_faces(ms.patches, ms.interfaces) == want
        pidx, free = free_face_mask(ms.patches, ms.interfaces)
        assert free.sum() == len(want) and len(pidx) == len(ms.patches)
        assert any(i.kind == "branch" for i in ms.interfaces) or ms is models[0]
        # every free face is tagged as boundary (and the slot faces besides)
        assert set(want) <= set(ms.tags["boundary"])
    assert slotted  # a model with slot faces (keys that are not one of the six faces) is among them


def test_regular_paving_boundary_variants():
    D = pr.box()
    sealed = L.hollow_box()
    ms = tiling.regular(D, L.cross(), (3, 1, 1), variants={(-1, 0, 0): sealed, (1, 0, 0): sealed})
    names = [ms.tiles[p.tile].name for p in ms.patches]
    assert names.count("hollow_box") == 12 and names.count("cross") == 7


def test_recursive_composition():
    D = curved_map()
    ms = tiling.regular(D, L.cross(), (1, 1, 1))
    inner_map = ms.patches[0].composed  # a composed trivariate is itself a deformation map
    ms2 = tiling.regular(inner_map, L.cross(), (1, 1, 1))
    x = np.random.default_rng(3).random((50, 3))
    P = ms2.patches[1]
    y = P.spline.evaluate(x)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]
    assert rel_err(P.composed(x)[:, :3], inner_map(y)[:, :3]) < 1e-11


def test_bad_tiles_and_maps_raise():
    cube = pr.box()
    with pytest.raises(TilingError, match="leaves the unit cube"):
        Tile([cube.translate([0.5, 0, 0])])
    with pytest.raises(TilingError, match="planar and axis-aligned"):
        Tile([pr.annulus(0.2, 0.4, 1.0).translate([0.5, 0.5, 0])], (0, "umax"), [(0, "vmax")])
    with pytest.raises(TilingError, match="branch-out faces but no branch-in"):
        Tile([cube], None, [(0, "wmax")])
    with pytest.raises(TilingError, match="does not take the branch-in face onto this face"):
        Tile([cube], (0, "wmin"), [BranchFace(0, "wmax", map=np.column_stack([np.eye(3), [0, 0, 0.5]]))])
    bx = pr.box(degrees=(2, 1, 1))
    cp = bx.control_points.copy()
    cp[1, :, :, 0] = 1.6  # folded
    with pytest.raises(TilingError, match="deformation map is singular"):
        tiling.regular(BSpline(bx.degrees, bx.knots, cp), L.cross(), (1, 1, 1))
    with pytest.raises(TilingError, match="counts must be 3 positive integers"):
        tiling.regular(cube, L.cross(), (1, 0, 1))
    with pytest.raises(TilingError, match="branch-in face and branch-out faces"):
        tiling.hierarchical(cube, L.cross(), (1, 1), 2)
    with pytest.raises(TilingError, match="crosses the deformation map's knot line w"):
        tiling.hierarchical(pr.box(elements=(1, 1, 2)), L.heat_sink_t1(), (1, 1), 2)
    with pytest.raises(SplineError):
        BSpline((1,), [[0, 0, 1]], np.zeros((2, 3)))
    with pytest.raises(TilingError, match="arm width must be in"):
        L.cross(1.5)


def test_graded_conductivity_is_exact_in_parameter_mode_and_usable_by_analysis():
    from tiling.materials import graded_channel, interpolate_channel

    rng = np.random.default_rng(4)
    shell = pr.annulus(0.5, 1.0, 1.0, elements=(2, 2, 1))  # NURBS
    g = graded_channel(shell, "k", 205.0, 54.0, face="vmin")
    x = rng.random((500, 3))
    assert np.abs(g(x)[:, 3] - (205 * (1 - x[:, 1]) + 54 * x[:, 1])).max() < 1e-10
    # a field outside the spline space is quasi-interpolated: close, not exact
    q = interpolate_channel(pr.box(degrees=(2, 2, 2), elements=(4, 4, 4)), "q", lambda p: np.sin(3 * p[:, 0]), on="points")
    err = np.abs(q(x)[:, 3] - np.sin(3 * x[:, 0])).max()
    assert 1e-6 < err < 1e-2
    with pytest.raises(TilingError, match="mode='distance' needs a planar face"):
        graded_channel(shell, "k", face="vmin", mode="distance")
    # channel on the tile is carried into composition; channel on D is composed
    D = graded_channel(pr.box(degrees=(1, 1, 2)), "k", 205.0, 54.0, face="wmin")
    ms = tiling.hierarchical(D, L.heat_sink_t1(), (1, 1), 2)
    C = ms.patches[1].composed
    assert C.channels == ("k",)
    y = rng.random((100, 3))
    P = ms.patches[1]
    w = (P.spline.evaluate(y)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3])[:, 2]
    assert np.abs(C(y)[:, 3] - (205 * (1 - w) + 54 * w)).max() < 1e-9


@pytest.mark.slow
def test_surface_export_and_watertightness(tmp_path):
    from geometry import PlacedPatch
    from tiling.export import watertightness, write_surfaces

    D = pr.annulus(1.0, 2.0, 1.0, exact=False, elements=(2, 1, 1))
    closed = tiling.regular(D, L.cross(), (2, 2, 2))
    w = watertightness(closed)
    # 4 x 2 x 2 cells (2 knot spans along u): a lattice of bars whose genus is the number of independent cycles
    # of the cell graph, E - V + 1 = (3*2*2 + 4*1*2 + 4*2*1) - 16 + 1 = 13, so chi = 2 - 2 * 13
    assert w["closed"] and w["manifold"] and w["components"] == 1 and w["euler_characteristic"] == 2 - 2 * 13
    t2 = watertightness(tiling.hierarchical(D, L.heat_sink_t2(), (2, 1), 2))
    assert t2["closed"] and t2["components"] == 1
    # one arm moved off its neighbour: no longer welded, a second component (a gap in the structure)
    ms = tiling.regular(D, L.cross(), (1, 1, 1))
    arm = ms.patches[-1]
    M = arm.placement.copy()
    M[:, 3] += [0.02, 0.0, 0.0]
    moved = tiling.Microstructure(ms.outer, ms.patches[:-1] + [PlacedPatch(arm.spline, M, arm.outer, arm.tile)],
                                  ms.interfaces[:0], ms.tags, ms.tiles)
    assert watertightness(moved)["components"] == 2
    # surface tiles: the hollow cell is closed; without one wall it has a hole
    box = tiling.regular(pr.box(), L.hollow_box(), (1, 1, 1))
    assert watertightness(box)["closed"]
    holed = tiling.Microstructure(box.outer, box.patches[:-1], [], box.tags, box.tiles)
    h = watertightness(holed)
    assert not h["closed"] and h["open_edges"] == 4 * 4  # the missing wall's rim, sampled 4 times per side
    for suffix in (".vtu", ".obj", ".stl", ".ply"):
        path = write_surfaces(tmp_path / f"s{suffix}", closed)
        assert path.stat().st_size > 1000
    import pyvista as pv

    assert pv.read(tmp_path / "s.stl").n_cells > 100
    with pytest.raises(TilingError, match="use a .vtu"):
        write_surfaces(tmp_path / "s.dxf", closed)


def test_tiles_that_do_not_stack_are_told_why_in_one_clause():
    with pytest.raises(TilingError, match=r"faces patch 0 wmax and patch 1 wmin meet corner to corner, but their "
                                          r"surfaces part between the corners \(the control points differ\); use tiles"):
        tiling.regular(pr.box(), L.skinned_branching(), (1, 1, 2))
