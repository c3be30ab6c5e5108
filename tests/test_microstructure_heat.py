"""Heat transfer across micro-structures: identity, branch and C0 constraints, slot faces."""

import numpy as np
import pytest

from geometry import primitives as pr
import tiling
from tiling import library as L
from iga import HeatProblem, ProblemError

from helpers import surface_area

AFFINE = pr.box((2.0, 1.0, 1.5), degrees=(1, 1, 1))


def linear(x):
    return 1 + 2 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]


@pytest.mark.parametrize("refine, elevate", [(0, 0), (1, 1)])
def test_patch_test_across_branch_and_identity_constraints(refine, elevate):
    # fractal hierarchy: wings glued to the trunk with swapped face parameters (identity),
    # children glued to the wing tops (branch, refinement matrices on the analysis spaces)
    ms = tiling.hierarchical(AFFINE, L.fractal(), (2, 1), 3)
    s = HeatProblem(ms, refine=refine, degree_elevation=elevate).dirichlet("boundary", linear).solve()
    assert s.l2_error(linear) < 1e-9
    pts = np.concatenate([P.composed(np.random.default_rng(i).random((3, 3)))[:, :3] for i, P in enumerate(ms.patches[::5])])
    assert np.abs(s.probe(pts) - linear(pts)).max() < 1e-9
    c = s.info["constraints"]
    assert c["branch_rows"] > 0 and c["identity_pairs"] > 0
    # free unknowns = equivalence classes - slave classes - prescribed (Dirichlet) unknowns - induced rank
    assert c["reduced"] == c["classes"] - c["slave_classes"]
    assert 0 < c["prescribed"] <= c["reduced"]
    assert s.info["free_dofs"] == c["reduced"] - c["prescribed"] - c["induced_rank"]


def test_regular_cross_patch_test_and_energy_balance():
    ms = tiling.regular(AFFINE, L.cross(), (3, 3, 3))
    s = HeatProblem(ms, degree_elevation=1).dirichlet("boundary", linear).solve()
    assert s.l2_error(linear) < 1e-9
    ms.tags["cooling"] = [f for f in ms.tags["boundary"] if f not in set(ms.tags["umin"])]
    s = HeatProblem(ms, conductivity=50.0).neumann("umin", 1000.0).robin("cooling", 5.0, 30.0).solve()
    b = s.info["balance"]
    assert b["relative_error"] < 1e-8
    # independent: the inflow is q times the area of the 9 arm ends on u = 0, each (0.3 * 2/3) x (0.3 * 1/2)
    area = sum(surface_area(ms.patches[i].composed.boundary(f)) for i, f in ms.tags["umin"])
    assert area == pytest.approx(9 * 0.3 * (1 / 3) * 0.3 * 0.5, rel=1e-12)
    assert s.flux("umin") == pytest.approx(-1000.0 * area, rel=1e-10)
    assert s.flux("cooling") == pytest.approx(1000.0 * area, rel=1e-8)


def test_hierarchical_energy_balance_neumann_root_robin_elsewhere():
    ms = tiling.hierarchical(AFFINE, L.fractal(), (2, 1), 4)
    ms.tags["cooling"] = [f for f in ms.tags["boundary"] if f not in set(ms.tags["branch-in"])]
    s = (HeatProblem(ms, conductivity=205.0, refine=1).neumann("branch-in", 1515.8)
         .robin("cooling", 5.0, 30.0).solve())
    assert s.info["balance"]["relative_error"] < 1e-8
    # one piece per root cell: the fractal tile keeps off its cell's sides, so the two trees do not touch
    assert s.info["components"]["count"] == 2 and not s.info["components"]["idle"]
    # independent: q times the area of the root faces, integrated on the composed splines
    area = sum(surface_area(ms.patches[i].composed.boundary(f)) for i, f in ms.tags["branch-in"])
    assert s.flux("branch-in") == pytest.approx(-1515.8 * area, rel=1e-10)
    # and the heat that convects away: h (T - T_inf) integrated on the faces equals it (steady state)
    assert s.flux("cooling") == pytest.approx(1515.8 * area, rel=1e-8)
    T = s.probe(np.array([P.composed(np.array([[0.5, 0.5, 0.5]]))[0, :3] for P in ms.patches[::9]]))
    assert np.all(T > 30.0)


def test_mismatched_refinement_is_refused():
    ms = tiling.hierarchical(AFFINE, L.fractal(), (1, 1), 2)
    prob = HeatProblem(ms, refine=1)
    prob.spaces[3] = HeatProblem(ms.patches[3].spline).spaces[0]  # a child space coarser than its parent
    prob.offsets = np.concatenate([[0], np.cumsum([sp.ndof for sp in prob.spaces])])
    prob.ndof = int(prob.offsets[-1])
    with pytest.raises(ProblemError, match="not nested|face spaces differ"):
        prob.dirichlet("boundary", 0.0).solve()


