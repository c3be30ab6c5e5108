"""Thermal radiation from faces, sigma eps (T^4 - T_amb^4) (W/m^2, outward), and the Newton solve it makes.

The face form of radiation is nonlinear in the temperature: its residual is
``F_i = int_F sigma eps (T^4 - T_amb^4) N_i dA`` and its tangent ``int_F 4 sigma eps T^3 N_i N_j dA``, a
boundary mass (:func:`iga.heat.forms.boundary_mass`) with a temperature-dependent coefficient, so the
Jacobian of the whole problem stays symmetric positive definite and every solver of the linear problem
applies.  Temperatures enter as absolute ones: the problem's temperatures plus the condition's ``offset``
(273.15 for degrees Celsius).

:func:`solve_radiation` runs Newton's method on the reduced system (constraints and Dirichlet data
eliminated as for the linear problem, :func:`iga.discretisation.system.reduction`) from the linear problem
with the radiation linearised about a reference temperature, with a backtracking line search on the residual
norm; it records every residual, so the quadratic convergence can be seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

import solvers

from geometry.numbers import TINY
from iga.discretisation.constraints import owners_of
from iga.discretisation.system import SystemSolution, project_symmetric, reduction
from iga.errors import ProblemError
from iga.heat.forms import boundary_load, boundary_mass

__all__ = ["STEFAN_BOLTZMANN", "RadiationFaces", "solve_radiation"]

#: the Stefan-Boltzmann constant, W/(m^2 K^4)
STEFAN_BOLTZMANN = 5.670374419e-8


@dataclass
class RadiationFaces:
    """The radiating faces of a problem at their Gauss points: ``fds`` (face data), ``coef`` per face sigma eps
    dA w (W/K^4 per point), ``ambient4`` per face the absolute ambient temperature to the fourth power, and
    ``offset`` per face (added to the problem's temperatures to make them absolute)."""

    fds: list
    coef: list
    ambient4: list
    offset: list

    @classmethod
    def of(cls, problem, book) -> "RadiationFaces":
        keys = list(book["radiation"])
        fds = problem.faces(keys)
        coef, amb4, off = [], [], []
        for key, fd in zip(keys, fds):
            eps, ambient, offset = book["radiation"][key]
            coef.append(STEFAN_BOLTZMANN * eps * fd.dAw)
            amb4.append((ambient + offset) ** 4)
            off.append(offset)
        return cls(fds, coef, amb4, off)

    def absolute(self, u: np.ndarray) -> list:
        """Absolute temperatures (K) at every face's Gauss points for coefficients ``u``."""
        return [fd.trace(u) + o for fd, o in zip(self.fds, self.offset)]

    def load(self, u: np.ndarray, ndof: int) -> np.ndarray:
        """F(u) (ndof,): int sigma eps (T^4 - T_amb^4) N_i dA, the heat radiated away through each function."""
        return boundary_load(self.fds, [c * (T ** 4 - a4) for c, T, a4 in zip(self.coef, self.absolute(u),
                                                                                 self.ambient4)], ndof)

    def tangent(self, u: np.ndarray, ndof: int) -> sp.csr_matrix:
        """dF/du (ndof x ndof): int 4 sigma eps T^3 N_i N_j dA."""
        return boundary_mass(self.fds, [4.0 * c * T ** 3 for c, T in zip(self.coef, self.absolute(u))], ndof)

    def flows(self, u: np.ndarray) -> list:
        """The heat radiated away through each face (W)."""
        return [float(np.sum(c * (T ** 4 - a4))) for c, T, a4 in zip(self.coef, self.absolute(u), self.ambient4)]

    def reference(self, f: np.ndarray) -> float:
        """A temperature (K) to linearise about at the start: the ambient's, or the one at which the faces
        radiate the loads' total away, whichever is higher."""
        area = sum(float(c.sum()) for c in self.coef)  # sigma int eps dA, W/K^4
        amb = max(float(np.max(a4)) ** 0.25 for a4 in self.ambient4)
        return max(amb, (abs(float(f.sum())) / area) ** 0.25 if area > 0 else 0.0, 1.0)


def solve_radiation(problem, K, f, constraints, dirichlet, faces: RadiationFaces, solver: str, tol: float,
                    maxiter: int | None, max_newton: int = 50):
    """Newton's method for K u + F(u) = f with the constraints and Dirichlet data; returns
    (:class:`iga.discretisation.system.SystemSolution`, the reduced residual norms per iteration).

    The start is the linear problem with sigma eps (T^4 - T_amb^4) replaced by its tangent about the
    reference temperature T_r (:meth:`RadiationFaces.reference`): 4 sigma eps T_r^3 (T - T_r) + sigma eps
    (T_r^4 - T_amb^4).  Converged when the reduced residual is ``tol`` times the larger of the loads' and the
    radiated heat's norms."""
    n = K.shape[0]
    Pf, offset, reaction_dofs, induced = reduction(constraints, dirichlet, n)
    Kr = project_symmetric(K, Pf)
    Tr = faces.reference(f)
    lin_coef = [4.0 * c * Tr ** 3 for c in faces.coef]
    lin_rhs = boundary_load(faces.fds, [c * (3.0 * Tr ** 4 + a4) - lc * o for c, a4, lc, o in
                                        zip(faces.coef, faces.ambient4, lin_coef, faces.offset)], n)
    B = boundary_mass(faces.fds, lin_coef, n)
    A0 = (Kr + project_symmetric(B, Pf)).tocsr()
    x, info = solvers.solve(A0, Pf.T @ (f + lin_rhs - (K + B) @ offset), method=solver, tol=tol, maxiter=maxiter)
    u = Pf @ x + offset

    def reduced_residual(u):
        R = K @ u - f + faces.load(u, n)
        return R, np.asarray(Pf.T @ R)

    R, r = reduced_residual(u)
    scale = max(float(np.linalg.norm(Pf.T @ f)), float(np.linalg.norm(Pf.T @ np.abs(faces.load(u, n)))), TINY)
    # the round-off of the conduction term, |K| |u|: with held temperatures, no loads and a faint radiation, a
    # converged residual holds that alone, however small the loads' scale
    floor = ROUNDOFF_RESIDUAL * float(np.linalg.norm(Pf.T @ (abs(K) @ np.abs(u))))
    history = [float(np.linalg.norm(r))]
    iterations = 0
    while history[-1] > max(max(tol, 1e-13) * scale, floor):
        if iterations >= max_newton:
            raise ProblemError(_stalled(history, scale))
        J = (Kr + project_symmetric(faces.tangent(u, n), Pf)).tocsr()
        dx, info = solvers.solve(J, -r, method=solver, tol=min(tol, 1e-12), maxiter=maxiter)
        step = 1.0
        while True:  # backtracking: the residual norm must fall (Armijo, 1e-4)
            u_try = u + step * (Pf @ dx)
            R_try, r_try = reduced_residual(u_try)
            if np.linalg.norm(r_try) <= (1 - 1e-4 * step) * history[-1]:
                break
            if step < 1e-6:
                raise ProblemError(_stalled(history, scale))
            step *= 0.5
        u, R, r = u_try, R_try, r_try
        history.append(float(np.linalg.norm(r)))
        iterations += 1
    low = min(float(T.min()) for T in faces.absolute(u))
    if low <= 0:
        raise ProblemError(f"the radiating faces reach {low:.3g} K, below absolute zero: the temperatures are "
                           "probably in degrees Celsius; pass scale='C' to radiation()")
    P = sp.identity(n, format="csr") if constraints is None else constraints.P
    reaction = (P.T @ R)[reaction_dofs]
    owner = reaction_dofs if constraints is None else owners_of(constraints.dof_master, P.shape[1])[reaction_dofs]
    prescribed = u[owner] if np.all(owner >= 0) else None
    info.extra = {**info.extra, "newton_iterations": iterations}
    return SystemSolution(u, reaction_dofs, reaction, info, int(Pf.shape[1]), induced, prescribed), history


#: a residual this small against |K| |u| is round-off: Newton stops there
ROUNDOFF_RESIDUAL = 1e-12


def _stalled(history: list, scale: float) -> str:
    """The message of a Newton iteration that stopped making progress."""
    return (f"Newton's method for the radiation did not converge after {len(history) - 1} iterations (relative "
            f"residuals {[f'{h / scale:.1e}' for h in history[-4:]]}): the conditions may admit no temperature "
            "above absolute zero (more heat drawn out than can reach the faces), or the temperatures are in "
            "degrees Celsius without scale='C'")
