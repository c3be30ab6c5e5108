"""What leaves the toolkit arrives intact: VTU for every reader, probes on slot walls, the demo sinks' volume."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from geometry.patches.chain import patch_geometry_points, gradient_and_det
from helpers import decode_appended_vtu, surface_gauss
from iga import HeatProblem, write_vtu
from iga.app.config import validate
from iga.app.pipeline import heat_sink_config
from iga.app.pipeline_build import build, build_maps
from tiling import library as L


def _demo_problem(variant):
    cfg = validate(heat_sink_config(variant, out="unused"), ".")
    ms = build(cfg, build_maps(cfg)).model
    return HeatProblem(ms, conductivity="k").neumann("branch-in", 1515.8).robin("exterior", 5.0, 30.0)


@pytest.fixture(scope="module", params=["circular", "vertical"])
def demo(request):
    """The demo sink (both variants) as the demo builds it, solved."""
    return _demo_problem(request.param).solve()


def test_meshio_reads_the_sampled_vtu_like_pyvista(tmp_path):
    meshio = pytest.importorskip("meshio")
    import pyvista as pv

    ms = tiling.hierarchical(pr.box((2.0, 2.0, 1.0)), L.heat_sink_t2(), (2, 2), 2)
    sol = HeatProblem(ms).dirichlet("wmin", 1.0).robin("exterior", 1.0, 0.0).solve()
    path = write_vtu(tmp_path / "s.vtu", sol)
    a, b = pv.read(path), meshio.read(path)
    assert np.array_equal(a.points, b.points)
    assert [c.type for c in b.cells] == ["hexahedron"]
    assert np.array_equal(b.cells[0].data, a.cell_connectivity.reshape(-1, 8))
    assert set(b.point_data) == set(a.point_data) == {"temperature", "heat_flux", "conductivity"}
    for k in a.point_data:
        assert np.array_equal(np.asarray(b.point_data[k]).reshape(a.n_points, -1),
                              np.asarray(a.point_data[k]).reshape(a.n_points, -1))
    for k in ("patch", "tile", "level"):
        assert np.array_equal(b.cell_data[k][0], a.cell_data[k])
    head = path.read_bytes()[:400].decode("ascii", "replace")
    assert 'header_type="UInt64"' in head and "compressor" not in head  # raw appended arrays (iga.io.vtu)


def test_bezier_vtu_arrays_decode_with_a_second_reader(tmp_path):
    """meshio 5.3.5 has no reader for variable-order cells (VTK_BEZIER_HEXAHEDRON), so the exact file is decoded
    here from its XML and zlib blocks (the VTK format as documented) and compared with what VTK reads."""
    import pyvista as pv

    ms = tiling.hierarchical(pr.box((2.0, 2.0, 1.0)), L.heat_sink_t2(), (1, 1), 2)
    sol = HeatProblem(ms).dirichlet("wmin", 1.0).robin("exterior", 1.0, 0.0).solve()
    path = write_vtu(tmp_path / "b.vtu", sol, cells="bezier")
    grid = pv.read(path)
    arrays = decode_appended_vtu(path)
    assert np.array_equal(arrays["Points"].reshape(-1, 3), grid.points)
    assert np.array_equal(arrays["temperature"], grid.point_data["temperature"])
    assert np.array_equal(arrays["types"], grid.celltypes) and set(arrays["types"]) == {79}
    assert np.array_equal(arrays["HigherOrderDegrees"].reshape(-1, 3), grid.cell_data["HigherOrderDegrees"])


@pytest.mark.slow
def test_every_boundary_point_of_the_demo_sinks_can_be_probed(demo, tmp_path):
    """Slot walls included: the points on either side of a discontinuity plane are found on their own side."""
    import pyvista as pv

    grid = pv.read(write_vtu(tmp_path / "d.vtu", demo, samples=1))
    surf = grid.extract_surface(algorithm="dataset_surface")
    T = demo.probe(surf.points)
    assert np.abs(T - surf.point_data["temperature"]).max() < 1e-9 * np.abs(T).max()


def test_the_sampled_demo_vtu_holds_the_exact_volume(demo, tmp_path):
    import pyvista as pv

    grid = pv.read(write_vtu(tmp_path / "d.vtu", demo))
    exact = demo.volume()
    assert abs(grid.volume / exact - 1) < 5e-3


def test_flux_at_welded_interface_points_is_the_mean_of_both_sides(tmp_path):
    """Two tiles of different conductivity: the flux jumps across their interface; the VTU holds the mean."""
    import pyvista as pv

    a = pr.box((1.0, 1.0, 1.0), channels={"k": 1.0})
    b = pr.box((1.0, 1.0, 1.0), origin=(1.0, 0.0, 0.0), channels={"k": 3.0})
    sol = HeatProblem([a, b], conductivity="k", degree=2) \
        .dirichlet("umin", 0.0).dirichlet("umax", 1.0).robin("vmin", 4.0, 2.0).solve()
    grid = pv.read(write_vtu(tmp_path / "w.vtu", sol, samples=4))
    on = np.flatnonzero(np.abs(grid.points[:, 0] - 1.0) < 1e-12)
    assert len(on) > 10
    sides = []
    for pi, k in ((0, 1.0), (1, 3.0)):
        xi = grid.points[on] - np.array([pi, 0.0, 0.0])
        xi[:, 0] = 1.0 - pi
        x, J, _ = patch_geometry_points(sol.problem.model.patches[pi], xi)
        T = sol.temperature_spline(pi)
        dT = np.stack([T.derivative(xi, o)[:, 0] for o in ((1, 0, 0), (0, 1, 0), (0, 0, 1))], 1)
        grad, _ = gradient_and_det([J[:, :, 0], J[:, :, 1], J[:, :, 2]], dT)
        sides.append(-k * grad)
    assert np.abs(sides[0] - sides[1]).max() > 0.05  # the flux does jump here
    written = grid.point_data["heat_flux"][on]
    assert np.abs(written - 0.5 * (sides[0] + sides[1])).max() < 1e-9


# ------------------------------------------------------------------ topology
@pytest.mark.parametrize("gap", [2e-14, 1e-9 * 2.0, 4e-14])
@pytest.mark.parametrize("x0", [0.0, 3.5e-7, 5e-8 - 1e-14])
def test_boxes_a_hair_apart_are_coupled_wherever_they_sit(gap, x0):
    """No rounding bucket splits a pair: the faces' centres are paired by a KD-tree within the tolerance."""
    from geometry import MultiPatch

    a = pr.box((2.0, 2.0, 2.0), origin=(x0, 0.0, 0.0))
    b = pr.box((2.0, 2.0, 2.0), origin=(x0 + 2.0 + gap, 0.0, 0.0))
    m = MultiPatch.from_splines([a, b])
    assert [(i.a, i.b) for i in m.interfaces] == [((0, "umax"), (1, "umin"))]
    sol = HeatProblem(m).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    assert sol.info["components"]["count"] == 1
    assert sol.probe(np.array([[x0 + 2.0, 1.0, 1.0]]))[0] == pytest.approx(0.5, abs=1e-8)


