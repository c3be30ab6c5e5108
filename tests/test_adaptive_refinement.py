"""Refinement by tiles: octrees of patches glued by refinement matrices, the residual estimate, the adaptive loop."""

import meshio
import numpy as np
import pytest
from commands import iga_command

import iga
import tiling
from geometry import primitives as pr
from geometry.patches.multipatch import MultiPatch
from iga.adaptivity.estimator import estimate_error
from iga.adaptivity.loop import AdaptiveStep, adaptive_solve, dorfler
from iga.adaptivity.tree import TileRefinement
from iga.errors import ProblemError
from tiling import library as L



def _linear(x):
    return 1.0 + 2.0 * x[:, 0] - 3.0 * x[:, 1] + 0.5 * x[:, 2]


def _lshape(elements=(2, 2, 2)):
    """[-1, 1]^2 without the quadrant x > 0, y < 0, times [0, 1]: three box patches, re-entrant edge along z."""
    return [pr.box((1, 1, 1), (x, y, 0), degrees=(2, 2, 2), elements=elements) for x, y in ((-1, -1), (-1, 0), (0, 0))]


def _corner(x):
    """r^(2/3) sin(2 theta / 3): harmonic, zero on the two faces of the re-entrant edge."""
    r, th = np.hypot(x[:, 0], x[:, 1]), np.mod(np.arctan2(x[:, 1], x[:, 0]), 2 * np.pi)
    return r ** (2 / 3) * np.sin(2 * th / 3)


def _corner_gradient(x):
    r, th = np.hypot(x[:, 0], x[:, 1]), np.mod(np.arctan2(x[:, 1], x[:, 0]), 2 * np.pi)
    dr, dth = (2 / 3) * r ** (-1 / 3) * np.sin(2 * th / 3), (2 / 3) * r ** (-1 / 3) * np.cos(2 * th / 3)
    return np.stack([dr * np.cos(th) - dth * np.sin(th), dr * np.sin(th) + dth * np.cos(th), 0 * r], axis=1)


def _points_in(model, n, seed):
    """n random physical points inside every patch of a model (images of random parameters)."""
    rng = np.random.default_rng(seed)
    out = []
    for p in model.patches:
        dom = p.spline.domain
        out.append(p.image(dom[:, 0] + rng.random((n, 3)) * np.ptp(dom, axis=1)))
    return np.concatenate(out)


def _exact_linear(model, **conditions):
    problem = iga.HeatProblem(model, conductivity=2.0)
    for tag in conditions.get("dirichlet", ("boundary",)):
        problem.dirichlet(tag, _linear)
    for tag, flux in conditions.get("neumann", {}).items():
        problem.neumann(tag, flux)
    s = problem.solve()
    x = _points_in(model, 6, 1)
    return np.abs(s.probe(x) - _linear(x)).max(), s


def test_patches_of_different_levels_carry_a_linear_field_exactly():
    # split one root, then a child at the re-entrant edge, then a corner of a third root: levels 0, 1 and 2 meet,
    # children next to coarser neighbours across the roots' faces and inside their own root
    tree = TileRefinement(_lshape()).refined([1])
    at_edge = [i for i in range(len(tree.leaves)) if tree.leaves.root[i] == 1 and tree.leaves.index[i, 0] == 1
               and tree.leaves.index[i, 1] == 0]
    tree = tree.refined(at_edge[:1]).refined([0])
    model = tree.model()
    assert sorted(set(tree.leaves.level.tolist())) == [0, 1, 2]
    assert any(i.kind == "branch" for i in model.interfaces)
    # Dirichlet below, the linear field's own flux k grad T . n = 2 * 0.5 on top (z = 1)
    err, s = _exact_linear(model, dirichlet=("boundary - wmax",), neumann={"wmax": 1.0})
    assert err < 1e-9
    # the middle root was split while its two neighbours only touch each other along the edge: the children tie them
    assert s.info.constraints["implied_conditions"] > 0
    # the volume and the tagged areas are those of the unrefined model
    assert s.volume() == pytest.approx(3.0, rel=1e-12)


