"""Interoperability: G+Smo XML (exact round trip, topology, heat problems), IGES (entities 126/128), iga info."""


import numpy as np
import pytest
from commands import iga_command

import tiling
from geometry import BSpline, SplineError, primitives as pr
from geometry.faces import FACE_AXIS
from geometry.io.gismo import GismoCondition, interface_maps, read_gismo, write_gismo
from geometry.io.iges import write_iges
from helpers import opencascade, read_own_iges as _read_own_iges, random_spline
from iga import HeatProblem, ProblemError
from iga.io.gismo import export_gismo, load_gismo, problem_from_gismo
from tiling import library as L

AFFINE = pr.box((2.0, 1.0, 1.5))


def _same(a: BSpline, b: BSpline) -> bool:
    return (a.degrees == b.degrees and all(np.array_equal(x, y) for x, y in zip(a.knots, b.knots))
            and np.array_equal(a.control_points, b.control_points) and a.channels == b.channels
            and ((a.weights is None and b.weights is None) or np.array_equal(a.weights, b.weights)))


def test_gismo_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(0)
    splines = [random_spline(rng, 3, rational=r, channels=c) for r, c in
               [(False, ()), (True, ()), (False, ("k",)), (True, ("k", "rho"))]]
    itf = [((0, "umax"), (1, "vmin"), True, (False, True))]
    conds = [GismoCondition("Dirichlet", [(0, "umin")], "20.0"), GismoCondition("Robin", [(1, "wmax")], "30", "5")]
    path = write_gismo(tmp_path / "m.xml", splines, itf, [(0, "umin"), (3, "wmax")], conds, {"conductivity": "205"})
    g = read_gismo(path)
    assert all(_same(a, b) for a, b in zip(splines, g.patches)) and len(g.patches) == 4
    assert g.boundary == [(0, "umin"), (3, "wmax")]
    (a, b, dmap, orient), = g.interfaces
    assert (a, b) == ((0, "umax"), (1, "vmin")) and (dmap, orient) == interface_maps("umax", "vmin", True, (False, True))
    assert [(c.kind, c.faces, c.expression, c.coefficient) for c in g.conditions] == \
        [(c.kind, c.faces, c.expression, c.coefficient) for c in conds]
    assert g.functions == {"conductivity": "205"}
    # and surfaces and curves (G+Smo's "BSpline" / "Nurbs" curve types)
    for dim in (2, 1):
        s = [random_spline(rng, dim, rational=True), random_spline(rng, dim)]
        assert all(_same(a, b) for a, b in zip(s, read_gismo(write_gismo(tmp_path / f"s{dim}.xml", s)).patches))


@pytest.mark.parametrize("a_face,b_face", [("umax", "umin"), ("vmax", "wmin"), ("wmin", "umin")])
def test_interface_maps_send_every_corner_where_our_orientation_does(a_face, b_face):
    """Our (swap, flip) and G+Smo's (direction map, orientation) agree on the four corners of the face."""
    ka, sa = FACE_AXIS[a_face]
    kb, sb = FACE_AXIS[b_face]
    ra, rb = [j for j in range(3) if j != ka], [j for j in range(3) if j != kb]
    for swap in (False, True):
        for fs in (False, True):
            for ft in (False, True):
                dmap, orient = interface_maps(a_face, b_face, swap, (fs, ft))
                assert sorted(dmap) == [0, 1, 2] and dmap[ka] == kb
                for s in (0, 1):
                    for t in (0, 1):
                        ours = (t, s) if swap else (s, t)  # b's (s', t') before the flips
                        ours = (1 - ours[0] if fs else ours[0], 1 - ours[1] if ft else ours[1])
                        a_par = np.zeros(3, int)
                        a_par[ka], a_par[ra[0]], a_par[ra[1]] = sa, s, t
                        b_par = np.zeros(3, int)
                        for i in range(3):  # G+Smo: direction i of a runs along dmap[i] of b, reversed if not orient
                            b_par[dmap[i]] = a_par[i] if orient[i] else 1 - a_par[i]
                        b_par[kb] = sb
                        assert (b_par[rb[0]], b_par[rb[1]]) == ours