def test_patches_that_touch_without_conforming_are_refused_naming_the_faces():
    from geometry import MultiPatch, SplineError
    from tiling import Tile, TilingError

    a = pr.box((1.0, 1.0, 0.5))
    b = pr.box((0.5, 0.5, 0.5), origin=(0.25, 0.25, 0.5))  # its wmin lies inside a's wmax
    with pytest.raises(SplineError, match="face wmax of patch 0 touches patch 1|face wmin of patch 1 touches"):
        MultiPatch.from_splines([a, b])
    # the same inside a paving: the tile's two patches meet face on face with no interface between them
    with pytest.raises(TilingError, match=r"face wmax of patch 0 \(tile 0\) and face wmin of patch 1 \(tile 0\) "
                                          "touch but no interface glues them"):
        tiling.regular(pr.box(), Tile([a, b], name="stack"), (1, 1, 1))


def test_a_floating_piece_is_refused_and_pieces_are_reported():
    from iga import SingularProblemError

    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    cut = [i for i in ms.interfaces if ms.patches[i.a[0]].tile != ms.patches[i.b[0]].tile]
    assert len(cut) == 1
    ms.interfaces.remove(cut[0])  # the bond between the two tiles
    with pytest.raises(SingularProblemError, match="falls apart into 2 connected pieces and 1 of them float"):
        HeatProblem(ms).dirichlet("umin", 0.0).neumann("umax", 1.0).solve()
    from iga.discretisation.components import IdleComponentWarning

    with pytest.warns(IdleComponentWarning, match="2 of the model's 2 connected pieces carry no heat"):
        sol = HeatProblem(ms).dirichlet("umin", 0.0).robin("umax", 1.0, 1.0).solve()
    assert sol.info["components"]["count"] == 2
    whole = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    ref = HeatProblem(whole).dirichlet("umin", 0.0).robin("umax", 1.0, 1.0).solve()
    assert ref.info["components"]["count"] == 1
    assert sol.info["free_dofs"] > ref.info["free_dofs"]  # the cut face's DOFs are no longer shared


