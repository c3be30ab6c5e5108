"""Every builder from a pipeline: V-rep models, polygon tiles, surface and curve tiles, two-level
structures, degree reduction, and the analysis degree; each against the same model built in Python."""

import numpy as np
import pytest
from commands import iga_command

from iga import HeatProblem
from iga.app.config import validate
from iga.errors import ProblemError
from iga.app.pipeline import run_pipeline


def _out(tmp_path, name="o", **kw):
    return {"dir": str(tmp_path / name), "png": False, **kw}


def _union(tmp_path):
    return {"paving": {"scheme": "vrep", "expression": "A | B"},
            "primitive": [{"name": "A", "map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0],
                                                                            "channels": {"k": 205.0}}},
                           "tile": {"library": "cross"}, "counts": [4, 2, 2], "priority": 2},
                          {"name": "B", "map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0],
                                                                            "origin": [1.5, 0.0, 0.0],
                                                                            "channels": {"k": 54.0}}},
                           "tile": {"library": "cross"}, "counts": [4, 2, 2], "priority": 1}],
            "material": {"conductivity": "k"},
            "bc": [{"kind": "dirichlet", "tag": "A:umin", "value": 100.0},
                   {"kind": "dirichlet", "tag": "B:umax", "value": 0.0}],
            "output": _out(tmp_path, vtu=False)}


def test_a_vrep_union_runs_from_a_pipeline_as_in_python(tmp_path):
    from geometry.primitives import box
    from tiling import library as L
    from tiling.vrep import Primitive, vrep_microstructure

    s = run_pipeline(_union(tmp_path), tmp_path)
    assert s["connected_pieces"] == 1 and s["energy_balance_error"] < 1e-9 and s["tiles"] > 20
    assert set(s["vrep"]["tiles_per_primitive"]) == {"A", "B"} and s["vrep"]["model"].startswith("VModel(")
    b = s["vrep"]["bridges"]  # the bridging in summary.json, with the faces left without a bridge by reason
    assert b["anchoring_faces"] > 0 and b["surface_bridges"] + b["union_bridges"] > 0
    assert isinstance(b["unbridged"], dict) and all(n > 0 for n in b["unbridged"].values())
    A = Primitive(box((2.0, 1.0, 1.0), channels={"k": 205.0}), L.cross(), (4, 2, 2), 2, "A")
    B = Primitive(box((2.0, 1.0, 1.0), origin=(1.5, 0.0, 0.0), channels={"k": 54.0}), L.cross(), (4, 2, 2), 1, "B")
    ms = vrep_microstructure(A | B).microstructure
    sol = HeatProblem(ms, "k").dirichlet("A:umin", 100.0).dirichlet("B:umax", 0.0).solve(tol=1e-10)
    assert s["temperature_C"]["mean"] == pytest.approx(sol.mean_temperature(), rel=1e-8)
    assert s["flux_W"]["A:umin"] == pytest.approx(sol.flux("A:umin"), rel=1e-8)


@pytest.mark.parametrize("change, match", [
    (lambda c: c["paving"].update(expression="A | C"), r"paving\.expression: names 'C', which no \[\[primitive\]\]"),
    (lambda c: c["paving"].update(expression="A"), r"paving\.expression: leaves out the primitive 'B'"),
    (lambda c: c["paving"].update(expression="A |"), r"primitive expression 'A \|': it ends where a primitive is "
                                                       r"expected; combine primitives with"),
    (lambda c: c["paving"].update(expression="(A | B"), r"a parenthesis is not closed"),
    (lambda c: c.update(map={"primitive": "box"}), r"config section map does not apply to the vrep scheme"),
    (lambda c: c.update(tile={"library": "cross"}), r"config section tile does not apply to the vrep scheme"),
    (lambda c: c["primitive"][1].update(name="A"), r"primitive\[1\]\.name: must be a new word"),
    (lambda c: c["primitive"][0].update(counts=[4, 2]), r"primitive\[0\]\.counts: must be a list of 3 integers"),
    (lambda c: c["primitive"][0]["tile"].update(library="nope"), r"primitive\[0\]\.tile\.library: must be one of"),
    (lambda c: c["primitive"][0]["tile"].update(library="hollow_cross"), r"primitive\[0\]\.tile: 'hollow_cross' has no "
                                                                         r"trivariates"),
    (lambda c: c.pop("primitive"), r"the vrep scheme needs \[\[primitive\]\] tables"),
    (lambda c: c["paving"].update(beta=2.0), r"paving\.beta: must be < 1"),
    (lambda c: c["paving"].update(counts=[1, 1, 1]), r"paving\.counts: does not apply to the vrep scheme"),
])
def test_bad_vrep_pipelines_are_refused_before_any_work(change, match, tmp_path):
    cfg = _union(tmp_path)
    change(cfg)
    with pytest.raises(ProblemError, match=match):
        validate(cfg, tmp_path)