def test_patches_of_different_degrees_and_levels_carry_a_linear_field_exactly():
    # p on one root, h on another, p again on a child: degrees 2, 3 and 4 meet levels 0 and 1 (degree-elevation and
    # refinement matrices across equal and nested faces)
    tree = TileRefinement(_lshape()).refined([1], "p").refined([0]).refined([0, 3], "p")
    model = tree.model()
    degrees = sorted({p.spline.degrees[0] for p in model.patches})
    assert degrees == [2, 3, 4] and sorted(set(tree.leaves.level.tolist())) == [0, 1]
    assert any(i.kind == "branch" for i in model.interfaces)
    err, s = _exact_linear(model, dirichlet=("boundary - wmax",), neumann={"wmax": 1.0})
    assert err < 1e-9
    assert s.volume() == pytest.approx(3.0, rel=1e-12)


def test_p_and_hp_refinement_reach_a_smooth_solution_with_fewer_unknowns_than_h():
    # a harmonic field, smooth everywhere: raising degrees converges faster per unknown than splitting
    def smooth(x):
        return np.sin(np.pi * x[:, 0] / 2) * np.sinh(np.pi * x[:, 1] / 2)

    def smooth_gradient(x):
        a, b = np.pi * x[:, 0] / 2, np.pi * x[:, 1] / 2
        return np.pi / 2 * np.stack([np.cos(a) * np.sinh(b), np.sin(a) * np.cosh(b), 0 * a], axis=1)

    def run(how, **budget):
        problem = iga.HeatProblem(_lshape((1, 1, 1))).dirichlet("boundary", smooth)
        result = adaptive_solve(problem, 2e-3, refine=how, exact_gradient=smooth_gradient, max_steps=10, **budget)
        assert all(0.3 <= h.effectivity <= 3.0 for h in result.history)
        return result

    p = run("p")
    assert p.reached and p.history[-1].relative <= 2e-3
    assert {q.spline.degrees[0] for q in p.solution.problem.model.patches} != {2}  # degrees were raised
    h = run("h", max_unknowns=5 * p.history[-1].unknowns)
    # at five times the unknowns, splitting is still less accurate than raising the degree
    assert h.history[-1].error > p.history[-1].error, (h.history[-1], p.history[-1])
    # hp: split first (no prediction yet), then raise the degree where the error fell as predicted
    both = run("hp")
    assert both.reached and both.history[-1].unknowns <= 2 * h.history[-1].unknowns
    assert both.history[-1].error < 0.2 * h.history[-1].error  # at about the unknowns of h, a fifth of its error
    degrees = {q.spline.degrees[0] for q in both.solution.problem.model.patches}
    assert len(both.solution.problem.model.patches) > 3 and max(degrees) > 2


def test_split_patches_follow_the_orientation_of_a_rotated_neighbour():
    a = pr.box((1, 1, 1), (0, 0, 0), degrees=(2, 2, 2), elements=(2, 2, 2))
    b = pr.box((1, 1, 1), (1, 0, 0), degrees=(2, 2, 2), elements=(2, 2, 2)).swap(1, 2).reverse(1)
    model = MultiPatch.from_splines([a, b])
    assert model.interfaces[0].swap or any(model.interfaces[0].flip)
    tree = TileRefinement(model).refined([1]).refined([2, 5])
    err, _ = _exact_linear(tree.model())
    assert err < 1e-9
    # the estimate of a harmonic quadratic, which every level represents, is zero: both sides of every glued face
    # are evaluated at the same points
    s = iga.HeatProblem(tree.model()).dirichlet("boundary", lambda x: x[:, 0] ** 2 - x[:, 2] ** 2).solve()
    assert estimate_error(s).total < 1e-9
    # the sampled VTU welds across the oriented branch faces: its outer surface is the 2 x 1 x 1 box's alone
    from iga.io.vtu import sampled_grid

    grid = sampled_grid(tree.model(), s, samples=2)
    assert grid.volume == pytest.approx(2.0, rel=1e-12)
    assert grid.extract_surface(algorithm="dataset_surface").area == pytest.approx(10.0, rel=1e-12)


def test_refining_a_branch_parent_splits_its_children_until_their_faces_nest():
    G = pr.box(degrees=(2, 2, 2))
    P = pr.box(origin=(0, 0, 1), degrees=(2, 2, 2), elements=(2, 2, 2))
    C = pr.box(origin=(1, 0, 1), degrees=(2, 2, 2), elements=(4, 4, 4))
    full = ((0.0, 1.0), (0.0, 1.0))
    model = MultiPatch.from_splines([G, P, C], branches=[((0, "wmax"), full, (1, "wmin")),
                                                         ((1, "umax"), full, (2, "umin"))])
    tree = TileRefinement(model).refined([0]).refined([0])
    # G split twice at one corner: P's face would meet several pieces of G, so P was split, and so on to C
    assert (tree.leaves.depth[tree.leaves.root == 1] > 0).all()
    err, _ = _exact_linear(tree.model())
    assert err < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("seal", [None, "cap"])