@pytest.mark.parametrize("make, levels", [(L.heat_sink_t1, 3), (L.heat_sink_t2, 3)])
def test_patch_test_on_discontinuity_hierarchies(make, levels):
    # C0 coupling where both sides of a discontinuity coincide, slot faces tagged and prescribed,
    # branch constraints between levels, identity constraints between neighbouring tiles
    ms = tiling.hierarchical(AFFINE, make(), (2, 1), levels)
    assert any(isinstance(f, str) and "=" in f for _, f in ms.tags["internal"])  # slot faces are tagged
    s = HeatProblem(ms, refine=1).dirichlet("boundary", linear).solve(tol=1e-12)
    assert s.l2_error(linear) < 1e-9
    assert s.info["constraints"]["c0_pairs"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("refine", [0, 1])
def test_patch_test_on_the_skinned_fig2_hierarchy(refine):
    # the Fig. 2 tile's slots reach its base: a child's slot faces (Dirichlet) meet the parent's
    # branch-out face inside an element, so their data fix combinations of the parent's coefficients
    ms = tiling.hierarchical(AFFINE, L.skinned_branching(), (1, 1), 3)
    assert len(ms.patches) == 1 + 6 + 36
    # geometry degree (2, 2, 3): the cofactor integrand needs one Gauss point more than p + 1
    s = HeatProblem(ms, refine=refine, quadrature_extra=1).dirichlet("boundary", linear).solve(tol=1e-12)
    assert s.l2_error(linear) < 1e-9
    c = s.info["constraints"]
    assert c["induced_rank"] > 0 and c["branch_rows"] > 0
    assert s.info["free_dofs"] == c["reduced"] - c["prescribed"] - c["induced_rank"]


def test_energy_balance_with_dirichlet_on_slave_dofs():
    ms = tiling.hierarchical(AFFINE, L.skinned_branching(), (1, 1), 2)
    ms.tags["rest"] = [f for f in ms.tags["boundary"] if f not in set(ms.tags["branch-in"])]
    s = HeatProblem(ms, conductivity=3.0, source=2.0).dirichlet("branch-in", 10.0).dirichlet("rest", 0.0).solve()
    assert s.info["constraints"]["induced_rank"] > 0
    assert s.info["balance"]["relative_error"] < 1e-8
    # the skinned tile's six arms meet only on a line of its base (the slots open from zero width), so each
    # arm with its child is a piece of its own
    assert s.info["components"]["count"] == 6 and not s.info["components"]["idle"]
    # heat enters at the hot base, leaves through the cold faces; together they carry the source
    assert s.flux("branch-in") < 0 < s.flux("rest")
    assert s.flux("branch-in") + s.flux("rest") == pytest.approx(s.info["balance"]["source_W"], rel=1e-8)


def test_optimal_l2_rate_across_a_hierarchy():
    ms = tiling.hierarchical(AFFINE, L.heat_sink_t2(), (1, 1), 2)
    T = lambda x: np.sin(x[:, 0]) * np.cos(0.8 * x[:, 1]) * np.exp(0.3 * x[:, 2])  # noqa: E731
    f = lambda x: (1 + 0.64 - 0.09) * T(x)  # noqa: E731
    errs = [HeatProblem(ms, source=f, refine=r).dirichlet("boundary", T).solve(tol=1e-12).l2_error(T) for r in (0, 1, 2)]
    rate = np.log2(errs[-2] / errs[-1])
    assert abs(rate - 3) < 0.2, errs  # tile degree 2: L2 rate p + 1


def test_identity_constraints_equal_the_merged_single_patch():
    # 3 x 3 x 3 box tiles glued by identity constraints span exactly the C0 space of one patch
    # with knots at the tile boundaries: the two solutions coincide
    ms = tiling.regular(AFFINE, tiling.Tile([pr.box()], name="block"), (3, 3, 3))
    merged = pr.box((2.0, 1.0, 1.5), elements=(3, 3, 3))
    f = lambda x: 1.0 + x[:, 0] * x[:, 1]  # noqa: E731
    a = HeatProblem(ms, source=f, degree_elevation=1).dirichlet("boundary", 0.0).solve(tol=1e-13)
    b = HeatProblem(merged, source=f, degree=2).dirichlet("boundary", 0.0).solve(tol=1e-13)
    assert a.info["free_dofs"] == b.info["free_dofs"]
    x = merged.evaluate(np.random.default_rng(7).random((200, 3)))[:, :3]
    assert np.abs(a.probe(x) - b.probe(x)).max() < 1e-10 * np.abs(b.probe(x)).max()


@pytest.mark.slow
def test_cross_paving_converges_to_a_refined_reference():
    ms = tiling.regular(AFFINE, L.cross(), (3, 3, 3))
    f = lambda x: 1.0 + 0 * x[:, 0]  # noqa: E731
    ends = [t for t in ("umin", "umax", "vmin", "vmax", "wmin", "wmax")]
    ms.tags["ends"] = [fc for t in ends for fc in ms.tags[t]]
    sols = [HeatProblem(ms, source=f, degree_elevation=1, refine=r).dirichlet("ends", 0.0).solve(tol=1e-12)
            for r in (0, 1, 2)]
    x = np.concatenate([P.composed(np.random.default_rng(i).random((4, 3)))[:, :3] for i, P in enumerate(ms.patches[::3])])
    ref = sols[-1].probe(x)
    e = [np.abs(s.probe(x) - ref).max() for s in sols[:-1]]
    # converging towards the reference; the arms meet the centre block along re-entrant edges, where the
    # solution is singular, so the pointwise rate is below the smooth-case p + 1
    assert e[1] < e[0] / 2
    assert np.all(ref > 0)
