"""The adjoint of a steady heat solution and the deformation map's parameterisation of the Gauss points: what
every sensitivity (:mod:`iga.sensitivity`, :mod:`iga.shape_sensitivity`) and the optimiser (:mod:`iga.design`)
share.

The discrete problem is R(u, p) = K(p) u - f(p) = 0 on the free unknowns (interface constraints and Dirichlet
values eliminated as the solve eliminates them); the adjoint lambda solves K lambda = dJ/du on the free unknowns
(the same reduced matrix: the heat forms are symmetric) and is zero on the prescribed ones.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry import knots as kn
from geometry.errors import show

from iga.discretisation.constraints import needs_constraints, prolongation
from iga.discretisation.dirichlet import project_dirichlet
from iga.discretisation.system import solve_system
from iga.errors import ProblemError
from iga.outputs import Output

__all__ = ["adjoint", "shape_map", "design_map", "map_parameters", "map_basis", "map_basis_values", "ChannelScatter",
           "per_patch_or_tile"]


def adjoint(solution, output: Output, solver: str = "auto", tol: float = 1e-12) -> np.ndarray:
    """The adjoint lambda (ndof,) of ``output`` on a steady, linear heat ``solution``: K lambda = dJ/du on the
    free unknowns, lambda = 0 where the solution is prescribed, the interface constraints as in the solve."""
    if getattr(type(solution), "physics", None) != "heat" or not type(solution).steady:
        raise ProblemError(f"the adjoint is of a steady heat solution (iga.Solution), got {show(solution)}")
    if not isinstance(output, Output):
        raise ProblemError(f"output must be one of iga.outputs (e.g. MeanTemperature()), got {show(output)}")
    prob = solution.problem
    prob.gauss_geometry.keep(prob)  # the adjoint load and the sensitivity pass read the same geometry
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
    return solve_system(K, g, constraints, dd.homogeneous(), solver, tol).u


def shape_map(problem):
    """(D, placed): the one deformation map the model's patches are placed in, or the model's single spline (not
    placed); :class:`ProblemError` for models of several maps."""
    patches = problem.model.patches
    outers = {id(p.outer): p.outer for p in patches}
    if len(outers) == 1 and next(iter(outers.values())) is not None:
        return next(iter(outers.values())), True
    if len(patches) == 1 and patches[0].outer is None:
        return patches[0].spline, False
    raise ProblemError("wrt='map' differentiates with respect to the control points of one deformation map: the "
                       f"model has {len(outers)} maps (a V-rep union has one per primitive) or patches without one")


def design_map(problem, channel: str):
    """(D, placed): the map of :func:`shape_map`, which must hold ``channel``; :class:`ProblemError` otherwise."""
    try:
        D, placed = shape_map(problem)
    except ProblemError:
        D = placed = None
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


def map_basis_values(D, y: np.ndarray, derivatives: bool = False, sides=None):
    """(idx (N, b), R (N, b), dR): the control indices of the b basis functions of D non-zero at each parameter y
    (N, 3), their values and, with ``derivatives``, [dR / dy_k (N, b)] * 3 (else None); NURBS where D has
    weights (R_c = w_c N_c / W, dR_c = w_c (dN_c W - N_c dW) / W^2).  ``sides``: per direction "left" or
    "right" (default), the limit taken at a knot (at a discontinuity plane, from one side)."""
    n = D.control_points.shape[:3]
    sides = sides or ("right",) * 3
    parts = [kn.basis_functions(D.knots[d], D.degrees[d], y[:, d], nder=int(derivatives), side=sides[d])
             for d in range(3)]
    idx = None
    for d, (spans, _) in enumerate(parts):
        i_d = spans[:, None] - D.degrees[d] + np.arange(D.degrees[d] + 1)[None]  # (N, p + 1) indices along d
        idx = i_d if idx is None else (idx[:, :, None] * n[d] + i_d[:, None, :]).reshape(len(y), -1)

    def product(orders):
        val = None
        for d, (_, ders) in enumerate(parts):
            v = ders[:, orders[d], :]
            val = v if val is None else (val[:, :, None] * v[:, None, :]).reshape(len(y), -1)
        return val

    N0 = product((0, 0, 0))
    dN = [product(tuple(int(j == k) for j in range(3))) for k in range(3)] if derivatives else None
    if D.weights is None:
        return idx, N0, dN
    w = np.asarray(D.weights, float).reshape(-1)[idx]
    W = (w * N0).sum(1, keepdims=True)
    R = w * N0 / W
    if dN is not None:
        dN = [w * (d * W - N0 * (w * d).sum(1, keepdims=True)) / W ** 2 for d in dN]
    return idx, R, dN


def map_basis(D, y: np.ndarray) -> sp.csr_matrix:
    """The sparse matrix (N, control points) of D's basis (NURBS where D has weights) at its parameters y (N, 3)."""
    idx, R, _ = map_basis_values(D, y)
    rows = np.repeat(np.arange(len(y)), idx.shape[1])
    return sp.csr_matrix((R.ravel(), (rows, idx.ravel())), shape=(len(y), int(np.prod(D.control_points.shape[:3]))))