def test_a_polygon_lattice_is_paved_to_its_mesh_and_takes_no_analysis(tmp_path):
    import pyvista as pv

    cfg = {"map": {"primitive": "box"}, "tile": {"library": "beam_lattice"},
           "paving": {"scheme": "polygons", "counts": [2, 2, 2]}, "output": _out(tmp_path)}
    s = run_pipeline(cfg, tmp_path)
    # 27 lattice points; 54 cell edges (each once) and 4 body diagonals in each of the 8 cells
    assert s["mesh"] == {"points": 27, "lines": 54 + 32, "facets": 0} and s["tiles"] == 8
    mesh = pv.read(s["files"]["vtp"])
    assert mesh.n_points == 27 and mesh.n_lines == 86
    for change, match in ((lambda c: c.update(bc=[{"kind": "dirichlet", "tag": "umin", "value": 1.0}]),
                           r"a polygonal paving is a mesh .* not a volumetric B-spline model"),
                          (lambda c: c["output"].update(exports=["stl"]), r"the polygon tile has lines only"),
                          (lambda c: c["output"].update(exports=["iges"]), r"a polygonal paving .* no B-spline"),
                          (lambda c: c.update(tile={"library": "cross"}), r"tile\.library: must be one of"),
                          (lambda c: c.update(tile={"points": [[0, 0, 0], [1, 0, 0], [0, 2, 0]], "polygons": [[0, 1, 2]]}),
                           r"config key tile: polygon tile .* points leave the unit cube")):
        bad = {**cfg, "output": dict(cfg["output"])}
        change(bad)
        with pytest.raises(ProblemError, match=match):
            validate(bad, tmp_path)
    tri = {**cfg, "tile": {"points": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "polygons": [[0, 1, 2]]},
           "output": _out(tmp_path, "t", exports=["stl"], vtu=False)}
    s = run_pipeline(tri, tmp_path)
    assert s["mesh"]["facets"] == 8 and set(s["files"]) == {"stl"}


@pytest.mark.slow
def test_surface_and_curve_tiles_run_to_their_exports_and_refuse_an_analysis(tmp_path):
    import meshio
    import pyvista as pv

    capped = {"map": {"primitive": "box"}, "tile": {"library": "hollow_cross"},
              "paving": {"scheme": "regular", "counts": [2, 2, 2], "seal": "cap"},
              "output": _out(tmp_path, exports=["stl", "iges"])}
    s = run_pipeline(capped, tmp_path)
    assert s["surface"]["closed"] and s["surface"]["components"] == 1 and s["tiles"] == 8
    assert len(meshio.read(s["files"]["stl"]).cells_dict["triangle"]) == s["surface"]["triangles"]
    assert set(s["files"]) == {"vtp", "stl", "iges"}
    with pytest.raises(ProblemError, match=r"tile 'hollow_cross' is made of surfaces.* not a volumetric"):
        validate({**capped, "bc": [{"kind": "dirichlet", "tag": "umin", "value": 1.0}]}, tmp_path)
    # shelled (every side), Boolean-sealed oblique walls, trimmed members: each runs to its exports
    for lib, paving, closed, components in (("hollow_cross", {"seal": "shell"}, True, 2),
                                            ("oblique_tubes", {"seal": "cap"}, True, 3),
                                            ("through_cylinders", {}, False, 1)):
        cfg = {"map": {"primitive": "box"}, "tile": {"library": lib},
               "paving": {"scheme": "regular", "counts": [1, 1, 1], **paving},
               "output": _out(tmp_path, lib, exports=["stl", "iges"])}
        s = run_pipeline(cfg, tmp_path)
        assert (s["surface"]["closed"], s["surface"]["components"]) == (closed, components), lib
        assert set(s["files"]) == {"vtp", "stl", "iges"}
    with pytest.raises(ProblemError, match=r"paving\.seal_sides: applies to seal = \"cap\" only"):
        validate({**capped, "paving": {**capped["paving"], "seal": "shell", "seal_sides": ["umin"]}}, tmp_path)
    helix = {"map": {"primitive": "box"}, "tile": {"library": "helix"}, "paving": {"scheme": "regular",
                                                                                 "counts": [2, 1, 1]},
             "output": _out(tmp_path, "h")}
    s = run_pipeline(helix, tmp_path)
    assert pv.read(s["files"]["vtp"]).n_lines > 0 and s["surface"]["triangles"] == 0
    with pytest.raises(ProblemError, match=r"hold triangles and the model is curves"):
        validate({**helix, "output": _out(tmp_path, "h", exports=["stl"])}, tmp_path)
    with pytest.raises(ProblemError, match=r"output\.bezier: Bezier hexahedra hold trivariates"):
        validate({**helix, "output": _out(tmp_path, "h", bezier=True)}, tmp_path)


