"""More of the Python API from a pipeline: the bifurcation scheme and the shape maps."""

import json

import numpy as np
import pytest

from iga.app.config import validate
from iga.errors import ProblemError
from iga.app.pipeline import run_pipeline


def _bif(**paving):
    return {"map": {"primitive": "duck"}, "paving": {"scheme": "bifurcation", **paving},
            "material": {"conductivity": 20.0},
            "bc": [{"kind": "dirichlet", "tag": "wmin", "value": 100.0},
                   {"kind": "robin", "tag": "rest", "h": 10.0, "ambient": 20.0}],
            "output": {"png": False, "vtu": False}}


def test_a_bifurcation_tiling_of_the_duck_runs_from_a_pipeline(tmp_path):
    cfg = _bif(epsilon=0.35, kind="1-2")
    cfg["output"]["dir"] = str(tmp_path / "o")
    s = run_pipeline(cfg, tmp_path)
    assert s["levels"] >= 2 and s["tiles"] > 20 and s["connected_pieces"] == 1
    assert s["energy_balance_error"] < 1e-9 and s["temperature_C"]["max"] <= 100.0 + 1e-6
    cfg = _bif(levels=[0, 0, 1, 1, 0, 0], kind="1-4a")
    cfg["map"] = {"primitive": "box", "args": {"size": [1.0, 1.0, 6.0]}}
    cfg["output"]["dir"] = str(tmp_path / "p")
    assert run_pipeline(cfg, tmp_path)["tiles"] == 12


@pytest.mark.parametrize("change, match", [
    (lambda c: c.update(tile={"library": "cross"}), r"config section tile does not apply to the bifurcation scheme"),
    (lambda c: c["paving"].update(counts=[2, 2, 2]), r"paving\.counts: does not apply to the bifurcation scheme"),
    (lambda c: c["paving"].update(levels=[0, 1]), r"needs exactly one of 'epsilon' .* or 'levels'"),
    (lambda c: c["paving"].update(kind="1-3"), r"paving\.kind: must be one of"),
    (lambda c: c["paving"].update(direction=3), r"paving\.direction: must be 0, 1 or 2"),
    (lambda c: c["paving"].update(epsilon=-1.0), r"paving\.epsilon"),
    (lambda c: c["map"].update(primitive="swan"), r"map\.primitive: must be one of .*'duck'"),
])
def test_bad_bifurcation_pipelines_are_refused_before_any_work(change, match, tmp_path):
    cfg = _bif(epsilon=0.35)
    change(cfg)
    with pytest.raises(ProblemError, match=match):
        validate(cfg, tmp_path)


def test_regular_pavings_still_need_their_counts_and_refuse_bifurcation_keys():
    cfg = _bif(epsilon=0.35)
    cfg["paving"] = {"scheme": "regular", "epsilon": 0.3}
    cfg["tile"] = {"library": "cross"}
    with pytest.raises(ProblemError, match=r"paving\.epsilon: applies to the bifurcation and implicit_bifurcation schemes only"):
        validate(cfg)
    cfg["paving"] = {"scheme": "regular"}
    with pytest.raises(ProblemError, match=r"paving \(scheme 'regular'\) needs 'counts'"):
        validate(cfg)