def test_no_heat_path_between_conditions_is_told_and_the_balance_is_scaled():
    """The regular paving of the fractal tile joins no wall to the opposite one (Massarwi et al. 2018 Fig. 3)."""
    from iga.discretisation.components import IdleComponentWarning

    ms = tiling.regular(pr.box(), L.fractal(), (2, 2, 2))
    with pytest.warns(IdleComponentWarning, match="no heat path joins conditions of different values"):
        sol = HeatProblem(ms).dirichlet("wmin", 100.0).robin("wmax", 5.0, 20.0).solve()
    info = sol.info
    assert info["components"]["count"] == info["components"]["idle"] > 1
    assert info["balance"]["inflow_W"] < 1e-9 and info["balance"]["relative_error"] < 1e-9
    assert info["balance"]["reference_flow_W"] > 1.0  # k A dT / L, not a round-off flow


# ---------------------------------------------------------------------- IGES
def _area_and_volume_flux(s):
    """(area, int x . (S_s x S_t) ds dt) of a surface: its share of 3 V by the divergence theorem."""
    g, W = surface_gauss(s)
    J = s.jacobian(g)[:, :3, :]
    n = np.cross(J[:, :, 0], J[:, :, 1])
    return float(np.sum(np.linalg.norm(n, axis=1) * W)), float(np.sum(np.einsum("ni,ni->n", s.evaluate(g)[:, :3], n) * W))


@pytest.mark.slow
def test_the_iges_boundary_of_the_demo_sinks_is_closed_continuous_and_outward(demo):
    """Slot walls included and every side cut at its C^-1 knots: the surfaces bound the solid, so the divergence
    theorem over them gives its volume (Massarwi et al. 2018: a precise, watertight model)."""
    from tiling.export import boundary_splines

    ms = demo.problem.model
    surfaces = boundary_splines(ms)
    for s in surfaces:
        for U, p in zip(s.knots, s.degrees):
            _, mult = np.unique(U, return_counts=True)
            assert mult[1:-1].max(initial=0) <= p  # continuous: no interior knot of multiplicity p + 1
    flux = sum(_area_and_volume_flux(s)[1] for s in surfaces)
    assert flux / 3 == pytest.approx(demo.volume(), rel=1e-9)
    without_slots = len(surfaces) - sum(len(r) for r in ms.face_regions.values())
    assert len(ms.face_regions) > 0 and without_slots < len(surfaces)


def _vrep_union():
    from tiling.vrep import Primitive, vrep_microstructure

    DA, DB = pr.box((2.0, 1.0, 1.0)), pr.box((2.0, 1.0, 1.0)).translate([1.5, 0.0, 0.0])
    A = Primitive(DA, L.cross(), (4, 2, 2), 2, "A")
    B = Primitive(DB, L.cross(), (6, 3, 3), 1, "B")
    return vrep_microstructure(A | B).microstructure