@pytest.mark.slow
def test_a_two_level_structure_runs_from_a_pipeline_as_in_python(tmp_path):
    import tiling
    from geometry.primitives import box
    from tiling import library as L

    cfg = {"map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0]}}, "tile": {"library": "cross"},
           "paving": {"scheme": "regular", "counts": [2, 1, 1]},
           "second_level": {"tile": {"library": "cross"}, "counts": [1, 1, 1], "degree": 2},
           "material": {"conductivity": 3.0},
           "bc": [{"kind": "dirichlet", "tag": "umin", "value": 1.0}, {"kind": "dirichlet", "tag": "umax",
                                                                     "value": 0.0}],
           "output": _out(tmp_path, vtu=False)}
    s = run_pipeline(cfg, tmp_path)
    two = tiling.compose_levels(tiling.regular(box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1)), L.cross(), (1, 1, 1))
    sol = HeatProblem(two, 3.0).dirichlet("umin", 1.0).dirichlet("umax", 0.0).solve()
    assert s["second_level"]["patches"] == len(two.patches) == 14 * 7 and s["connected_pieces"] == 1
    assert s["flux_W"]["umin"] == pytest.approx(sol.flux("umin"), rel=1e-8) and s["energy_balance_error"] < 1e-9
    with pytest.raises(ProblemError, match=r"second_level\.degree: must be 2, 3 or \"exact\""):
        validate({**cfg, "second_level": {**cfg["second_level"], "degree": 4}}, tmp_path)
    surf = {**cfg, "second_level": {"tile": {"library": "hollow_cross"}, "counts": [1, 1, 1], "seal": "cap"}}
    with pytest.raises(ProblemError, match=r"second_level\.tile 'hollow_cross' is made of surfaces"):
        validate(surf, tmp_path)
    surf.pop("bc")
    surf.pop("material")
    surf["output"] = _out(tmp_path, "s", vtu=False, exports=["stl"])
    assert run_pipeline(surf, tmp_path)["surface"]["closed"]


def test_a_reduced_sink_keeps_its_tags_and_solves_as_the_exact_one(tmp_path):
    cfg = {"map": {"primitive": "vertical_heat_sink"}, "tile": {"library": "heat_sink_t2"},
           "paving": {"scheme": "hierarchical", "counts": [2, 2], "levels": 2},
           "material": {"conductivity": 50.0},
           "bc": [{"kind": "neumann", "tag": "branch-in", "value": 1000.0},
                  {"kind": "robin", "tag": "rest", "h": 5.0, "ambient": 30.0}],
           "output": _out(tmp_path, vtu=False)}
    exact = run_pipeline(cfg, tmp_path)
    red = run_pipeline({**cfg, "reduce": {"degree": 2}, "output": _out(tmp_path, "r", vtu=False, exports=["stl"])},
                       tmp_path)
    # the vertical sink's box map is affine, so its T2 tiles compose at their own degree 2 (not Eq. 7's 12):
    # the reduction to degree 2 keeps them as they are
    assert red["reduction"]["deviation_m"] < 1e-12 and red["reduction"]["degrees_before"] == [[2, 2, 2]]
    assert red["tiles"] == exact["tiles"] == 20 and red["interfaces"] == exact["interfaces"]
    assert red["temperature_C"]["mean"] == pytest.approx(exact["temperature_C"]["mean"], rel=1e-10)
    assert red["flux_W"]["rest"] == pytest.approx(exact["flux_W"]["rest"], rel=1e-9)
    with pytest.raises(ProblemError, match=r"reduce\.degree: must be 2 or 3"):
        validate({**cfg, "reduce": {"degree": 1}}, tmp_path)
    with pytest.raises(ProblemError, match=r"config section reduce approximates trivariates; tile 'hollow_cross' is "
                                           r"made of surfaces"):
        validate({"map": {"primitive": "box"}, "tile": {"library": "hollow_cross"},
                  "paving": {"scheme": "regular", "counts": [1, 1, 1]}, "reduce": {"degree": 2}}, tmp_path)
    with pytest.raises(ProblemError, match=r"config section reduce needs a model of trivariates"):
        validate({"map": {"primitive": "box"}, "paving": {"scheme": "random_implicit", "counts": [2, 2, 2]},
                  "reduce": {"degree": 2}}, tmp_path)