@pytest.mark.slow
def test_heat_problem_export_reimport_gives_the_same_solution(tmp_path):
    ms = tiling.hierarchical(AFFINE, L.fractal(), (2, 1), 3)  # identity and branch interfaces
    ms.tags["cool"] = [f for f in ms.tags["boundary"] if f not in set(ms.tags["branch-in"])]
    p = HeatProblem(ms, conductivity=205.0, degree=3).neumann("branch-in", 1515.8).robin("cool", 5.0, 30.0)
    from iga.io.gismo import GismoExtensionWarning

    with pytest.warns(GismoExtensionWarning, match="12 branch interfaces"):
        path = export_gismo(p, tmp_path / "sink.xml")
    g = read_gismo(path)
    assert len(g.patches) == len(ms.patches) and len(g.branches) == sum(i.kind == "branch" for i in ms.interfaces)
    assert len(g.interfaces) == sum(i.kind == "identity" for i in ms.interfaces)
    # the exported geometry is the composed geometry, exactly
    rng = np.random.default_rng(1)
    for i in rng.choice(len(ms.patches), 8, replace=False):
        x = rng.random((20, 3))
        assert np.allclose(g.patches[i].evaluate(x)[:, :3], ms.patches[i].composed.evaluate(x)[:, :3], atol=1e-13)
    # the file's problem, solved: the same spaces (degree 3 everywhere) and conditions give the same temperatures
    q = problem_from_gismo(path)
    assert sum(i.kind == "branch" for i in q.model.interfaces) == len(g.branches)
    s1, s2 = p.solve(tol=1e-12), q.solve(tol=1e-12)
    x = np.concatenate([P.composed(rng.random((3, 3)))[:, :3] for P in ms.patches])
    assert np.abs(s1.probe(x) - s2.probe(x)).max() < 1e-7 * np.abs(s1.probe(x)).max()
    assert s2.flux("bc0") == pytest.approx(s1.flux("branch-in"), rel=1e-10)


def test_load_gismo_detects_topology_and_checks_the_files(tmp_path):
    a, b = pr.box((1, 1, 1)), pr.box((1, 1, 1), origin=(1, 0, 0))
    path = write_gismo(tmp_path / "two.xml", [a, b], [((0, "umax"), (1, "umin"), False, (False, False))])
    model = load_gismo(path)
    assert len(model.interfaces) == 1 and {model.interfaces[0].a, model.interfaces[0].b} == {(0, "umax"), (1, "umin")}
    bad = write_gismo(tmp_path / "bad.xml", [a, b], [((0, "umin"), (1, "umax"), False, (False, False))])
    with pytest.raises(ProblemError, match="do not coincide"):
        load_gismo(bad)


def test_gismo_bad_input(tmp_path):
    cases = {
        "malformed.xml": ("<xml><Geometry", "malformed XML"),
        "thb.xml": ('<xml><Geometry type="THBSpline3" id="0"/></xml>', "THBSpline3"),
        "empty.xml": ("<xml></xml>", "no <Geometry>"),
        "coefs.xml": ('<xml><Geometry type="BSpline" id="0"><Basis type="BSplineBasis">'
                      '<KnotVector degree="1">0 0 1 1</KnotVector></Basis><coefs geoDim="3">0 0 0</coefs>'
                      "</Geometry></xml>", "coefficients"),
        "text.xml": ('<xml><Geometry type="BSpline" id="0"><Basis type="BSplineBasis">'
                     '<KnotVector degree="1">0 0 one 1</KnotVector></Basis><coefs>0</coefs></Geometry></xml>',
                     "knots must be numbers"),
    }
    for name, (text, match) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(SplineError, match=match):
            read_gismo(tmp_path / name)
    path = write_gismo(tmp_path / "bc.xml", [pr.box()], conditions=[GismoCondition("Dirichlet", [(0, "umin")], "1")])
    path.write_text(path.read_text().replace('type="Dirichlet"', 'type="Clamped"'))
    with pytest.raises(SplineError, match="Clamped"):
        read_gismo(path)
    with pytest.raises(SplineError, match="not one of"):
        write_gismo(tmp_path / "x.xml", [pr.box()], conditions=[GismoCondition("Clamped", [(0, "umin")], "1")])
    with pytest.raises(SplineError, match="cannot read"):
        read_gismo(tmp_path / "missing.xml")
    with pytest.raises(SplineError, match=r"interfaces: \(5, 'top'\)"):
        write_gismo(tmp_path / "i.xml", [pr.box()], [((0, "umax"), (5, "top"), False, (False, False))])
    # export refuses what has no expression, naming it
    p = HeatProblem(AFFINE).dirichlet("umin", lambda x: x[:, 0])
    with pytest.raises(ProblemError, match="dirichlet value on 'umin' is a callable"):
        export_gismo(p, tmp_path / "c.xml")
    with pytest.raises(ProblemError, match="isotropic conductivity that is a number, a channel or a formula"):
        export_gismo(HeatProblem(AFFINE, conductivity=np.diag([1.0, 2.0, 3.0])), tmp_path / "k.xml")
    assert not (tmp_path / "c.xml").exists() and not (tmp_path / "k.xml").exists()


