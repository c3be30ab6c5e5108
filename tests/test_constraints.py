"""The prolongation of interface constraints: classes, branch rows, slaves of slaves, refusals."""

import numpy as np
import pytest

from geometry import BSpline
from geometry import primitives as pr
from geometry.faces import face_knots, nested_refinement
from geometry.patches.multipatch import Interface, MultiPatch
from iga import HeatProblem
from iga.discretisation.constraints import (branch_rows, class_expressions, equivalence_classes, identity_pairs,
                             plane_pairs, prolongation)
from iga.errors import ProblemError
from iga.discretisation.space import make_space

FULL = ((0.0, 1.0), (0.0, 1.0))


def _sideways_branch():
    """G below P (P.wmin refines G.wmax), C beside P (C.umin refines P.umax): the bottom edge of P.umax lies
    on P's branch-in face, so C's face DOFs there are slaves of slaves."""
    G = pr.box(degrees=(2, 2, 2))
    P = pr.box(origin=(0, 0, 1), degrees=(2, 2, 2), elements=(2, 2, 2))
    C = pr.box(origin=(1, 0, 1), degrees=(2, 2, 2), elements=(4, 4, 4))
    return MultiPatch.from_splines([G, P, C], branches=[((0, "wmax"), FULL, (1, "wmin")),
                                                        ((1, "umax"), FULL, (2, "umin"))])


def _field(problem, u, pi):
    """Patch ``pi``'s scalar field of the DOF vector ``u`` as a B-spline of its parameters."""
    s = problem.spaces[pi]
    coef = u[problem.offsets[pi]:problem.offsets[pi + 1]].reshape(s.shape)
    return BSpline(tuple(d.degree for d in s.dirs), [d.knots for d in s.dirs], np.repeat(coef[..., None], 3, -1))


def test_slaves_of_slaves_are_substituted_so_every_branch_face_is_continuous():
    problem = HeatProblem(_sideways_branch())
    c = prolongation(problem.model, problem.spaces, problem.offsets)
    assert c.stats["branch_rows"] == 4 * 4 + 6 * 6
    # before substitution some slave rows name other slaves (C's bottom edge through P's bottom edge)
    ia, ib = identity_pairs(problem.model, problem.spaces, problem.offsets)
    ncls, cls = equivalence_classes(problem.ndof, ia, ib)
    E, slaves = class_expressions(problem.model, ncls, cls, branch_rows(problem.model, problem.spaces,
                                                                        problem.offsets))
    assert E[slaves][:, slaves].nnz > 0
    rng = np.random.default_rng(3)
    u = c.P @ rng.standard_normal(c.P.shape[1])  # any function of the constrained space
    G, P, C = (_field(problem, u, i) for i in range(3))
    st = rng.random((200, 2))
    st[:20, 1] = 0.0  # on the edge where the two branch faces meet
    one = lambda f, x: f.evaluate(x)[:, 0]  # noqa: E731
    assert np.allclose(one(G, np.c_[st, np.ones(200)]), one(P, np.c_[st, np.zeros(200)]), atol=1e-12)
    assert np.allclose(one(P, np.c_[np.ones(200), st]), one(C, np.c_[np.zeros(200), st]), atol=1e-12)


def test_a_linear_temperature_is_exact_through_a_sideways_branch():
    exact = lambda x: x[:, 0] + 2 * x[:, 1] - 3 * x[:, 2]  # noqa: E731
    s = HeatProblem(_sideways_branch()).dirichlet("boundary", exact).solve()
    x = np.random.default_rng(4).random((300, 3)) * [1, 1, 1]
    x[100:200] += [0, 0, 1]
    x[200:] += [1, 0, 1]
    assert np.abs(s.probe(x) - exact(x)).max() < 1e-10


