"""Exact sensitivities of heat outputs by the adjoint: the derivative of an output J (:mod:`iga.outputs`) with
respect to the conductivity of each patch or tile, from one extra solve.

The discrete problem is R(u, p) = K(p) u - f = 0 on the free unknowns (interface constraints and Dirichlet
values eliminated as the solve eliminates them).  With the adjoint lambda, K lambda = dJ/du on the free
unknowns (the same reduced matrix: the heat forms are symmetric) and zero on the prescribed ones,

    dJ/dp = dJ/dp (explicit) - lambda . (dK/dp u - df/dp).

A factor (1 + p_e) on the conductivity of patch (or tile) e scales its diffusion matrix K_e, so
dJ/dp_e = - int_e grad lambda . k grad T dV, integrated by the problem's own Gauss rule: the derivative of
the discrete output, exact to round-off (a finite difference agrees to its own truncation error,
``tests/test_sensitivity.py``).  Robin, Neumann and source terms do not depend on the conductivity.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.discretisation.constraints import needs_constraints, prolongation
from iga.discretisation.dirichlet import DirichletData, project_dirichlet
from iga.discretisation.system import solve_system
from iga.errors import ProblemError
from iga.heat.coefficients import TENSOR_PAIRS
from iga.outputs import Output, gauss_pass

__all__ = ["adjoint", "conductivity_sensitivity"]


def adjoint(solution, output: Output, solver: str = "auto", tol: float = 1e-12) -> np.ndarray:
    """The adjoint lambda (ndof,) of ``output`` on a steady, linear heat ``solution``: K lambda = dJ/du on the
    free unknowns, lambda = 0 where the solution is prescribed, the interface constraints as in the solve."""
    from iga.heat.solution import Solution

    if not isinstance(solution, Solution) or type(solution) is not Solution:
        raise ProblemError(f"the adjoint is of a steady heat solution (iga.Solution), got {show(solution)}")
    if not isinstance(output, Output):
        raise ProblemError(f"output must be one of iga.outputs (e.g. MeanTemperature()), got {show(output)}")
    prob = solution.problem
    if prob.conductivity.of_temperature is not None or any(c.kind == "radiation" for c in prob.conditions):
        raise ProblemError("the adjoint here is of a linear problem; a temperature-dependent conductivity or "
                           "radiation makes it nonlinear (its adjoint needs the tangent at the solution)")
    g = output.gradient(solution)
    K, _, book = prob.assemble()
    constraints = prolongation(prob.model, prob.spaces, prob.offsets, prob.weights) \
        if needs_constraints(prob.model, prob.spaces) else None
    dd = project_dirichlet(prob.faces, book["dirichlet"], prob.ndof, constraints)
    zero = DirichletData(dd.dofs, np.zeros(len(dd.dofs)), dd.G, dd.keys, dd.slave_rows,
                         np.zeros(len(dd.slave_rows)), dd.slave_faces, dd.master_faces)
    return solve_system(K, g, constraints, zero, solver, tol).u


def conductivity_sensitivity(solution, output: Output, per: str = "patch", solver: str = "auto") -> np.ndarray:
    """dJ/dp_e of ``output`` for a factor (1 + p_e) on the conductivity of every patch (``per="patch"``, (patches,))
    or every tile (``per="tile"``, (tiles,), a micro-structure's), at p = 0: one adjoint solve and one pass over the
    Gauss points (module notes).  Units: those of J per unit relative change of the conductivity."""
    if per not in ("patch", "tile"):
        raise ProblemError(f"per must be 'patch' or 'tile', got {show(per)}")
    prob = solution.problem
    if per == "tile" and not hasattr(prob.model, "tiles"):
        raise ProblemError("per='tile' needs a micro-structure (its patches know their tiles); use per='patch'")
    lam = adjoint(solution, output, solver)
    out = np.zeros(len(prob.model.patches))

    def add(chunk, space, vals, grads, wv, x, chans):
        where = f"patches {chunk[0]}..{chunk[-1]}"
        k = prob.conductivity.values(x, {c: np.reshape(v, -1) for c, v in chans.items()}, where)
        gT, gL = grads[:, 0], grads[:, 1]
        if k.ndim == 1:
            dens = k * np.sum(gT * gL, axis=1)
        else:  # the six tensor components (xx, yy, zz, xy, xz, yz)
            dens = sum(k[:, j] * (gL[:, r] * gT[:, s] + (gL[:, s] * gT[:, r] if r != s else 0.0))
                       for j, (r, s) in enumerate(TENSOR_PAIRS))
        out[np.asarray(chunk)] -= (dens * wv).reshape(len(chunk), -1).sum(1)

    gauss_pass(prob, np.stack([solution.u, lam]), add)
    if per == "patch":
        return out
    tiles = np.array([p.tile for p in prob.model.patches])
    return np.bincount(tiles, weights=out, minlength=len(prob.model.tiles))