def test_a_hierarchical_heat_sink_refined_in_place_and_split_keeps_a_linear_field(seal, tmp_path):
    sink = tiling.hierarchical(pr.box(degrees=(2, 2, 2)), L.heat_sink_t2(), (1, 1) if seal else (2, 2), 2, seal=seal,
                               seal_sides=("wmin",) if seal else None)
    tree = TileRefinement(sink)
    # the tiles have discontinuity planes (slots): bisected in place; the seal plates are split
    planes = np.array([any((np.unique(U, return_counts=True)[1][1:-1] > p).any() for U, p in
                           zip(q.spline.knots, q.spline.degrees)) for q in sink.patches])
    assert (tree.splittable == ~planes).all() and tree.splittable.any() == (seal is not None)
    rng = np.random.default_rng(2)
    marked = np.r_[rng.choice(np.flatnonzero(planes), 4, replace=False),
                   rng.choice(np.flatnonzero(~planes), 2, replace=False) if seal else []].astype(int)
    refined = tree.refined(marked)
    assert (refined.leaves.depth > 0).any() == (seal is not None)
    model = refined.model()
    assert isinstance(model, tiling.Microstructure) and refined.leaves.level.max() >= 1
    err, s = _exact_linear(model)
    assert err < 1e-9
    # every level and refinement is written to the VTU as cell data
    iga.write_vtu(tmp_path / "sink.vtu", s)
    mesh = meshio.read(tmp_path / "sink.vtu")
    refinement = np.concatenate([c for c in mesh.cell_data["refinement"]])
    assert refinement.max() == refined.leaves.level.max() and refinement.min() == 0


def test_the_estimate_vanishes_for_a_field_in_the_space_and_tracks_the_error_of_a_smooth_one():
    quad = iga.HeatProblem(TileRefinement(_lshape()).refined([0]).model()).dirichlet(
        "boundary", lambda x: x[:, 0] ** 2 - x[:, 1] ** 2).solve()
    assert estimate_error(quad).total < 1e-10
    exact = lambda x: np.exp(x[:, 0]) * np.sin(x[:, 1])  # noqa: E731
    grad = lambda x: np.stack([exact(x), np.exp(x[:, 0]) * np.cos(x[:, 1]), 0 * x[:, 0]], axis=1)  # noqa: E731
    ratios = []
    for n in (1, 2, 4):
        s = iga.HeatProblem(_lshape((n, n, n))).dirichlet("boundary", exact).solve()
        ratios.append(estimate_error(s).total / s.h1_error(grad))
    assert all(0.3 <= r <= 3 for r in ratios)
    assert max(ratios) / min(ratios) < 1.3  # the estimate falls at the error's rate


def test_a_graded_channel_conductivity_enters_the_residual_through_its_gradient():
    # -(k T')' = 0 with k = 1 + x along a bar: T = ln(1 + x) / ln 2; the channel's gradient is exact
    bar = pr.box(degrees=(2, 1, 1), elements=(4, 1, 1))
    cp = bar.control_points
    graded = bar.with_channel("k", 1.0 + cp[..., 0])
    exact = lambda x: np.log1p(x[:, 0]) / np.log(2)  # noqa: E731
    grad = lambda x: np.stack([1 / ((1 + x[:, 0]) * np.log(2)), 0 * x[:, 0], 0 * x[:, 0]], axis=1)  # noqa: E731
    ratios = []
    for r in (0, 1, 2):
        s = iga.HeatProblem(graded, conductivity="k", refine=r).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
        x = np.random.default_rng(r).random((20, 3))
        assert np.abs(s.probe(x) - exact(x)).max() < 1e-3  # the problem is the one whose solution is known
        err = np.sqrt(s.integrate(lambda x, T, g: (1 + x[:, 0]) * np.sum((g - grad(x)) ** 2, axis=1)))
        ratios.append(estimate_error(s).total / err)
    assert all(0.3 <= r <= 3 for r in ratios)
    varying = iga.HeatProblem(bar, conductivity=lambda x: 1.0 + x[:, 0]).dirichlet("umin", 0.0).dirichlet("umax", 1.0)
    with pytest.raises(ProblemError, match="gradient of the conductivity"):
        estimate_error(varying.solve())


