"""The adjoint of a steady heat solution and the deformation map's parameterisation of the Gauss points: what
every sensitivity (:mod:`iga.sensitivity`, :mod:`iga.shape_sensitivity`) and the optimiser (:mod:`iga.design`)
share.

The discrete problem is R(u, p) = K(p) u - f(p) = 0 on the free unknowns (interface constraints and Dirichlet
values eliminated as the solve eliminates them); the adjoint lambda solves K lambda = dJ/du on the free unknowns
(the same reduced matrix: the heat forms are symmetric) and is zero on the prescribed ones.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.discretisation.constraints import needs_constraints, prolongation
from iga.discretisation.dirichlet import DirichletData, project_dirichlet
from iga.discretisation.system import solve_system
from iga.errors import ProblemError
from iga.outputs import Output

__all__ = ["adjoint", "design_map", "map_parameters", "map_basis"]


def adjoint(solution, output: Output, solver: str = "auto", tol: float = 1e-12) -> np.ndarray:
    """The adjoint lambda (ndof,) of ``output`` on a steady, linear heat ``solution``: K lambda = dJ/du on the
    free unknowns, lambda = 0 where the solution is prescribed, the interface constraints as in the solve."""
    if getattr(type(solution), "physics", None) != "heat" or not type(solution).steady:
        raise ProblemError(f"the adjoint is of a steady heat solution (iga.Solution), got {show(solution)}")
    if not isinstance(output, Output):
        raise ProblemError(f"output must be one of iga.outputs (e.g. MeanTemperature()), got {show(output)}")
    prob = solution.problem
    if prob.conductivity.of_temperature is not None or any(c.kind == "radiation" for c in prob.conditions):
        raise ProblemError("the adjoint here is of a linear problem; a temperature-dependent conductivity or "
                           "radiation makes it nonlinear (its adjoint needs the tangent at the solution)")
    g = output.gradient(solution)
    record = solution.record
    if record.again is not None:  # the forward solve kept its factorisation: one back-substitution
        return record.again(g)
    K, _, book = prob.assemble()
    if record.dirichlet is not None:  # the forward solve's constraints and Dirichlet data
        constraints, dd = record.constraints, record.dirichlet
    else:
        constraints = prolongation(prob.model, prob.spaces, prob.offsets, prob.weights) \
            if needs_constraints(prob.model, prob.spaces) else None
        dd = project_dirichlet(prob.faces, book["dirichlet"], prob.ndof, constraints)
    zero = DirichletData(dd.dofs, np.zeros(len(dd.dofs)), dd.G, dd.keys, dd.slave_rows,
                         np.zeros(len(dd.slave_rows)), dd.slave_faces, dd.master_faces)
    return solve_system(K, g, constraints, zero, solver, tol).u


def design_map(problem, channel: str):
    """(D, placed): the one deformation map of the model that holds ``channel`` (placed: the patches are placed in
    it), or the model's single spline holding it (not placed); :class:`ProblemError` otherwise."""
    patches = problem.model.patches
    outers = {id(p.outer): p.outer for p in patches}
    D = next(iter(outers.values())) if len(outers) == 1 else None
    placed = D is not None
    if D is None and len(patches) == 1:  # a single spline: the channel is its own
        D, placed = patches[0].spline, False
    if D is None or channel not in getattr(D, "channels", ()):
        raise ProblemError(f"the model needs one deformation map holding the channel {show(channel)} (a "
                           "micro-structure paved in one map, or one spline)")
    return D, placed


def map_parameters(patches, chunk, space, D, placed: bool) -> np.ndarray:
    """The parameters y (P N, 3) in the map D of the Gauss points of the patches ``chunk`` (one tile spline and
    ``space``): the placed tile's values A T(xi) + b, or (a model of one spline: D itself) the points xi; clipped
    onto D's domain."""
    axes = np.stack(np.meshgrid(*space.qaxes, indexing="ij"), -1).reshape(-1, 3)
    S = patches[chunk[0]].spline.evaluate(axes)[:, :3] if placed else axes
    ys = [S @ patches[i].placement[:, :3].T + patches[i].placement[:, 3]
          if placed and patches[i].placement is not None else S for i in chunk]
    return np.clip(np.concatenate(ys), D.domain[:, 0], D.domain[:, 1])


def map_basis(D, y: np.ndarray):
    """The sparse matrix (N, control points) of D's basis (NURBS where D has weights) at its parameters y (N, 3)."""
    import scipy.sparse as sp

    from geometry import knots as kn

    n = D.control_points.shape[:3]
    parts = [kn.basis_functions(D.knots[d], D.degrees[d], y[:, d]) for d in range(3)]
    idx, val = None, None
    for d, (spans, ders) in enumerate(parts):
        p = D.degrees[d]
        i_d = spans[:, None] - p + np.arange(p + 1)[None]  # (N, p + 1) control indices along d
        v_d = ders[:, 0, :]
        if idx is None:
            idx, val = i_d, v_d
        else:
            idx = (idx[:, :, None] * n[d] + i_d[:, None, :]).reshape(len(y), -1)
            val = (val[:, :, None] * v_d[:, None, :]).reshape(len(y), -1)
    if D.weights is not None:  # R_c = w_c N_c / sum_c w_c N_c
        wv = val * np.asarray(D.weights, float).reshape(-1)[idx]
        val = wv / wv.sum(1, keepdims=True)
    rows = np.repeat(np.arange(len(y)), idx.shape[1])
    return sp.csr_matrix((val.ravel(), (rows, idx.ravel())), shape=(len(y), int(np.prod(n))))
