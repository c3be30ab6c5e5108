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
A conductivity given as a channel of the deformation map D is linear in D's control values k_c of that
channel: k(y) = sum_c R_c(y) k_c at the point's parameter y of D (R_c the NURBS basis where D has weights), so
dJ/dk_c = - int R_c(y) grad lambda . grad T dV (:func:`channel_sensitivity`).
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

__all__ = ["gradient", "adjoint", "conductivity_sensitivity", "channel_sensitivity", "design_map", "map_basis",
           "map_parameters"]


def gradient(solution, output: Output, wrt: str = "tiles", solver: str = "auto") -> np.ndarray:
    """The derivative of ``output`` (one of :mod:`iga.outputs`) on a steady heat ``solution`` by the adjoint:
    ``wrt="tiles"`` or ``"patches"``, per tile or patch for a factor (1 + p) on its conductivity
    (:func:`conductivity_sensitivity`); ``wrt="channel:NAME"``, per control value of the map's channel NAME, which
    the conductivity reads (:func:`channel_sensitivity`)."""
    if isinstance(wrt, str) and wrt.startswith("channel:"):
        return channel_sensitivity(solution, output, wrt.split(":", 1)[1], solver)
    if wrt not in ("tiles", "patches"):
        raise ProblemError(f"wrt must be 'tiles', 'patches' or 'channel:NAME', got {show(wrt)}")
    return conductivity_sensitivity(solution, output, per=wrt[:-1], solver=solver)


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


def channel_sensitivity(solution, output: Output, channel: str, solver: str = "auto") -> np.ndarray:
    """dJ/dk_c of ``output`` with respect to the control values of the channel ``channel`` of the deformation map
    (the heat problem's conductivity must be that channel): an array shaped like D's control grid (module
    notes).  Units: those of J per W/(m K) of a control value."""
    prob = solution.problem
    k = prob.conductivity
    if k.scalar is None or k.scalar.kind != "channel" or k.scalar.spec != channel:
        raise ProblemError(f"channel_sensitivity: the conductivity is not the channel {show(channel)} of the map; "
                           "give the problem conductivity=" + repr(channel) + " (or differentiate the channel the "
                           "conductivity reads)")
    patches = prob.model.patches
    D, placed = design_map(prob, channel)
    lam = adjoint(solution, output, solver)
    grad = np.zeros(int(np.prod(D.control_points.shape[:3])))

    def add(chunk, space, vals, grads, wv, x, chans):
        rho = wv * np.sum(grads[:, 0] * grads[:, 1], axis=1)  # grad T . grad lambda w |det J|
        grad[:] -= map_basis(D, map_parameters(patches, chunk, space, D, placed)).T @ rho

    gauss_pass(prob, np.stack([solution.u, lam]), add)
    return grad.reshape(D.control_points.shape[:3])


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
