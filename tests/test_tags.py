"""Tag algebra: unions, intersections, differences, lists, 'rest', and clashes that name both tags."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import HeatProblem
from iga.errors import ProblemError
from iga.model import as_model, tag_faces
from iga.app.pipeline import run_pipeline
from tiling import library as L


def _lattice():
    return tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))


def test_expressions_combine_tags_as_sets():
    ms = as_model(_lattice())
    t = {k: set(v) for k, v in ms.tags.items()}
    assert set(tag_faces(ms, "umin | umax")) == t["umin"] | t["umax"]
    assert set(tag_faces(ms, ["umin", "umax"])) == t["umin"] | t["umax"]
    assert set(tag_faces(ms, "boundary - umin")) == t["boundary"] - t["umin"]
    assert set(tag_faces(ms, "boundary - (umin | vmin) & boundary")) == t["boundary"] - (t["umin"] | (t["vmin"] & t["boundary"]))
    assert set(tag_faces(ms, "(boundary - umin) & (umin | umax)")) == t["umax"]
    assert set(tag_faces(ms, "branch-in")) == t["branch-in"]  # a hyphen inside a name is the name
    for bad, match in (("umin |", "ends where a tag is expected"), ("(umin | umax", "parenthesis is not closed"),
                       ("umin) | umax", "is left over"), ("nowhere - umin", "unknown boundary tag 'nowhere'"),
                       ("rest", "only names faces in a problem's boundary condition"), ([], "non-empty string")):
        with pytest.raises(ProblemError, match=match):
            tag_faces(ms, bad)


def test_dirichlet_on_one_face_and_robin_on_the_rest_is_one_line():
    ms = _lattice()
    a = HeatProblem(ms, conductivity=5.0).dirichlet("umin", 80.0).robin("rest", 10.0, 25.0).solve()
    b = HeatProblem(ms, conductivity=5.0).dirichlet("umin", 80.0).robin("boundary - umin", 10.0, 25.0).solve()
    assert np.array_equal(a.u, b.u)
    rest = set(ms.tags["boundary"]) - set(ms.tags["umin"])
    assert set(a.problem.tag_faces("rest")) == rest and a.info["balance"]["relative_error"] < 1e-9
    assert a.flux("rest") == pytest.approx(-a.flux("umin"), rel=1e-9)


def test_a_clash_names_both_tags_and_the_way_out():
    p = HeatProblem(_lattice()).dirichlet("umin", 80.0).robin("boundary", 10.0, 25.0)
    with pytest.raises(ProblemError, match=r"Dirichlet condition \(tag 'umin'\) and a robin condition \(tag "
                                           r"'boundary'\); .* on 'boundary - umin' or on 'rest'"):
        p.solve()


def test_a_pipeline_takes_lists_expressions_and_rest(tmp_path):
    cfg = {"map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0]}}, "tile": {"library": "cross"},
           "paving": {"scheme": "regular", "counts": [2, 1, 1]}, "material": {"conductivity": 5.0},
           "bc": [{"kind": "dirichlet", "tag": ["umin", "vmin"], "value": 80.0},
                  {"kind": "robin", "tag": "rest", "h": 10.0, "ambient": 25.0}],
           "output": {"dir": str(tmp_path / "o"), "vtu": False, "png": False}}
    s = run_pipeline(cfg, tmp_path)
    assert set(s["flux_W"]) == {"umin | vmin", "rest"}
    assert s["flux_W"]["rest"] == pytest.approx(-s["flux_W"]["umin | vmin"], rel=1e-8)


def test_an_elastic_problem_takes_rest_too():
    from iga import ElasticityProblem

    ms = _lattice()
    a = ElasticityProblem(ms, youngs=1e3, poisson=0.3).dirichlet("umin", 0.0).pressure("rest", 1.0).solve()
    b = ElasticityProblem(ms, youngs=1e3, poisson=0.3).dirichlet("umin", 0.0).pressure("boundary - umin", 1.0).solve()
    assert np.array_equal(a.u, b.u) and a.info["work"]["relative_error"] < 1e-9
    # a closed surface under uniform pressure has no resultant, so the pressure on the rest pushes the body
    # towards -x with p times the clamped area: the clamp holds it with the opposite force
    area = sum(fd.dAw.sum() for fd in a.problem.faces(ms.tags["umin"]))
    assert np.allclose(a.reaction("umin"), [1.0 * area, 0.0, 0.0], rtol=1e-9, atol=1e-12)