@pytest.mark.slow
def test_the_adaptive_loop_refines_towards_the_re_entrant_edge_with_a_trustworthy_estimate():
    problem = iga.HeatProblem(_lshape()).dirichlet("boundary", _corner)
    result = adaptive_solve(problem, 1e-3, max_unknowns=6000, exact_gradient=_corner_gradient)
    h = result.history
    assert not result.reached and "6,000" in result.reason
    assert all(isinstance(s, AdaptiveStep) for s in h) and len(h) >= 5
    assert all(0.3 <= s.effectivity <= 3 for s in h)
    assert h[-1].error < 0.5 * h[0].error and h[-1].unknowns <= 6000 <= 3 * h[-1].unknowns  # the budget is used
    # refined where the solution is singular: patches near the edge x = y = 0 are finer than those far from it
    model = result.model
    centre = np.array([np.hypot(*p.image(p.spline.domain.mean(axis=1)[None])[0, :2]) for p in model.patches])
    levels = np.array([p.refinement for p in model.patches])
    assert levels[centre < 0.3].mean() >= levels[centre > 0.7].mean() + 1
    assert levels[centre < 0.3].min() >= 2
    assert result.solution.problem.model is model


def test_dorfler_marks_the_fewest_largest_indicators():
    eta = np.array([0.1, 4.0, 0.3, 3.0, 2.0])
    assert dorfler(eta, 0.5).tolist() == [1, 3]  # 7 >= 0.5 x 9.4 needs the two largest
    assert dorfler(eta, 1.0).tolist() == [0, 1, 2, 3, 4]
    assert dorfler(np.zeros(3), 0.5).tolist() == []


@pytest.mark.parametrize("kwargs, match", [
    ({"tolerance": 0.0}, "tolerance must be a positive number"),
    ({"tolerance": float("nan")}, "tolerance must be a positive number"),
    ({"tolerance": 1e-3, "marking": 0.0}, r"marking must lie in \(0, 1\]"),
    ({"tolerance": 1e-3, "marking": 1.5}, r"marking must lie in \(0, 1\]"),
    ({"tolerance": 1e-3, "max_unknowns": 10}, "already has 32 unknowns, more than max_unknowns = 10"),
    ({"tolerance": 1e-3, "refine": "hq"}, "refine must be 'h'"),
    ({"tolerance": 1e-3, "max_steps": 0}, "max_steps must be an integer >= 1"),
    ({"tolerance": 1e-3, "refine": "p", "degree": 3}, "fixes every patch's degree"),
])
def test_bad_adaptive_input_is_refused_naming_it(kwargs, match):
    degree = kwargs.pop("degree", None)
    problem = iga.HeatProblem(_lshape(), degree=degree).dirichlet("boundary", _corner)
    with pytest.raises(ProblemError, match=match):
        adaptive_solve(problem, **kwargs)


def test_a_loop_that_cannot_reach_its_tolerance_returns_its_best_solution_and_says_why():
    problem = iga.HeatProblem(_lshape()).dirichlet("boundary", _corner)
    result = adaptive_solve(problem, 1e-8, max_unknowns=700)
    assert not result.reached and ("max_unknowns = 700" in result.reason or "budget of 700" in result.reason)
    assert result.estimate.relative == pytest.approx(result.history[-1].relative)
    assert result.solution.info.free_dofs == result.history[-1].unknowns
    solution, history = result  # the (solution, history) of the API contract
    assert solution is result.solution and history == result.history


SINK = """
[map]
primitive = "circular_heat_sink"
args = {r_in = 0.02, r_out = 0.05, height = 0.02, twist = 0.0}
grading = {channel = "k", near = 205.0, far = 54.0, face = "wmin"}

[tile]
library = "heat_sink_t1"

[paving]
scheme = "hierarchical"
counts = [1, 1]
levels = 2

[material]
conductivity = "k"

[[bc]]
kind = "neumann"
tag = "branch-in"
value = 1515.8

[[bc]]
kind = "robin"
tag = "exterior"
h = 5.0
ambient = 30.0

[adapt]
tolerance = 1e-3
max_unknowns = 20000

[output]
dir = "out"
name = "sink"
png = false
"""