class ChannelScatter:
    """Densities at the Gauss points scattered onto the control values of a channel: dJ/dc = sum_q R_c(y_q) rho_q
    for the map(s) that hold ``channel`` (one map or one spline; or every map of a model of several, a V-rep
    union's primitives and bridges).  ``add(chunk, space, rho (P nq,))`` per group of :func:`iga.outputs.gauss_pass`;
    :meth:`result` is an array shaped like the map's control grid, or a tuple of them, one per map in the order
    the patches first name them."""

    def __init__(self, problem, channel: str):
        self.patches = problem.model.patches
        maps = _channel_maps(problem, channel)
        if maps is None:  # one map (or one spline)
            D, self.placed = design_map(problem, channel)
            maps = [D]
        else:
            self.placed = True
        self.maps = maps
        self.index = {id(D): i for i, D in enumerate(maps)}
        self.grads = [np.zeros(int(np.prod(D.control_points.shape[:3]))) for D in maps]

    def add(self, chunk, space, rho: np.ndarray) -> None:
        rho = rho.reshape(len(chunk), -1)
        owner = np.array([self.index[id(self.patches[i].outer)] if len(self.maps) > 1 else 0 for i in chunk])
        for m in np.unique(owner):  # the patches of each map at once
            rows = np.flatnonzero(owner == m)
            D = self.maps[m]
            y = map_parameters(self.patches, [chunk[r] for r in rows], space, D, self.placed)
            self.grads[m] += map_basis(D, y).T @ rho[rows].reshape(-1)

    def result(self):
        out = [g.reshape(D.control_points.shape[:3]) for g, D in zip(self.grads, self.maps)]
        return out[0] if len(out) == 1 else tuple(out)


def _channel_maps(problem, channel: str):
    """The maps of a model of several deformation maps, in the order their patches first name them, each holding
    ``channel``; None for a model of one map or one spline."""
    maps: list = []
    for p in problem.model.patches:
        if p.outer is None:
            return None
        if all(p.outer is not m for m in maps):
            maps.append(p.outer)
    if len(maps) <= 1:
        return None
    for m in maps:
        if channel not in m.channels:
            raise ProblemError(f"the model's maps must all hold the channel {show(channel)}; one holds "
                               f"{list(m.channels)}")
    return maps


def per_patch_or_tile(problem, per_patch: np.ndarray, per: str) -> np.ndarray:
    """Values per patch (patches,) as they are (``per="patch"``) or summed per tile (``per="tile"``, (tiles,): a
    micro-structure's; the project's error for another model)."""
    if per == "patch":
        return per_patch
    if not hasattr(problem.model, "tiles"):
        raise ProblemError("per tile needs a micro-structure (its patches know their tiles); ask per patch")
    tiles = np.array([p.tile for p in problem.model.patches])
    return np.bincount(tiles, weights=per_patch, minlength=len(problem.model.tiles))