def test_the_analysis_degree_and_extra_quadrature_are_configured(tmp_path):
    cfg = {"map": {"primitive": "box"}, "tile": {"library": "cross"}, "paving": {"scheme": "regular",
                                                                               "counts": [2, 1, 1]},
           "bc": [{"kind": "dirichlet", "tag": "umin", "value": 1.0}, {"kind": "robin", "tag": "rest", "h": 1.0,
                                                                     "ambient": 0.0}],
           "output": _out(tmp_path, vtu=False)}
    base = run_pipeline(cfg, tmp_path)
    cubic = run_pipeline({**cfg, "solver": {"degree": 3, "quadrature_extra": 1}, "output": _out(tmp_path, "c", vtu=False)},
                         tmp_path)
    assert cubic["dofs"] > base["dofs"] and np.isfinite(cubic["temperature_C"]["mean"])
    with pytest.raises(ProblemError, match=r"solver\.quadrature_extra: must be an integer >= 0"):
        validate({**cfg, "solver": {"quadrature_extra": -1}}, tmp_path)


@pytest.mark.parametrize("expression", ["A - B", "A & B", "(A | B) - B"])
def test_vrep_subtractions_and_intersections_run_as_in_python(expression, tmp_path):
    from geometry.primitives import box
    from iga.tags import parse_expression
    from tiling import library as L
    from tiling.vrep import Primitive, vrep_microstructure

    cfg = _union(tmp_path)
    cfg["paving"]["expression"] = expression
    cfg["bc"] = [{"kind": "dirichlet", "tag": "A:vmin", "value": 100.0},
                 {"kind": "robin", "tag": "rest", "h": 10.0, "ambient": 20.0}]
    s = run_pipeline(cfg, tmp_path)
    prims = {"A": Primitive(box((2.0, 1.0, 1.0), channels={"k": 205.0}), L.cross(), (4, 2, 2), 2, "A"),
             "B": Primitive(box((2.0, 1.0, 1.0), origin=(1.5, 0.0, 0.0), channels={"k": 54.0}), L.cross(), (4, 2, 2),
                            1, "B")}
    ms = vrep_microstructure(parse_expression(expression, prims.__getitem__, "primitive", "")).microstructure
    sol = HeatProblem(ms, "k").dirichlet("A:vmin", 100.0).robin("rest", 10.0, 20.0).solve(tol=1e-10)
    assert s["tiles"] == ms.n_tiles > 0 and s["connected_pieces"] == 1
    assert s["temperature_C"]["mean"] == pytest.approx(sol.mean_temperature(), rel=1e-8)


@pytest.mark.slow
def test_iga_run_reports_a_surface_or_a_lattice_of_lines(tmp_path):
    """From the command line: a polygon lattice (lines only) and a capped hollow lattice (triangles) run to their
    surface and report it in one line (20 cell edges and 4 diagonals per cell: 28 lines)."""

    (tmp_path / "lines.toml").write_text('[map]\nprimitive = "box"\n[tile]\nlibrary = "beam_lattice"\n'
                                         '[paving]\nscheme = "polygons"\ncounts = [2, 1, 1]\n[output]\npng = false\n')
    (tmp_path / "caps.toml").write_text('[map]\nprimitive = "box"\n[tile]\nlibrary = "hollow_cross"\n[paving]\n'
                                        'scheme = "regular"\ncounts = [2, 1, 1]\nseal = "cap"\n[output]\npng = false\n'
                                        'dir = "caps"\n')
    for name, want in (("lines.toml", "2 tiles (no analysis); 28 lines"), ("caps.toml", "triangles, closed")):
        out = iga_command("run", tmp_path / name)
        assert out.returncode == 0 and want in out.stdout, out.stderr
