"""One Problem: heat and elasticity share the discretisation and the tag check, and a solve writes nothing onto
its problem (what it finds is the solution's ``record``)."""

import numpy as np
import pytest

from geometry import primitives as pr
from iga import ElasticityProblem, HeatProblem, ProblemError
from iga.discretisation.problem import Problem, SolveRecord


def _state(problem) -> dict:
    """The problem's attributes by identity and, for dicts, by content."""
    return {k: (id(v), dict(v) if isinstance(v, dict) else None) for k, v in vars(problem).items()}


def test_a_solve_leaves_its_problem_as_it_was_and_hands_what_it_found_to_the_solution():
    model = [pr.box(degrees=(2, 2, 2)), pr.box(degrees=(2, 2, 2)).translate((1.0, 0.0, 0.0))]
    heat = HeatProblem(model).dirichlet("umin", 0.0).neumann("umax", 1.0)
    elastic = ElasticityProblem(model, 1.0, 0.3).dirichlet("umin", 0.0).traction("umax", (0.0, 0.0, 1e-3))
    for problem in (heat, elastic):
        assert isinstance(problem, Problem)
        before = _state(problem)
        first, second = problem.solve(solver="direct"), problem.solve(solver="cg", tol=1e-12)
        assert _state(problem) == before  # nothing added, replaced or changed on the problem
        for s in (first, second):
            assert isinstance(s.record, SolveRecord) and s.record.partition is None
            assert s.record.reduced_dofs == s.info["free_dofs"] > 0
            assert s.record.constraint_stats == s.info["constraints"] and s.info["constraints"]  # an interface
            assert "solve" in s.record.timings and "constraints" in s.record.timings
        assert first.record is not second.record
        assert np.allclose(first.u, second.u, atol=1e-8 * np.abs(first.u).max())
    # the heat solution's components are its own record's
    assert heat.solve().info["components"]["count"] == 1


def test_heat_and_elasticity_refuse_a_tag_without_faces_in_the_same_words():
    from geometry import MultiPatch, PlacedPatch

    model = MultiPatch([PlacedPatch(pr.box(degrees=(1, 1, 1)))], [], {"top": [], "umin": [(0, "umin")]})
    messages = []  # the tag exists, but names no face
    for make in (lambda: HeatProblem(model).dirichlet("top", 0.0),
                 lambda: ElasticityProblem(model, 1.0, 0.3).dirichlet("top", 0.0)):
        with pytest.raises(ProblemError, match=r"dirichlet: tag 'top' has no faces in this model"):
            make()
        try:
            make()
        except ProblemError as exc:
            messages.append(str(exc))
    assert len(messages) == 2 and messages[0] == messages[1]


def test_solution_info_is_typed_and_reads_as_the_dictionaries_did():
    import json

    from iga import ElasticityProblem
    from iga.discretisation.problem import ElasticInfo, HeatBalance, SolutionInfo
    from solvers import SolveInfo

    box = pr.box(degrees=(2, 2, 2))
    heat = HeatProblem(box, conductivity=3.0).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    info = heat.info
    assert isinstance(info, SolutionInfo) and isinstance(info.balance, HeatBalance)
    assert isinstance(info.solver, SolveInfo) and info.solver.method == info["solver"]["method"]
    assert info.balance.inflow_W == info["balance"]["inflow_W"] == pytest.approx(3.0, rel=1e-12)
    assert set(info) == {"dofs", "free_dofs", "constraints", "patches", "solver", "timings", "balance",
                         "components", "newton"} and info.newton == []
    assert json.loads(json.dumps(info.as_dict()))["balance"]["inflow_W"] == info.balance.inflow_W
    with pytest.raises(KeyError):
        info["no such field"]
    with pytest.raises(AttributeError):
        info.dofs = 1  # frozen: a solution's record is not edited afterwards
    elastic = ElasticityProblem(box, youngs=1.0, poisson=0.3).dirichlet("umin", 0.0).traction(
        "umax", [1.0, 0.0, 0.0]).solve()
    assert isinstance(elastic.info, ElasticInfo) and elastic.info.work.strain_energy_J > 0
    assert elastic.info["work"]["strain_energy_J"] == elastic.info.work.strain_energy_J