def test_iges_writes_exact_surfaces_and_curves(tmp_path):
    rng = np.random.default_rng(3)
    s = random_spline(rng, 2, rational=True, max_p=3)
    c = random_spline(rng, 1, max_p=3)
    path = write_iges(tmp_path / "x.igs", [s, c])
    (p128, p126) = _read_own_iges(path)
    # entity 128: K1, K2, M1, M2, flags, knots, weights, points (first index fastest), range
    k1, k2, m1, m2 = (int(v) for v in p128[1:5])
    assert (m1, m2) == s.degrees and (k1 + 1, k2 + 1) == s.shape and p128[7] == 0  # rational
    n1, n2 = s.shape
    i = 10
    U = p128[i:i + n1 + m1 + 1]
    V = p128[i + n1 + m1 + 1:i + n1 + m1 + 1 + n2 + m2 + 1]
    i += len(U) + len(V)
    W = np.array(p128[i:i + n1 * n2]).reshape(n2, n1).T
    P = np.array(p128[i + n1 * n2:i + 4 * n1 * n2]).reshape(n2, n1, 3).transpose(1, 0, 2)
    back = BSpline(s.degrees, [np.array(U), np.array(V)], P, W)
    x = rng.random((200, 2))
    assert np.abs(back.evaluate(x) - s.evaluate(x)[:, :3]).max() < 1e-14
    assert int(p126[1]) + 1 == c.shape[0] and int(p126[2]) == c.degrees[0] and p126[5] == 1  # polynomial
    # a micro-structure's boundary: one entity per free side
    ms = tiling.regular(AFFINE, L.cross(), (2, 1, 1))
    path = tiling.export.write_iges(tmp_path / "ms.igs", ms)
    assert len(_read_own_iges(path)) == len(ms.tags["boundary"])
    with pytest.raises(SplineError, match="curves and surfaces"):
        write_iges(tmp_path / "v.igs", [pr.box()])
    with pytest.raises(SplineError, match="units"):
        write_iges(tmp_path / "u.igs", [s], units="furlong")


def test_iges_opens_in_opencascade(tmp_path):
    """A second reader: gmsh's OpenCASCADE import (gmsh's pip wheel) gives the same surface points."""
    rng = np.random.default_rng(5)
    surfaces = [random_spline(rng, 2, rational=r, max_p=3) for r in (False, True, True)]
    path = write_iges(tmp_path / "x.igs", surfaces, units="mm")  # OpenCASCADE works in millimetres
    with opencascade(path) as (gmsh, tags):
        assert len(tags) == 3
        for tag, s in zip(tags, surfaces):
            uv = rng.random((30, 2))
            got = np.array(gmsh.model.getValue(2, tag, uv.ravel())).reshape(-1, 3)
            assert np.abs(got - s.evaluate(uv)[:, :3]).max() < 1e-10


def test_gismo_file_opens_in_pygismo(tmp_path):
    """G+Smo's own reader (the pygismo wheel) evaluates our patches alike and sees our topology."""
    gs = pytest.importorskip("pygismo")
    rng = np.random.default_rng(6)
    a, b = pr.box((1, 1, 1)), pr.box((1, 1, 1), origin=(1, 0, 0))
    nurbs = random_spline(rng, 3, rational=True, max_p=3)
    path = write_gismo(tmp_path / "m.xml", [a, b, nurbs], [((0, "umax"), (1, "umin"), False, (False, False))],
                       [(0, "umin")])
    mp = gs.core.gsMultiPatch()
    assert gs.io.gsFileData(str(path)).getFirst(mp)
    assert mp.nPatches() == 3 and len(mp.interfaces()) == 1
    for i, s in enumerate([a, b, nurbs]):
        x = rng.random((3, 40))
        assert np.abs(mp.patch(i).eval(x) - s.evaluate(x.T)[:, :3].T).max() < 1e-13