@pytest.mark.slow
def test_a_pipeline_adapts_a_graded_heat_sink_and_reports_every_step(tmp_path):
    import json

    (tmp_path / "sink.toml").write_text(SINK)
    done = iga_command("run", tmp_path / "sink.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    a = summary["adapt"]
    steps = a["steps"]
    # the tiles have discontinuity planes: refined in place, the estimate falls step by step until the budget
    assert len(steps) >= 2 and not a["reached"] and "20,000" in a["reason"]
    assert all(s1["relative"] < s0["relative"] for s0, s1 in zip(steps, steps[1:]))
    assert summary["unknowns"] == steps[-1]["unknowns"] and abs(summary["energy_balance_error"]) < 1e-9
    mesh = meshio.read(tmp_path / "out" / "sink.vtu")
    assert np.concatenate(mesh.cell_data["refinement"]).max() == len(steps) - 1


@pytest.mark.parametrize("change, match", [
    ({"adapt": {"tolerance": 0}}, "adapt.tolerance: must be > 0"),
    ({"adapt": {"tolerance": 1e-3, "marking": 1.5}}, r"adapt.marking: must lie in \(0, 1\]"),
    ({"adapt": {"tolerance": 1e-3, "refine": "q"}}, "adapt.refine: must be one of"),
    ({"adapt": {"tolerance": 1e-3, "budget": 3}}, "budget"),
    ({"adapt": {"marking": 0.5}}, "tolerance"),
    ({"physics": {"kind": "transient-heat"}, "time": {"end": 10.0, "step": 1.0}}, "adapt refines a steady heat "
     "analysis"),
])
def test_a_bad_adapt_section_is_refused_naming_the_key(change, match):
    import tomllib

    from iga.app.config import validate

    cfg = tomllib.loads(SINK)
    cfg.update(change)
    if "physics" in change:
        cfg["material"]["capacity"] = 2.4e6
    with pytest.raises(ProblemError, match=match):
        validate(cfg)


def test_the_box_map_shortcut_of_the_estimate_equals_the_general_chain_rule(monkeypatch):
    import iga.adaptivity.estimator as est

    tree = TileRefinement(_lshape()).refined([0]).refined([3, 9])
    s = iga.HeatProblem(tree.model(), source=lambda x: 1.0 + x[:, 0] ** 2).dirichlet("boundary", _corner).solve()
    fast = estimate_error(s)
    monkeypatch.setattr(est, "_affine", lambda D: None)  # every map through its second derivatives
    general = estimate_error(s)
    assert np.allclose(fast.patch, general.patch, rtol=1e-10, atol=0)
    assert fast.energy == pytest.approx(general.energy, rel=1e-12)


def test_the_budget_counts_the_unknowns_a_solve_solves_for():
    from iga.adaptivity.loop import unknowns

    tree = TileRefinement(_lshape()).refined([1]).refined([3, 4, 5])
    for tag in ("boundary", "boundary - wmax"):
        problem = iga.HeatProblem(tree.model()).dirichlet(tag, _corner)
        assert unknowns(problem) == problem.solve().info.free_dofs


def test_a_large_adapted_model_is_sampled_with_hanging_points_and_the_same_fields(monkeypatch):
    import geometry.patches.sampling as sampling
    from iga.io.vtu import sampled_grid

    tree = TileRefinement(_lshape()).refined([1]).refined([3, 4, 5, 6]).refined([10, 11])
    s = iga.HeatProblem(tree.model()).dirichlet("boundary", _corner).solve()
    conforming = sampled_grid(tree.model(), s, samples=2)
    monkeypatch.setattr(sampling, "_CONFORMING_POINTS", 0)  # as if the conforming grid were too large
    monkeypatch.setattr(sampling, "_CONFORMING_COST", 1.0)
    hanging = sampled_grid(tree.model(), s, samples=2)
    assert hanging.n_points < conforming.n_points
    assert conforming.extract_surface(algorithm="dataset_surface").area == pytest.approx(14.0, rel=1e-12)
    assert hanging.volume == pytest.approx(3.0, rel=1e-12)  # the same solid, hanging points where fineness changes
    x = np.asarray(hanging.points)
    assert np.allclose(hanging.point_data["temperature"], s.probe(x), atol=1e-10)
