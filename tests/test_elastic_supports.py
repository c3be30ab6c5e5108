"""Supports and loads off whole faces: a plate strip simply supported on two lines against Kirchhoff-Love, a bar
pinned at three points and pulled (the reactions carry the load), springs whose forces balance the load, a point
load whose stress is refused at its point, and the refusals of bad selections."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, ProblemError, SingularProblemError
from tiling import library

E, NU = 70e9, 0.3


@pytest.mark.parametrize("slenderness, limit", [(20, 0.01), (40, 0.003)])
def test_a_plate_strip_on_two_line_supports_bends_as_kirchhoff_love_says(slenderness, limit):
    # simply supported along its bottom edges x = 0 and x = L (held in z, one also in x), plane strain across
    # (y held on the long sides), uniform pressure q on top: w(L/2) = 5 q L^4 / (384 D), D = E t^3 / 12 (1 - nu^2)
    t, b, q = 0.01, 0.05, 1e4
    L = slenderness * t
    D = pr.refined(pr.box((L, b, t), degrees=(3, 1, 3)), (24, 1, 2))
    problem = ElasticityProblem(D, youngs=E, poisson=NU)
    problem.hold(("umin", "wmin"), components="xz", name="left").hold(("umax", "wmin"), components="z", name="right")
    problem.dirichlet("vmin | vmax", 0.0, components="y").pressure("wmax", q)
    s = problem.solve(solver="direct")
    w = -s.displacement(np.array([[L / 2, b / 2, t / 2]]))[0, 2]
    w_kl = 5 * q * L**4 / (384 * E * t**3 / (12 * (1 - NU**2)))
    # above KL by the shear deflection, (384 D / 40 kappa G t L^2) of it: 0.7% at L/t = 20, 0.17% at 40
    assert 1.0 < w / w_kl < 1 + limit
    support = s.reaction("left") + s.reaction("right")
    assert support[2] == pytest.approx(q * L * b, rel=1e-9)  # the two lines carry the whole load
    assert s.reaction("left")[2] == pytest.approx(s.reaction("right")[2], rel=1e-6)  # symmetric
    assert s.info.work.relative_error < 1e-9


def test_a_bar_pinned_at_three_corners_carries_its_axial_load_by_the_pins():
    F, L, b, t = 1000.0, 0.2, 0.02, 0.01
    D = pr.refined(pr.box((L, b, t), degrees=(2, 2, 2)), (8, 2, 2))
    problem = ElasticityProblem(D, youngs=E, poisson=NU)
    # 3-2-1: all of A, x and z of B, x of C: statically determinate, every rigid motion held
    problem.hold((0, 0, 0), name="A").hold((0, b, 0), components="xz", name="B").hold((0, 0, t), components="x",
                                                                                    name="C")
    problem.traction("umax", [F / (b * t), 0.0, 0.0])
    s = problem.solve(solver="direct")
    total = sum(s.reaction(name) for name in "ABC")
    assert np.allclose(total, [-F, 0.0, 0.0], atol=1e-9 * F)
    assert s.reaction("C")[1:] == pytest.approx([0.0, 0.0], abs=1e-9 * F)  # C holds x only
    sigma = s.stress(np.array([[L / 2, b / 2, t / 2]]))[0]
    assert sigma[0, 0] == pytest.approx(F / (b * t), rel=0.02)  # Saint-Venant: uniform away from the pins
    assert s.info.work.relative_error < 1e-9
    with pytest.raises(SingularProblemError, match="rigid-body motion"):  # one pin leaves the rotations free
        ElasticityProblem(D, youngs=E, poisson=NU).hold((0, 0, 0)).traction("umax", [1.0, 0, 0]).solve()


def test_springs_carry_the_load_and_their_work_is_in_the_balance():
    F, L, b, t, k = 1000.0, 0.2, 0.02, 0.01, 1e7
    D = pr.refined(pr.box((L, b, t), degrees=(2, 2, 2)), (8, 2, 2))
    problem = ElasticityProblem(D, youngs=E, poisson=NU)
    problem.spring(lambda x: x[:, 0] <= 1e-12, [k, 0.0, 0.0], name="bed")  # the nodes of the face x = 0
    problem.hold((0, 0, 0), components="yz").hold((0, b, 0), components="z").hold((0, 0, t), components="y")
    problem.traction("umax", [F / (b * t), 0.0, 0.0])
    s = problem.solve(solver="direct")
    bed = problem.springs[0]
    assert len(bed.dofs) == 16  # 4 x 4 control points on the face
    assert s.reaction("bed") == pytest.approx([-F, 0.0, 0.0], abs=1e-9 * F)
    # the springs' forces k u_i add up to F: their mean displacement is F / (n k), whatever its spread
    assert s.u[bed.dofs].mean() == pytest.approx(F / (16 * k), rel=1e-9)
    assert s.info.work.relative_error < 1e-9  # u . f = internal work + the springs' work u . K_s u


def test_a_point_load_is_balanced_and_its_stress_is_refused_at_its_point():
    F, L, b, t = 100.0, 0.2, 0.02, 0.01
    D = pr.refined(pr.box((L, b, t), degrees=(2, 2, 2)), (8, 2, 2))
    problem = ElasticityProblem(D, youngs=E, poisson=NU).dirichlet("umin", 0.0)
    problem.point_load((L, b / 2, t / 2), (0.0, 0.0, -F), name="tip")
    s = problem.solve(solver="direct")
    assert s.reaction("umin") == pytest.approx([0.0, 0.0, F], abs=1e-9 * F)
    assert s.info.applied_N["tip"] == [0.0, 0.0, -F] and s.info.work.relative_error < 1e-9
    away = s.stress(np.array([[L / 2, b / 2, t / 2]]))  # finite away from the point
    assert np.all(np.isfinite(away))
    # the bending moment at mid-span, F L / 2, from the stress over the section (Euler-Bernoulli: linear in z)
    sigma_top = s.stress(np.array([[L / 2, b / 2, t * 0.999]]))[0, 0, 0]
    assert sigma_top == pytest.approx(F * (L / 2) * (t / 2) / (b * t**3 / 12), rel=0.05)
    for ask in (s.stress, s.von_mises, s.strain):
        with pytest.raises(ProblemError, match="'tip'.*infinite"):
            ask(np.array([[L / 2, b / 2, t / 2], [L, b / 2, t / 2]]))


def test_line_supports_follow_patch_edges_across_a_paving():
    # a regular paving of solid cells: the bottom edges of the end faces run over several patches
    ms = tiling.regular(pr.box((0.04, 0.01, 0.01), degrees=(2, 2, 2)), library.cube(), (4, 2, 1))
    problem = ElasticityProblem(ms, youngs=E, poisson=NU)
    problem.hold(("umin", "wmin"), components="xyz", name="left").hold(("umax", "wmin"), components="yz",
                                                                      name="right")
    problem.pressure("wmax", 1e4)
    s = problem.solve(solver="direct")
    nodes = problem.nodes()[problem.holds[0].dofs]
    assert np.allclose(nodes[:, [0, 2]], 0.0, atol=1e-12) and np.ptp(nodes[:, 1]) == pytest.approx(0.01)
    total = s.reaction("left") + s.reaction("right")
    assert total == pytest.approx([0.0, 0.0, 1e4 * 0.04 * 0.01], abs=1e-8)
    assert np.abs(s.displacement(nodes)).max() < 1e-15  # the whole edge held, not only its nodes


@pytest.mark.parametrize("build, match", [
    (lambda p: p.hold(("umin", "nosuch")), "nosuch"),
    (lambda p: p.hold(((1.5, 1.5, 1.5), (2.0, 2.0, 2.0))), "holds no node.*nearest node"),
    (lambda p: p.hold((0.5, 0.5, 0.5)), "holds no node"),
    (lambda p: p.hold(lambda x: x[:, 0] < -1), "selects no node"),
    (lambda p: p.hold(lambda x: x[:, 0]), "boolean array"),
    (lambda p: p.hold("umin"), "where must be two or three face tags"),
    (lambda p: p.hold(((1, 1, 1), (0, 0, 0))), "lower one"),
    (lambda p: p.hold((0, 0, 0), components="xw"), "components"),
    (lambda p: p.spring((0, 0, 0), -5.0), "stiffness must be >= 0"),
    (lambda p: p.spring((0, 0, 0), [0.0, 0.0, 0.0]), "> 0 in one"),
    (lambda p: p.spring((0, 0, 0), "stiff"), "stiffness must be a number"),
    (lambda p: p.point_load((5.0, 5.0, 5.0), (1.0, 0.0, 0.0)), "point load 1"),
    (lambda p: p.point_load((0.5, 0.5, 0.5), (1.0, float("nan"), 0.0)), "finite"),
    (lambda p: p.hold((0, 0, 0), name="umin"), "already a tag"),
    (lambda p: p.dirichlet("umin").hold((0, 0, 0), components="x").solve(), "already prescribed"),
])
def test_bad_supports_and_point_loads_are_refused_naming_them(build, match):
    problem = ElasticityProblem(pr.refined(pr.box(degrees=(2, 2, 2)), (2, 2, 2)), youngs=1.0, poisson=0.3)
    with pytest.raises(ProblemError, match=match):
        build(problem)


def test_a_pipeline_holds_an_edge_springs_a_corner_and_takes_a_point_load(tmp_path):
    from iga.app.pipeline import run_pipeline

    F = 50.0
    cfg = {"map": {"primitive": "box", "args": {"size": [0.1, 0.02, 0.01]}}, "tile": {"library": "cube"},
           "paving": {"scheme": "regular", "counts": [4, 1, 1]},
           "physics": {"kind": "elasticity", "youngs": 70e9, "poisson": 0.3},
           "support": [{"edge": ["umin", "wmin"], "name": "hinge"},
                       {"corner": ["umax", "vmin", "wmin"], "components": "z", "stiffness": 1e6, "name": "pad"},
                       {"corner": ["umax", "vmax", "wmin"], "components": "z", "stiffness": 1e6}],
           "load": [{"kind": "point", "point": [0.05, 0.01, 0.01], "value": [0.0, 0.0, -F]}],
           "output": {"dir": str(tmp_path), "name": "plate", "png": False}}
    s = run_pipeline(cfg, tmp_path)["elasticity"]
    reactions = s["reactions_N"]
    assert set(reactions) == {"hinge", "pad", "support[2]"}
    total = np.sum([reactions[k] for k in reactions], axis=0)
    assert total == pytest.approx([0.0, 0.0, F], abs=1e-8 * F)  # hinge and pads carry the point force
    assert reactions["pad"][2] == pytest.approx(reactions["support[2]"][2], rel=1e-6)  # symmetric pads
    assert reactions["pad"][2] == pytest.approx(F / 4, rel=0.05)  # the lever: half the load, shared by two pads
    assert "grows under refinement" in s["max_von_mises_note"] and s["work"]["relative_error"] < 1e-9
    for bad, match in (({"edge": ["umin"]}, r"support\[0\]\.edge: must be a list of 2 face tags"),
                       ({"tag": "umin", "stiffness": 1.0}, r"support\[0\]\.stiffness: springs go on nodes"),
                       ({"point": [0, 0, 0], "box": [[0, 0, 0], [1, 1, 1]]}, "exactly one of"),
                       ({"corner": ["umin", "vmin", "wmin"], "stiffness": 1.0, "value": 0.0}, "not both")):
        with pytest.raises(ProblemError, match=match):
            run_pipeline({**cfg, "support": [bad]}, tmp_path)