@pytest.mark.slow
def test_iga_info_reads_gismo_and_npz(tmp_path):
    from geometry.io.files import save_all

    path = write_gismo(tmp_path / "m.xml", [pr.box(), pr.box(origin=(1, 0, 0))],
                       [((0, "umax"), (1, "umin"), False, (False, False))],
                       conditions=[GismoCondition("Dirichlet", [(0, "umin")], "20")])
    out = iga_command("info", path)
    assert out.returncode == 0, out.stderr
    assert "2 patches, 1 interface" in out.stdout and "Dirichlet 20" in out.stdout and "regularity: regular" in out.stdout
    npz = save_all(tmp_path / "s.npz", [pr.box((2.0, 1.0, 0.5))])
    out = iga_command("info", npz)
    assert out.returncode == 0 and "1 spline" in out.stdout
    # the map's scale bounds (Elber 2017, Section 4): exact for a box of sides 2, 1, 0.5
    assert "singular values of the Jacobian) within 0.5 .. 2 over 1 boxes" in out.stdout
    assert "|dD/du| 2 .. 2, |dD/dv| 1 .. 1, |dD/dw| 0.5 .. 0.5" in out.stdout and "distortion bound 4" in out.stdout
    (tmp_path / "x.stl").write_text("solid")
    out = iga_command("info", tmp_path / "x.stl")
    assert out.returncode == 1 and "cannot read x.stl as a mesh" in out.stderr and "Traceback" not in out.stderr


@pytest.mark.slow
def test_iga_info_describes_every_file_the_toolkit_writes(tmp_path):
    import tiling
    from geometry.io.iges import write_iges
    from iga import HeatProblem, write_vtu
    from tiling import library as L
    from tiling.export import boundary_splines, write_surfaces

    ms = tiling.regular(pr.box(), L.cross(), (1, 1, 1))
    s = HeatProblem(ms).dirichlet("umin", 1.0).dirichlet("umax", 0.0).solve()
    files = {"m.vtu": lambda p: write_vtu(p, s, samples=1), "s.stl": lambda p: write_surfaces(p, ms),
             "b.igs": lambda p: write_iges(p, boundary_splines(ms))}
    want = {"m.vtu": [r"hexahedra", r"point array temperature: 0 \.\. 1"], "s.stl": [r"triangles"],
            "b.igs": [r"IGES, 30 entities \(30 B-spline surfaces\)"]}
    import re

    for name, write in files.items():
        write(tmp_path / name)
        out = iga_command("info", tmp_path / name)
        assert out.returncode == 0, out.stderr
        for pattern in want[name]:
            assert re.search(pattern, out.stdout), (name, out.stdout)
    (tmp_path / "summary.json").write_text('{"tiles": 3, "levels": 1, "interfaces": 2, "files": {"vtu": "m.vtu"}}')
    out = iga_command("info", tmp_path / "summary.json")
    assert out.returncode == 0 and "pipeline summary, 3 tiles on 1 levels" in out.stdout
    (tmp_path / "bad.igs").write_text("not iges\n")
    out = iga_command("info", tmp_path / "bad.igs")
    assert out.returncode == 1 and "is not an IGES file" in out.stderr and "Traceback" not in out.stderr


def test_raw_and_compressed_vtu_hold_the_same_arrays_for_meshio_and_vtk(tmp_path):
    import meshio
    import pyvista as pv

    from iga import write_vtu

    ms = tiling.regular(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), L.cross(), (2, 1, 1))
    sol = HeatProblem(ms, conductivity=3.0).dirichlet("umin", 1.0).robin("rest", 2.0, 0.0).solve()
    raw, packed = write_vtu(tmp_path / "raw.vtu", sol), write_vtu(tmp_path / "zlib.vtu", sol, compress=True)
    head = [p.read_bytes()[:400] for p in (raw, packed)]
    assert b"vtkZLibDataCompressor" not in head[0] and b"vtkZLibDataCompressor" in head[1]
    assert b'header_type="UInt64"' in head[0]
    a, b = meshio.read(raw), meshio.read(packed)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.cells[0].data, b.cells[0].data)
    for name in ("temperature", "heat_flux"):
        assert np.array_equal(a.point_data[name], b.point_data[name])
        assert np.array_equal(pv.read(raw).point_data[name], a.point_data[name])
    with pytest.raises(ProblemError, match="compress must be True or False"):
        write_vtu(tmp_path / "x.vtu", sol, compress="yes")