def test_exports_by_name_are_written_and_read_back(tmp_path):
    import warnings

    import meshio

    from geometry.io.gismo import read_gismo
    from iga.io.describe import describe

    cfg = {"map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0]}}, "tile": {"library": "cross"},
           "paving": {"scheme": "regular", "counts": [2, 1, 1]}, "material": {"conductivity": 5.0},
           "bc": [{"kind": "dirichlet", "tag": "umin", "value": 1.0}, {"kind": "robin", "tag": "rest", "h": 2.0,
                                                                     "ambient": 0.0}],
           "output": {"dir": str(tmp_path / "o"), "png": False, "vtu": False, "exports": ["stl", "iges", "gismo"]}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a regular paving says everything in G+Smo's own terms: no extension
        s = run_pipeline(cfg, tmp_path)
    assert set(s["files"]) == {"stl", "iges", "gismo"}
    assert len(meshio.read(s["files"]["stl"]).cells_dict["triangle"]) > 100
    assert "B-spline surfaces" in describe(__import__("pathlib").Path(s["files"]["iges"]))[0]
    assert len(read_gismo(s["files"]["gismo"]).patches) == 14
    gmsh = pytest.importorskip("gmsh")  # the second readers: OpenCASCADE for the IGES, G+Smo for the XML
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Geometry.OCCImportLabels", 0)
        gmsh.model.occ.importShapes(s["files"]["iges"])
        gmsh.model.occ.synchronize()
        n_iges = len(gmsh.model.getEntities(2))
    finally:
        gmsh.finalize()
    assert n_iges == int(describe(__import__("pathlib").Path(s["files"]["iges"]))[0].split("IGES, ")[1].split()[0])
    gs = pytest.importorskip("pygismo")
    mp = gs.core.gsMultiPatch()
    assert gs.io.gsFileData(s["files"]["gismo"]).getFirst(mp) and mp.nPatches() == 14
    cfg["output"]["exports"] = ["step"]
    with pytest.raises(ProblemError, match=r"output\.exports: must be a list of distinct names from"):
        validate(cfg, tmp_path)


def test_a_random_implicit_structure_runs_to_its_surface_and_refuses_an_analysis(tmp_path):
    import meshio

    cfg = {"map": {"primitive": "box"}, "paving": {"scheme": "random_implicit", "counts": [2, 2, 2], "cap": True,
                                                   "resolution": 6},
           "output": {"dir": str(tmp_path / "o"), "png": False, "exports": ["stl"]}}
    s = run_pipeline(cfg, tmp_path)
    assert s["surface"]["closed"] and s["surface"]["components"] == 1 and set(s["files"]) == {"vtp", "stl"}
    assert len(meshio.read(s["files"]["stl"]).cells_dict["triangle"]) == s["surface"]["triangles"]
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["certificate"]["certified"] is True and summary["certificate"]["boxes"] == 20 ** 3  # 2 boxes per span, 5 spans per cell
    heat = {**cfg, "bc": [{"kind": "dirichlet", "tag": "wmin", "value": 1.0}]}
    with pytest.raises(ProblemError, match=r"is a surface .* not a volumetric B-spline model"):
        validate(heat, tmp_path)
    iges = {**cfg, "output": {**cfg["output"], "exports": ["iges"]}}
    with pytest.raises(ProblemError, match=r"output\.exports: a random implicit structure is a triangulated surface"):
        validate(iges, tmp_path)
    with pytest.raises(ProblemError, match=r"paving\.alpha"):
        validate({**cfg, "paving": {**cfg["paving"], "alpha": 2.0}}, tmp_path)


def test_a_model_without_analysis_writes_its_geometry(tmp_path):
    import pyvista as pv

    cfg = {"map": {"primitive": "box"}, "tile": {"library": "cross"}, "paving": {"scheme": "regular", "counts": [2, 1, 1]},
           "physics": {"kind": "none"}, "output": {"dir": str(tmp_path / "o"), "png": False, "exports": ["iges"]}}
    s = run_pipeline(cfg, tmp_path)
    assert set(s["files"]) == {"iges", "vtu"} and pv.read(s["files"]["vtu"]).n_cells > 0 and "temperature_C" not in s
    with pytest.raises(ProblemError, match=r"config section bc needs an analysis"):
        validate({**cfg, "bc": [{"kind": "dirichlet", "tag": "umin", "value": 1.0}]}, tmp_path)
    with pytest.raises(ProblemError, match=r"'gismo' writes the heat problem"):
        validate({**cfg, "output": {**cfg["output"], "exports": ["gismo"]}}, tmp_path)


def test_an_implicit_bifurcation_of_the_duck_runs_to_a_closed_surface(tmp_path):
    cfg = {"map": {"primitive": "duck"}, "paving": {"scheme": "implicit_bifurcation", "epsilon": 0.5},
           "output": {"dir": str(tmp_path / "o"), "png": False, "vtu": False, "exports": ["ply"]}}
    s = run_pipeline(cfg, tmp_path)
    assert s["surface"]["closed"] and s["surface"]["components"] == 1 and s["tiles"] > 10 and set(s["files"]) == {"ply"}
    import meshio

    assert len(meshio.read(s["files"]["ply"]).cells_dict["triangle"]) == s["surface"]["triangles"]
    with pytest.raises(ProblemError, match=r"the implicit bifurcation structure is a surface"):
        validate({**cfg, "physics": {"kind": "heat"}, "bc": [{"kind": "dirichlet", "tag": "wmin", "value": 1.0}]})
    with pytest.raises(ProblemError, match=r"needs 'epsilon'"):
        validate({**cfg, "paving": {"scheme": "implicit_bifurcation"}})


def test_a_heat_sink_graded_by_its_pins_runs_from_a_pipeline(tmp_path):
    """The vertical demo map paved by the heat-sink family with pins widening along x: the pipeline paves 16
    tiles glued by the cell grid's 24 identities, as the script does with the same field, whose widths on the u
    walls grow with x from the formula's value at one end of the sink to its value at the other."""
    cfg = {"map": {"primitive": "vertical_heat_sink"}, "tile": {"library": "face_graded_heat_sink"},
           "paving": {"scheme": "field_graded", "counts": [4, 4, 1], "field": {"formula": "0.3 + 2 * x"}},
           "material": {"conductivity": 205.0},
           "bc": [{"kind": "neumann", "tag": "wmin", "value": 2e4}, {"kind": "robin", "tag": "rest", "h": 3000.0,
                                                                       "ambient": 0.0}],
           "output": {"dir": str(tmp_path), "png": False}}
    s = run_pipeline(cfg, tmp_path)
    import tiling
    from iga.app.maps import vertical_heat_sink_map
    from tiling import library

    D = vertical_heat_sink_map()
    lo, hi = D.control_points[..., 0].min(), D.control_points[..., 0].max()
    ms = tiling.field_graded(D, library.face_graded_heat_sink, (4, 4, 1),
                             lambda u: 0.3 + 2 * D.evaluate(u)[:, 0])  # x at the wall centres (D's domain: [0, 1]^3)
    assert s["tiles"] == 16 and s["interfaces"] == len(ms.interfaces) == 24 and s["energy_balance_error"] < 1e-9
    umin = ms.grading.faces[0][:, 0, 0]
    assert np.all(np.diff(umin) > 0)
    assert abs(umin[0] - (0.3 + 2 * lo)) < 1e-12 and abs(umin[-1] - (0.3 + 2 * hi)) < 1e-12


def test_a_field_graded_lattice_runs_from_a_pipeline_with_a_formula_of_the_position(tmp_path):
    cfg = {"map": {"primitive": "box", "args": {"size": [0.03, 0.02, 0.02]}}, "tile": {"library": "face_graded_cross"},
           "paving": {"scheme": "field_graded", "counts": [3, 2, 2], "field": {"formula": "0.15 + 10 * x"}},
           "material": {"conductivity": 205.0},
           "bc": [{"kind": "dirichlet", "tag": "umin", "value": 50.0}, {"kind": "robin", "tag": "rest", "h": 10.0,
                                                                         "ambient": 20.0}],
           "output": {"dir": str(tmp_path), "png": False}}
    s = run_pipeline(cfg, tmp_path)
    assert s["tiles"] == 12 and s["connected_pieces"] == 1 and s["energy_balance_error"] < 1e-9
    import tiling
    from geometry import primitives
    from tiling import library

    ms = tiling.field_graded(primitives.box((0.03, 0.02, 0.02)), library.face_graded_cross, (3, 2, 2),
                             lambda u: 0.15 + 10 * 0.03 * u[:, 0])  # x = 0.03 u on this map
    assert s["interfaces"] == len(ms.interfaces)
    for bad, match in ((dict(cfg, tile={"library": "cross"}), r"tile\.library: the field_graded scheme needs"),
                       (dict(cfg, tile={"library": "face_graded_cross", "args": {"umin": 0.2}}), r"tile\.args"),
                       (dict(cfg, paving={"scheme": "field_graded", "counts": [3, 2, 2]}), "needs 'field'"),
                       (dict(cfg, paving={"scheme": "field_graded", "counts": [3, 2, 2], "field": 1.5}),
                        r"paving\.field: must be < 1")):
        with pytest.raises(ProblemError, match=match):
            validate(bad, tmp_path)
