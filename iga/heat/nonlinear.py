"""Temperature-dependent conductivity, k(x, T), solved by Newton's method (radiating faces included).

The residual of -div(k(T) grad T) = f with the conditions is
``R_i(u) = int k(T) grad T . grad N_i dV + (Robin) + F_i(u) - f_i`` and its Jacobian
``J_ij = int k(T) grad N_j . grad N_i dV + int dk/dT N_j grad T . grad N_i dV + (Robin) + dF_i/du_j``.
The first volume term is the diffusion form with the conductivity frozen at the current temperature
(:func:`iga.heat.forms.diffusion`, :func:`iga.assembly.tensor.stiffness_data`); the second is a first-order
term of the same sum-factorised vocabulary, sum_r int G_r d_r N_i N_j with G_r = dk/dT (c_r . grad T) w
sign(det J) (c_r the rows of det J * J^-1), and makes J unsymmetric: it is solved by a sparse LU.  Both are
assembled on the NumPy path, patch group by patch group, with the temperature and its gradient at the Gauss
points from the coefficients (:func:`iga.discretisation.fields.grid_fields`).  Patches analysed in the NURBS
basis (:mod:`iga.discretisation.rational`) are refused for now.

Newton starts from the linear problem with k frozen at a reference temperature (the mean of the prescribed
and ambient values) and takes backtracking steps on the residual norm; it runs past ``tol`` until the residual
stops falling quadratically (round-off), and every residual is recorded.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from geometry.numbers import TINY
from geometry.patches.chain import patches_geometry_derivs

from iga.assembly.forms import form_data
from iga.assembly.tensor import pattern
from iga.assembly.terms import DIFFUSION, form_terms
from iga.assembly.vector_csr import VectorCSR
from iga.discretisation.components import analyse_components
from iga.discretisation.constraints import owners_of, prolongation
from iga.discretisation.dirichlet import project_dirichlet
from iga.discretisation.problem import SolveRecord
from iga.discretisation.faces import chunks
from iga.discretisation.fields import grid_fields
from iga.discretisation.jacobians import checked_det
from iga.discretisation.system import SystemSolution, reduction
from iga.errors import ProblemError
from iga.heat.forms import diffusion
from iga.heat.radiation import RadiationFaces
from iga.heat.solution import Solution
from solvers.info import SolveInfo

__all__ = ["tangent_forms", "solve_conductivity", "solve_temperature_dependent"]

#: int G_r d_r N_i N_j: the test function differentiated along direction r, the trial one not; the tangent of
#: k(T) takes G_r = dk/dT (c_r . grad T) w sign(det J) (c_r the rows of det J J^-1)
TEMPERATURE_GRADIENT = form_terms([(r, tuple((int(k == r), 0) for k in range(3))) for r in range(3)], fields=3)


def tangent_forms(problem, u: np.ndarray, derivative: bool = True):
    """(K(u), C(u)): the diffusion matrix with k at the temperature of coefficients ``u`` (symmetric, CSR) and,
    with ``derivative``, the first-order term int dk/dT N_j grad T . grad N_i dV (CSR; None otherwise)."""
    vol, k = problem.volume, problem.conductivity
    Kc = VectorCSR(problem.offsets, vol.nnz, components=1)
    Cc = VectorCSR(problem.offsets, vol.nnz, components=1) if derivative else None
    for members in vol.groups.values():  # patches sharing a space and a tile spline
        if problem.weights[members[0]] is not None:
            raise ProblemError(f"patch {members[0]} is analysed in the NURBS basis of its own weights; a "
                               "temperature-dependent conductivity is assembled in the polynomial basis only: "
                               "give the patch as a polynomial spline (or a constant conductivity)")
        space = problem.spaces[members[0]]
        tables = [np.swapaxes(d.B[:, :, :-1], 1, 2) for d in space.dirs]
        w = np.einsum("i,j,k->ijk", *[d.qw for d in space.dirs]).ravel()
        pat = pattern(space)
        for chunk in chunks(members, 2 * space.nq_total):
            P = len(chunk)
            where = f"patch {chunk[0]}" if P == 1 else f"patches {chunk[0]}..{chunk[-1]}"
            x, D, _ = patches_geometry_derivs([problem.model.patches[i] for i in chunk], space.qaxes)
            U = np.stack([u[problem.offsets[i]:problem.offsets[i + 1]].reshape((1,) + space.shape) for i in chunk])
            T, grad, det = grid_fields(U, tables, D)
            checked_det(det, where)
            xs, T, grad = x.reshape(-1, 3), T[:, 0], grad[:, 0]
            kv, dk = k.at_temperature(xs, T, where, derivative=True) if derivative else \
                (k.at_temperature(xs, T, where), None)
            wv = np.broadcast_to(w, (P, len(w))).reshape(-1)
            C6, _, _ = diffusion(D, kv, np.zeros_like(kv), wv)
            Kc.put(chunk, pat, {(0, 0): form_data(space, C6.reshape((6, P) + space.qshape), DIFFUSION, pat)})
            if derivative:
                Du, Dv, Dw = (d.reshape(-1, 3) for d in D)
                rows = (np.cross(Dv, Dw), np.cross(Dw, Du), np.cross(Du, Dv))  # det J * J^-1, row by row
                scale = dk * wv * np.sign(det)
                G = np.stack([(scale * np.sum(c * grad, axis=1)).reshape((P,) + space.qshape) for c in rows])
                Cc.put(chunk, pat, {(0, 0): form_data(space, G, TEMPERATURE_GRADIENT, pat)})
    return Kc.matrix(), (Cc.matrix() if derivative else None)


def solve_conductivity(problem, f, robin, constraints, dirichlet, faces, tol: float, max_newton: int = 50):
    """Newton's method for a temperature-dependent conductivity (and radiation, ``faces`` a
    :class:`iga.heat.radiation.RadiationFaces` or None): f the loads (ndof,), ``robin`` the Robin mass (CSR or
    None); returns (:class:`iga.discretisation.system.SystemSolution`, reduced residual norms)."""
    n = problem.ndof
    Pf, offset, reaction_dofs, induced = reduction(constraints, dirichlet, n)
    R0 = robin if robin is not None else sp.csr_matrix((n, n))
    t0 = time.perf_counter()

    def residual(u):
        K, _ = tangent_forms(problem, u, derivative=False)
        R = K @ u + R0 @ u - f + (faces.load(u, n) if faces is not None else 0.0)
        return R, np.asarray(Pf.T @ R)

    u = _start(problem, offset, Pf, f, R0, faces, dirichlet)
    R, r = residual(u)
    scale = max(float(np.linalg.norm(Pf.T @ f)), float(np.linalg.norm(r)), TINY)
    history = [float(np.linalg.norm(r))]
    while history[-1] > 1e-14 * scale:
        if len(history) > max_newton:
            raise ProblemError(f"Newton's method for k(T) did not converge in {max_newton} iterations (relative "
                               f"residuals {[f'{h / scale:.1e}' for h in history[-4:]]}); check that k(T) is "
                               "smooth and positive over the temperatures reached")
        K, C = tangent_forms(problem, u)
        J = K + C + R0 + (faces.tangent(u, n) if faces is not None else 0)
        dx = spla.splu((Pf.T @ (J @ Pf)).tocsc()).solve(-r)
        step = 1.0
        while True:  # backtracking on the residual norm (Armijo, 1e-4)
            u_try = u + step * (Pf @ dx)
            R_try, r_try = residual(u_try)
            if np.linalg.norm(r_try) <= (1 - 1e-4 * step) * history[-1] or step < 1e-6:
                break
            step *= 0.5
        if np.linalg.norm(r_try) > (1 - 1e-4 * step) * history[-1]:  # no step lowers the residual
            if history[-1] <= tol * scale:
                break  # converged to round-off
            raise ProblemError(f"Newton's method for k(T) stalled (relative residual {history[-1] / scale:.1e}): "
                               "no step lowers the residual; check k(T) over the temperatures reached")
        u, R, r = u_try, R_try, r_try
        history.append(float(np.linalg.norm(r)))
        if history[-1] <= tol * scale and history[-1] > 1e-3 * history[-2]:
            break  # converged, and no longer falling quadratically: round-off
    P = sp.identity(n, format="csr") if constraints is None else constraints.P
    owner = reaction_dofs if constraints is None else owners_of(constraints.dof_master, P.shape[1])[reaction_dofs]
    prescribed = u[owner] if np.all(owner >= 0) else None
    info = SolveInfo("newton (SuperLU)", len(history) - 1, history[-1] / scale, 0.0, time.perf_counter() - t0,
                     {"newton_iterations": len(history) - 1})
    return SystemSolution(u, reaction_dofs, (P.T @ R)[reaction_dofs], info, int(Pf.shape[1]), induced,
                          prescribed), history


def _start(problem, offset, Pf, f, R0, faces, dirichlet) -> np.ndarray:
    """The linear problem with k at a reference temperature (the mean of the prescribed values, or of the
    radiation's ambient, or 0) and radiation linearised about it: Newton's first iterate."""
    values = [np.asarray(dirichlet.values, float)] if len(dirichlet.values) else []
    if faces is not None:
        values.append(np.array([a4.mean() ** 0.25 - o for a4, o in zip(faces.ambient4, faces.offset)]))
    T_ref = float(np.mean(np.concatenate(values))) if values else 0.0
    u_ref = np.full(problem.ndof, T_ref)
    K, _ = tangent_forms(problem, u_ref, derivative=False)
    A = K + R0
    rhs = f.copy()
    if faces is not None:  # F(u) ~ F(u_ref) + F'(u_ref) (u - u_ref)
        Ft = faces.tangent(u_ref, problem.ndof)
        A = A + Ft
        rhs += Ft @ u_ref - faces.load(u_ref, problem.ndof)
    Ar = (Pf.T @ (A @ Pf)).tocsc()
    x = spla.splu(Ar).solve(np.asarray(Pf.T @ (rhs - A @ offset)))
    return Pf @ x + offset


def solve_temperature_dependent(problem, tol: float) -> Solution:
    """The steady solve of a problem whose conductivity depends on the temperature: loads and face terms as
    the linear problem's, constraints, components and Dirichlet projection likewise, then
    :func:`solve_conductivity`; a :class:`iga.Solution` whose ``info["newton"]`` holds the residuals."""
    by_kind = problem.faces_by_kind()
    t0 = time.perf_counter()
    f_vol, source_total = problem.volume.load(problem.source)
    loads, robin_mass, book = problem.face_terms(by_kind)
    f = f_vol + loads
    book["source"] = source_total
    record = SolveRecord(timings={**problem.timings, "assembly_loads": time.perf_counter() - t0})
    t0 = time.perf_counter()
    constraints = (prolongation(problem.model, problem.spaces, problem.offsets, problem.weights)
                   if problem._needs_constraints() else None)
    record.constraint_stats = dict(constraints.stats) if constraints is not None else {}
    record.components, record.idle_components = analyse_components(problem, constraints, by_kind, source_total)
    dd = project_dirichlet(problem.faces, book["dirichlet"], problem.ndof, constraints)
    record.timings["constraints"] = time.perf_counter() - t0
    faces = RadiationFaces.of(problem, book) if book["radiation"] else None
    res, record.newton = solve_conductivity(problem, f, robin_mass, constraints, dd, faces, tol)
    record.timings["solve"] = res.info.solve_s
    record.constraint_stats["prescribed"] = int(len(dd.dofs))
    record.reduced_dofs = int(res.reduced)
    Gd = dd.G[res.reaction_dofs].toarray() if dd.G is not None else np.zeros((len(res.reaction_dofs), 0))
    integrals = {key: Gd[:, j] for j, key in enumerate(dd.keys)}
    # the energy identity a(T, T) = l(T) + r . T_D holds for k(T) too; radiation has none
    return Solution(problem, res.u, book, res.reaction_dofs, res.reaction, integrals, res.info,
                    loads=None if faces is not None else f, prescribed=res.prescribed, record=record)