def test_branch_rows_that_prescribe_one_dof_differently_are_refused_naming_both_faces():
    # two children on the same parent face, over boxes that overlap: the shared DOFs get two different rows
    G = pr.box(degrees=(1, 1, 1), elements=(2, 1, 1))
    A = pr.box(origin=(0, 0, 1), size=(1, 1, 1), degrees=(1, 1, 1), elements=(2, 1, 1))
    B = pr.box(origin=(0.5, 0, 1), size=(1, 1, 1), degrees=(1, 1, 1), elements=(2, 1, 1))
    model = MultiPatch.from_splines([G, A, B], couple=False)
    for child, box in ((1, ((0.0, 0.5), (0.0, 1.0))), (2, ((0.25, 0.75), (0.0, 1.0)))):
        R = nested_refinement(face_knots(G, "wmax"), box, face_knots(model.patches[child].spline, "wmin"))
        model.interfaces.append(Interface("branch", (0, "wmax"), (child, "wmin"), box=box, R=R))
    model.interfaces.append(Interface("identity", (1, "wmin"), (2, "wmin"), swap=False, flip=(False, False)))
    problem = HeatProblem(model)
    with pytest.raises(ProblemError, match=r"patch 0 wmax -> patch 1 wmin and patch 0 wmax -> patch 2 wmin"):
        prolongation(problem.model, problem.spaces, problem.offsets)


def test_c0_pairs_couple_exactly_the_functions_that_meet_material():
    # degree 2, a full-multiplicity plane u = 0.5, 4 x 4 elements in (v, w); slot rectangle v, w in (0, 0.5)
    knots = [np.r_[0, 0, 0, .5, .5, .5, 1, 1, 1], np.r_[0, 0, 0, .25, .5, .75, 1, 1, 1],
             np.r_[0, 0, 0, .25, .5, .75, 1, 1, 1]]
    space = make_space(knots, (2, 2, 2))
    a, b = plane_pairs(space, {"u=0.5-": [((0.0, 0.5), (0.0, 0.5))]})
    # brute force: function (j, k) of (v, w) is coupled when its support meets an element outside the slot
    idx = np.arange(space.ndof).reshape(space.shape)
    want = []
    for j in range(6):
        for k in range(6):
            ev = [e for e in range(4) if knots[1][j] <= e / 4 and (e + 1) / 4 <= knots[1][j + 3]]
            ew = [e for e in range(4) if knots[2][k] <= e / 4 and (e + 1) / 4 <= knots[2][k + 3]]
            if any(not (e1 < 2 and e2 < 2) for e1 in ev for e2 in ew):
                want.append((idx[2, j, k], idx[3, j, k]))
    assert sorted(zip(a.tolist(), b.tolist())) == sorted(want) and 0 < len(want) < 36


def test_dirichlet_conditions_that_overlap_with_different_values_are_refused_naming_both():
    # two boxes glued face to face; 'patchN.face' tags name a face glued or not, so both sides of the shared face
    a, b = pr.box(degrees=(2, 2, 2)), pr.box(origin=(1, 0, 0), degrees=(2, 2, 2))
    model = MultiPatch.from_splines([a, b])
    p = HeatProblem(model).dirichlet("patch0.umax", 1.0).dirichlet("patch1.umin", 2.0).dirichlet("patch1.umax", 0.0)
    with pytest.raises(ProblemError, match=r"give one unknown different values \(1 and 2\) where their faces lie on "
                                           r"each other: the faces tagged 'patch0.umax' and the faces tagged 'patch1.umin'"):
        p.solve()
    # through a branch constraint: the child's face is tied to the parent's by the refinement matrix
    q = (HeatProblem(_sideways_branch()).dirichlet("patch0.wmax", 1.0).dirichlet("patch1.wmin", 2.0)
         .dirichlet("patch2.umax", 0.0))
    with pytest.raises(ProblemError, match=r"cannot both meet .* the faces tagged 'patch0.wmax' and the faces tagged "
                                           r"'patch1.wmin'"):
        q.solve()
    # faces that only share an edge, with values that jump along it, are fine (the edge takes the mean)
    s = HeatProblem(model).dirichlet("umin", 1.0).dirichlet("vmin", 2.0).solve()
    assert s.info["balance"]["relative_error"] < 1e-9