@pytest.mark.slow
@pytest.mark.parametrize("which", ["circular", "vertical", "vrep union"])
def test_opencascade_rereads_the_iges_with_every_area(which, tmp_path):
    """gmsh's OpenCASCADE reads every surface back: the same surfaces (points and areas, integrated on the
    surfaces OpenCASCADE holds) and its own area integral (BRepGProp, whose fixed rule, with Gauss points
    by the degree, reaches about 4e-6 on the circular sink's degree-12 surfaces and 7e-5 on the curved
    degree-2 ones of the vertical sink, whose box map is affine: exact to 3e-16 on its flat faces)."""
    gmsh = pytest.importorskip("gmsh")
    from geometry.io.iges import write_iges
    from tiling.export import boundary_splines

    ms = _vrep_union() if which == "vrep union" else _demo_problem(which).model
    ours = boundary_splines(ms)  # what tiling.export.write_iges writes
    path = write_iges(tmp_path / "m.igs", ours, units="mm")  # OpenCASCADE works in millimetres: no scaling
    rng = np.random.default_rng(11)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Geometry.OCCAutoFix", 0)  # read the surfaces as written, no shape healing
        gmsh.option.setNumber("Geometry.OCCImportLabels", 0)  # no XDE labels: 20x faster on 1,300 entities
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        tags = [t for _, t in gmsh.model.getEntities(2)]
        assert len(tags) == len(ours)
        mass_check = set(rng.choice(len(tags), min(len(tags), 40), replace=False).tolist())
        for j, (tag, s) in enumerate(zip(tags, ours)):
            g, W = surface_gauss(s)
            d = np.array(gmsh.model.getDerivative(2, tag, g.ravel())).reshape(-1, 2, 3)
            area = float(np.sum(np.linalg.norm(np.cross(d[:, 0], d[:, 1]), axis=1) * W))
            mine = _area_and_volume_flux(s)[0]
            assert area == pytest.approx(mine, rel=1e-9)
            x = np.array(gmsh.model.getValue(2, tag, g[:7].ravel())).reshape(-1, 3)
            assert np.abs(x - s.evaluate(g[:7])[:, :3]).max() < 1e-9 * max(1.0, np.abs(x).max())
            if j in mass_check:
                assert gmsh.model.occ.getMass(2, tag) == pytest.approx(mine, rel=1e-4)
    finally:
        gmsh.finalize()


def test_iges_strings_that_would_corrupt_the_records_are_refused(tmp_path):
    from geometry import SplineError
    from geometry.io.iges import write_iges

    s = pr.box().boundary("umin")
    for kw, match in (({"name": "a\nb"}, "name 'a\\\\nb' holds"), ({"author": "Zoë"}, "author 'Zoë' holds 'ë'")):
        with pytest.raises(SplineError, match=match):
            write_iges(tmp_path / "x.igs", [s], **kw)
    assert not list(tmp_path.iterdir())
    path = write_iges(tmp_path / "ok.igs", [s], name="x" * 300, author="a, b; c")
    lines = path.read_text(encoding="ascii").splitlines()
    assert all(len(r) == 80 for r in lines)


# ------------------------------------------------------------------ G+Smo XML
@pytest.mark.slow
def test_gismo_round_trip_of_the_graded_sink_with_robin_on_exterior(tmp_path):
    """The README's T2 sink (conductivity graded as the channel k), Robin on every exterior face, slot walls
    included: read back, the same temperatures at the bases the exported problem used; G+Smo's own reader
    (pygismo) sees every patch, identity interface and side condition, and the export names what it cannot."""
    import re

    from geometry.io.gismo import read_gismo
    from iga import ProblemError
    from iga.io.gismo import GismoExtensionWarning, export_gismo, problem_from_gismo

    p = _demo_problem("vertical")
    p.conditions.clear()
    p.neumann("branch-in", 1515.8).robin("exterior", 5.0, 30.0)
    with pytest.warns(GismoExtensionWarning, match=r"64 branch interfaces, \d+ conditions on slot faces, the "
                                                    "conductivity channel 'k'"):
        path = export_gismo(p, tmp_path / "sink.xml")
    with pytest.raises(ProblemError, match=r"G\+Smo.s format cannot hold 64 branch interfaces"):
        export_gismo(p, tmp_path / "strict.xml", strict=True)
    assert not (tmp_path / "strict.xml").exists()
    q = problem_from_gismo(path)
    assert q.ndof == p.ndof and [s.shape for s in q.spaces] == [s.shape for s in p.spaces]  # not degree 12
    s1, s2 = p.solve(tol=1e-12), q.solve(tol=1e-12)
    rng = np.random.default_rng(2)
    x = np.concatenate([P.image(rng.random((2, 3))) for P in p.model.patches])
    t1, t2 = s1.probe(x), s2.probe(x)
    assert np.abs(t1 - t2).max() < 1e-8 * np.abs(t1).max()
    assert s2.mean_temperature() == pytest.approx(s1.mean_temperature(), rel=1e-10)
    assert s2.flux("bc1") == pytest.approx(s1.flux("exterior"), rel=1e-9)
    gs = pytest.importorskip("pygismo")
    g = read_gismo(path)
    mp = gs.core.gsMultiPatch()
    fd = gs.io.gsFileData(str(path))
    assert fd.getFirst(mp) and mp.nPatches() == len(p.model.patches)
    assert len(mp.interfaces()) == sum(i.kind == "identity" for i in p.model.interfaces) == len(g.interfaces)
    bc = gs.pde.gsBoundaryConditions()
    fd.getId(int(re.search(r'<boundaryConditions multipatch="\d+" id="(\d+)"', path.read_text()).group(1)), bc)
    assert bc.size() == sum(len(c.faces) for c in g.conditions) > 0


