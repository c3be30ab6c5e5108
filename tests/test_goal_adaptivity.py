"""Goal-oriented adaptivity (iga.adaptivity.goal): the dual problem of weighted heat flows satisfies the duality
identity with the primal load, the loop marks by the dual-weighted indicators and converges the flows, and bad
goals are refused naming them."""

import numpy as np
import pytest

import iga
import tiling
from iga import ProblemError
from iga.adaptivity.goal import check_goals, dual_problem, goal_weights
from iga.app.maps import circular_heat_sink_map
from iga.outputs import HeatFlow, MeanTemperature
from tiling import library


def _sink(refine=0):
    ms = tiling.hierarchical(circular_heat_sink_map(), library.heat_sink_t1(), counts=(4, 1), levels=2, scale=0.5)
    return iga.HeatProblem(ms, conductivity=205.0, refine=refine).neumann("branch-in", 1515.8).robin(
        "exterior", 5.0, 30.0)


def test_the_dual_of_weighted_flows_meets_the_duality_identity():
    """sum_t w_t int_t h T dA = a(T, z) + int_R h T z dA = f . z: the flows' weights times (J_t + h T_inf A_t)
    equal the primal load against the dual solution, to round-off."""
    p = _sink()
    s = p.solve(tol=1e-13)
    goals = check_goals(p, [HeatFlow("vmin"), HeatFlow("wmax")])
    w = goal_weights(s, goals)
    assert np.allclose(w * np.abs([g.value(s) for g in goals]), 1.0)
    z = dual_problem(p, goals, w).solve(tol=1e-13)
    area = [sum(fd.dAw.sum() for fd in p.faces(p.tag_faces(g.tag))) for g in goals]
    lhs = sum(wi * (g.value(s) + 5.0 * 30.0 * a) for wi, g, a in zip(w, goals, area))
    assert float(s._loads @ z.u) == pytest.approx(lhs, rel=1e-12)


@pytest.mark.slow
def test_the_goal_oriented_loop_converges_the_flows():
    goal = [HeatFlow("vmin"), HeatFlow("wmax")]
    reference = _sink(refine=2).solve()
    res = iga.adaptive_solve(_sink(), 1e-12, refine="p", marking=0.3, max_steps=3, goal=goal)
    steps = res.history
    assert len(steps) == 3 and all(s.goal is not None and s.goal > 0 for s in steps)
    assert steps[-1].goal < steps[0].goal
    start = _sink().solve()

    def deviation(s):
        return max(abs(g.value(s) - g.value(reference)) / abs(g.value(reference)) for g in goal)

    assert deviation(res.solution) < 0.5 * deviation(start)
    assert steps[-1].unknowns < reference.info.free_dofs


def test_bad_goals_are_refused_naming_them():
    p = _sink()
    with pytest.raises(ProblemError, match="Robin"):
        iga.adaptive_solve(p, 1e-3, goal=HeatFlow("branch-in"))
    with pytest.raises(ProblemError, match="share the face"):
        iga.adaptive_solve(p, 1e-3, goal=[HeatFlow("exterior"), HeatFlow("wmax")])
    with pytest.raises(ProblemError, match="HeatFlow"):
        iga.adaptive_solve(p, 1e-3, goal=MeanTemperature())
    with pytest.raises(ProblemError, match="no faces"):
        iga.adaptive_solve(p, 1e-3, goal=HeatFlow("umax"))
    rest = iga.HeatProblem(p.model, conductivity=205.0).neumann("branch-in", 1515.8).robin("rest", 5.0, 30.0)
    with pytest.raises(ProblemError, match="rest"):
        iga.adaptive_solve(rest, 1e-3, goal=HeatFlow("wmax"))


def test_a_bad_adapt_goal_is_refused_naming_the_key():
    import tomllib

    from iga.app.config import validate

    text = (
        '[map]\nprimitive = "box"\nargs = {size = [0.03, 0.03, 0.03]}\n\n[tile]\nlibrary = "cross"\n\n'
        '[paving]\nscheme = "regular"\ncounts = [1, 1, 1]\n\n[material]\nconductivity = 205.0\n\n'
        '[[bc]]\nkind = "neumann"\ntag = "umin"\nvalue = 1e3\n\n[[bc]]\nkind = "robin"\ntag = "umax"\nh = 10.0\n'
        'ambient = 20.0\n\n[adapt]\ntolerance = 1e-3\ngoal = "umax"\n')
    with pytest.raises(ProblemError, match="adapt.goal"):
        validate(tomllib.loads(text))
    cfg = validate(tomllib.loads(text.replace('goal = "umax"', 'goal = ["umax"]')))
    assert list(cfg.adapt.goal) == ["umax"]
