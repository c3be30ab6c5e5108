"""Goal-oriented marking: refine where the error in chosen heat flows comes from, not where the energy error is.

For outputs J_t (the heat flows :class:`iga.outputs.HeatFlow` through Robin faces, J_t = int_t h (T - T_inf) dA)
the dual problem has the primal's operator and the outputs' derivatives as its load: a(v, z) + int_R h v z dA
= sum_t w_t int_t h v dA, i.e. the primal problem with no source, no Neumann flux, zero Dirichlet values, and
the ambient temperature w_t on the faces of output t (0 on the other Robin faces).  With the residual
indicators eta_P(T_h) of the solution and eta_P(z_h) of the dual (:mod:`iga.adaptivity.estimator`), the
product rho_P = eta_P(T_h) eta_P(z_h) bounds each patch's share of the output error up to constants (the
dual-weighted residual in product form: Becker and Rannacher 2001; Mommer and Stevenson 2009 prove optimal
rates for its marking); Dorfler marking runs on rho_P and the loop stops when sum_P rho_P, relative to the
weighted outputs (w_t = 1 / |J_t| of the first step, so every flow counts alike), meets the tolerance.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.errors import ProblemError
from iga.heat.coefficients import ScalarField
from iga.outputs import HeatFlow
from iga.tags import mentions_rest

__all__ = ["check_goals", "dual_problem", "goal_weights"]


def check_goals(problem, goal) -> list:
    """The goal as a list of :class:`HeatFlow` outputs whose faces are Robin faces of ``problem`` and do not
    overlap; the project's error otherwise."""
    goals = list(goal) if isinstance(goal, (list, tuple)) else [goal]
    if not goals or not all(isinstance(g, HeatFlow) for g in goals):
        raise ProblemError(f"goal must be a HeatFlow(tag) or a list of them (the flows to converge), got {show(goal)}")
    if any(mentions_rest(problem.model, c.tag) for c in problem.conditions):
        raise ProblemError("a goal-oriented loop builds the dual problem from the conditions' tags; the tag 'rest' "
                           "would resolve differently there: name the faces instead")
    robin = set(problem.faces_by_kind()["robin"])
    seen: dict = {}
    for g in goals:
        faces = set(problem.tag_faces(g.tag))
        if not faces:
            raise ProblemError(f"goal {g.name}: the tag {show(g.tag)} has no faces")
        if not faces <= robin:
            raise ProblemError(f"goal {g.name}: the flow through faces without a Robin condition is not a goal here "
                               "(Neumann flows are prescribed, Dirichlet ones are reactions); choose Robin faces")
        for f in faces:
            if f in seen:
                raise ProblemError(f"goals {seen[f]} and {g.name} share the face {f}; give each face to one goal")
            seen[f] = g.name
    return goals


def goal_weights(solution, goals) -> np.ndarray:
    """w_t = 1 / |J_t| of ``solution`` (1 where a flow is zero): every flow counts relative to its size."""
    values = np.array([abs(g.value(solution)) for g in goals])
    return np.where(values > 0, 1.0 / np.where(values > 0, values, 1.0), 1.0)


def dual_problem(problem, goals, weights):
    """The dual problem of the weighted flows (module notes) on ``problem``'s model and spaces."""
    dual = problem.on(problem.model)
    dual.conditions = []
    dual.source = ScalarField(0.0, "source", model=problem.model)
    union = " | ".join(f"({g.tag})" for g in goals)
    for c in problem.conditions:
        if c.kind == "dirichlet":
            dual.dirichlet(c.tag, 0.0)
        elif c.kind == "robin":
            h = c.h.spec
            rest = f"({c.tag}) - ({union})"
            if problem.tag_faces(rest):
                dual.robin(rest, h, 0.0)
            for g, w in zip(goals, weights):
                part = f"({c.tag}) & ({g.tag})"
                if problem.tag_faces(part):
                    dual.robin(part, h, float(w))
        elif c.kind != "neumann":
            raise ProblemError(f"a goal-oriented loop needs Dirichlet, Neumann and Robin conditions; the "
                               f"{c.kind} condition on {show(c.tag)} is not covered")
    return dual