_GEO = ('<Geometry type="TensorBSpline3" id="{id}"><Basis type="TensorBSplineBasis3">'
        + "".join(f'<Basis type="BSplineBasis" index="{k}"><KnotVector degree="{{deg}}">0 0 1 1</KnotVector></Basis>'
                  for k in range(3)) + '</Basis><coefs geoDim="{gdim}">' + " ".join(["0 0 0"] * 8) + "</coefs></Geometry>")


@pytest.mark.parametrize("text, match", [
    ("<xml>" + _GEO.format(id=0, deg="abc", gdim=3) + "</xml>", r"degree='abc' is not an integer"),
    ("<xml>" + _GEO.format(id=0, deg=1, gdim="x") + "</xml>", r"geoDim='x' is not an integer"),
    ("<xml>" + _GEO.format(id=0, deg=1, gdim=3).replace('degree="1"', "", 1) + "</xml>",
     r"<KnotVector> has no degree attribute"),
    ("<xml>" + _GEO.format(id=0, deg=4000000000, gdim=3) + "</xml>", r"direction 0 has degree 4000000000 and 4 knots"),
    ("<xml>" + _GEO.format(id=0, deg=1, gdim=3) + _GEO.format(id=0, deg=1, gdim=3) + "</xml>",
     r"two <Geometry> elements have id '0'"),
    ("<xml>" + _GEO.format(id=0, deg=1, gdim=3) + '<MultiPatch parDim="3" id="1"><patches type="id_range">0 999999999'
     "</patches></MultiPatch></xml>", r"id_range.*at most 1 defined"),
    ("<xml>" + _GEO.format(id=0, deg=1, gdim=3) + "<BranchInterfaces>99 1 0 1 0 1 0 2</BranchInterfaces></xml>",
     r"<BranchInterfaces> names patch 99\.0"),
    ("<xml>" + _GEO.format(id=0, deg=1, gdim=3).replace('<Basis type="TensorBSplineBasis3">',
                                                        '<Basis type="TensorNurbsBasis3"><Basis type="TensorBSplineBasis3">')
     .replace("</Basis><coefs", "</Basis><weights>1 1 1 1 1 1 1</weights></Basis><coefs") + "</xml>",
     r"7 weights for 8 control points"),
])
def test_gismo_reader_names_the_file_element_and_attribute(text, match, tmp_path):
    from geometry import SplineError
    from geometry.io.gismo import read_gismo

    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(SplineError, match=match):
        read_gismo(path)


