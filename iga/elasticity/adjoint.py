"""The adjoint of a linear elastic solution: K lambda = dJ/du on the free unknowns, lambda = 0 where the
displacement is prescribed, the interface constraints, supports, holds, springs and pins as the solve has them
(:meth:`iga.ElasticityProblem.system`; K is symmetric, so the adjoint system is the forward one with another
load).  What the sensitivities of outputs other than the self-adjoint compliance solve with
(:mod:`iga.elasticity.sensitivity`)."""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.discretisation.system import solve_system
from iga.errors import ProblemError
from iga.outputs import Output

__all__ = ["elastic_adjoint"]


def elastic_adjoint(solution, output: Output, solver: str = "auto", tol: float = 1e-12) -> np.ndarray:
    """The adjoint lambda (3 ndof,), component-major, of ``output`` on an elastic ``solution`` (module notes): one
    assembly and one solve of the forward system with the load dJ/du.  Serial solves only."""
    if getattr(type(solution), "physics", None) != "elasticity":
        raise ProblemError(f"the elastic adjoint is of an elastic solution (iga.ElasticSolution), got {show(solution)}")
    if not isinstance(output, Output):
        raise ProblemError(f"output must be one of iga.outputs (e.g. VonMisesNorm()), got {show(output)}")
    if solution._prescribed is None:  # (a distributed solve keeps no prescribed values)
        raise ProblemError("the elastic adjoint is of a serial solve; solve without mpiexec to differentiate")
    g = output.gradient(solution)
    system = solution.problem.system(solver)
    return solve_system(system.K, g, system.constraints, system.dd.homogeneous(), solver, tol, None,
                        system.options).u