def test_vtu_samples_chosen_from_a_geometric_tolerance_meet_it_per_direction(tmp_path):
    import pyvista as pv

    from geometry.patches.sampling import chord_samples

    ms = tiling.regular(pr.annulus(0.5, 1.0, 0.3, angle=np.pi), L.cross(), (2, 1, 1))  # curved along u only
    sol = HeatProblem(ms).dirichlet("vmin", 1.0).dirichlet("vmax", 0.0).solve()
    knots = lambda pi: [d.knots for d in sol.problem.spaces[pi].dirs]  # noqa: E731
    loose, tight = chord_samples(ms, knots, 1e-2), chord_samples(ms, knots, 1e-4)
    assert all(t[0] > lo[0] for t, lo in zip(tight, loose))  # finer along the curved direction ...
    assert all(t[1:] == (1, 1) for t in tight)  # ... and one sample per element where the geometry is straight
    exact = sol.volume()
    err = [abs(pv.read(write_vtu(tmp_path / f"t{i}.vtu", sol, tolerance=tol)).volume / exact - 1)
           for i, tol in enumerate((1e-2, 1e-4))]
    assert err[1] < 0.05 * err[0] and err[1] < 1e-4


def test_pinch_lines_of_a_tile_are_named_and_explain_its_non_manifold_edges():
    """Massarwi et al. 2018, Fig. 2(c): the skinned tile's slots open right from its base, so at the root its fins
    touch along lines of the free base face: closed, not a manifold there, and the report names those lines;
    a real defect (two blocks touching along an edge only) stays unexplained."""
    from geometry import MultiPatch
    from tiling.export import watertightness

    ms = tiling.hierarchical(pr.box(), L.skinned_branching(), (2, 1), levels=2)
    w = watertightness(ms)
    assert w["closed"] and w["components"] == 1 and not w["manifold"]
    assert w["pinched_edges"] == w["nonmanifold_edges"] > 0 and w["unexplained_nonmanifold_edges"] == 0
    assert {ln["face"] for ln in w["pinch_lines"]} == {"wmin"} and len(w["pinch_lines"]) == 2 * 7
    for ln in w["pinch_lines"]:  # on the base (z = 0) of the box map, along a slot plane of its tile
        assert np.abs(ln["points"][:, 2]).max() < 1e-12
    edge = MultiPatch.from_splines([pr.box(), pr.box(origin=(1.0, 1.0, 0.0))], couple=False)
    w = watertightness(edge)
    assert not w["pinch_lines"] and w["unexplained_nonmanifold_edges"] == w["nonmanifold_edges"] > 0
    sink = tiling.hierarchical(pr.box((0.06, 0.06, 0.03), degrees=(2, 2, 2)), L.heat_sink_t2(), (2, 2), levels=2)
    w = watertightness(sink)  # slots that open above a solid base: a crease, no pinch
    assert w["manifold"] and not w["pinch_lines"]


def test_the_contact_check_finds_the_same_pairs_whatever_its_chunks(monkeypatch):
    """The free faces are sampled in chunks (bounded transients); pairs across chunks are still found."""
    import geometry.patches.contact as contact
    from geometry.patches.multipatch import free_face_mask

    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (3, 2, 2))
    cut = [i for i in ms.interfaces if ms.patches[i.a[0]].tile != ms.patches[i.b[0]].tile][:4]
    for itf in cut:  # four glued pairs between tiles made free faces that touch
        ms.interfaces.remove(itf)
    mask = free_face_mask(ms.patches, ms.interfaces)
    whole = contact.unglued_contacts(ms.patches, ms.interfaces, limit=10, mask=mask)
    monkeypatch.setattr(contact, "_CHUNK", 7)  # a prime below the faces' count: pairs straddle chunks
    chunked = contact.unglued_contacts(ms.patches, ms.interfaces, limit=10, mask=mask)
    expected = {frozenset([i.a, i.b]) for i in cut}
    assert {frozenset(p) for p in whole} == expected and {frozenset(p) for p in chunked} == expected


def test_face_points_take_keys_as_tuples_or_as_an_index_array():
    from geometry.faces import FACE_NAMES
    from geometry.patches.multipatch import FACE_SAMPLES
    from geometry.patches.placed_points import face_points

    ms = tiling.regular(pr.twisted(pr.box(degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5)), L.cross(), (2, 2, 1))
    rng = np.random.default_rng(3)
    rows = np.stack([rng.integers(0, len(ms.patches), 40), rng.integers(0, 6, 40)], axis=1)
    keys = [(int(p), FACE_NAMES[f]) for p, f in rows]
    assert np.array_equal(face_points(ms.patches, rows, FACE_SAMPLES), face_points(ms.patches, keys, FACE_SAMPLES))
