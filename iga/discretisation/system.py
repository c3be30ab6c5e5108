"""The reduced linear system: constraints and Dirichlet data eliminated, solved, expanded back.

Without interface constraints (one unconstrained patch) the prescribed
unknowns are removed by row and column selection, in the matrix's own memory
for large systems.  With constraints ``u = P u_red + g`` the reduced system is
``P_f^T K P_f x = P_f^T (f - K g)``.  The consistent boundary flux (the
reaction ``K u - f`` on the prescribed unknowns) is returned for the energy
balance and ``Solution.flux``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

import solvers
from geometry.numbers import TINY
from solvers.indexing import complement

from iga.assembly import compiled as fast_assembly
from iga.discretisation.constraints import owners_of
from solvers.elimination import induced_elimination
from iga.errors import ProblemError

__all__ = ["eliminate", "solve_system", "SystemSolution", "reduction", "project_symmetric"]

#: solvers a solve can keep prepared for the same system's next right-hand side (:func:`solvers.prepare`)
_KEEPABLE = ("auto", "direct", "amg-cg", "cg")
_IN_PLACE_NNZ = 1 << 22  # in-place Dirichlet elimination (numba) from this many matrix entries


def eliminate(K: sp.csr_matrix, f: np.ndarray, free: np.ndarray, dofs: np.ndarray, g: np.ndarray,
              in_place: bool = False):
    """``K[free][:, free]`` and ``f[free] - K[free][:, dofs] @ g`` in O(nnz) array operations.

    SciPy's column fancy indexing is several times slower on large matrices;
    here the kept rows are sliced once and their columns filtered by a map.
    ``in_place``: K may be destroyed; for large matrices the compiled kernel
    (numba) then compacts K inside its own arrays, so no second matrix is
    allocated.
    """
    n = K.shape[0]
    ug = np.zeros(n)
    ug[dofs] = g
    rhs = f[free] - (K @ ug)[free] if len(dofs) else f[free].copy()
    if in_place and fast_assembly.AVAILABLE and K.nnz >= _IN_PLACE_NNZ:
        return fast_assembly.compact_rows_cols(K, free), rhs
    Kr = K[free]  # row selection (fast in SciPy)
    col = np.full(n, -1, np.int64)
    col[free] = np.arange(len(free))
    new = col[Kr.indices]
    keep = new >= 0
    dropped = np.flatnonzero(~keep)  # few: the Dirichlet columns of the kept rows
    indptr = Kr.indptr - np.searchsorted(dropped, Kr.indptr)
    idx = new[keep]
    A = sp.csr_matrix((Kr.data[keep], idx.astype(np.int32) if len(free) < 2**31 else idx, indptr),
                      shape=(len(free), len(free)))
    return A, rhs


@dataclass
class SystemSolution:
    """Coefficients ``u`` (ndof,), the reaction on ``reaction_dofs``, solver info, reduced size, induced rank."""

    u: np.ndarray
    reaction_dofs: np.ndarray
    reaction: np.ndarray
    info: object
    reduced: int
    induced_rank: int
    #: the reduced unknowns' values on ``reaction_dofs`` (the supports' work is reaction . prescribed); None
    #: where a distributed solve does not gather them
    prescribed: np.ndarray | None = None
    #: with ``keep``: load (ndof,) -> coefficients (ndof,) of the same system with zero Dirichlet data, by the
    #: solve's own factorisation or hierarchy (an adjoint: :func:`iga.sensitivity.adjoint`); else None
    again: object = None


def project_symmetric(A, Pf) -> sp.csr_matrix:
    """Pf^T A Pf for a symmetric A, as CSR: (A Pf)^T Pf, whose CSC arrays are the result's CSR arrays (no
    (nfree x ndof) intermediate Pf^T A and no format conversion)."""
    C = (A @ Pf).T @ Pf
    return sp.csr_matrix((C.data, C.indices, C.indptr), shape=C.shape)


def reduction(constraints, dirichlet, ndof: int):
    """``u = Pf x + offset`` over the free unknowns x: (Pf (ndof x nfree, CSC), offset (ndof,), the reduced
    unknowns whose reactions are reported, induced rank).  ``constraints`` None: the identity prolongation."""
    P = sp.identity(ndof, format="csr") if constraints is None else constraints.P
    nred = P.shape[1]
    dofs, g = dirichlet.dofs, dirichlet.values
    free = complement(nred, dofs)
    Pf, Pd = P[:, free].tocsc(), P[:, dofs].tocsc()
    offset = Pd @ g
    reaction_dofs, induced = dofs, 0
    if len(dirichlet.slave_rows):
        # slave DOFs on Dirichlet faces fix combinations of free unknowns: eliminate them
        Ps = P[dirichlet.slave_rows]
        rhs = dirichlet.slave_values - Ps[:, dofs] @ g
        T, x0, touched = induced_elimination(Ps[:, free], rhs)
        _refuse_conflicts(Ps[:, free] @ x0 - rhs, rhs, dirichlet, Ps, dofs)
        offset = offset + Pf @ x0
        Pf = (Pf @ T).tocsc()
        reaction_dofs = np.concatenate([dofs, free[touched]])
        induced = int(len(free) - T.shape[1])
    return Pf, offset, reaction_dofs, induced


def _refuse_conflicts(residual: np.ndarray, rhs: np.ndarray, dirichlet, Ps, dofs) -> None:
    """Slave Dirichlet rows that the constraints make contradictory (least squares would split the
    difference) are refused when the contradiction lies inside faces of two different conditions (a slave's
    own, and those of the prescribed unknowns it is tied to); along shared edges the least-squares mean is
    kept (the reading of data that jump along an edge)."""
    faces = dirichlet.slave_faces
    if not len(residual) or not faces:
        return
    bad = np.flatnonzero(np.abs(residual) > 1e-8 * max(float(np.abs(rhs).max()), TINY))
    Ps = sp.csr_matrix(Ps)
    names: set = set()
    for i in bad:
        if faces[i]:  # a slave inside its face: its own condition and those of the unknowns it is tied to
            names |= faces[i]
            for j in Ps.indices[Ps.indptr[i]:Ps.indptr[i + 1]]:
                names |= dirichlet.master_faces.get(int(j), frozenset())
    names = sorted(names)
    if len(names) >= 2:
        raise ProblemError(f"two Dirichlet conditions prescribe values that the interface constraints cannot both "
                           f"meet (off by up to {np.abs(residual[bad]).max():.3g}) where their faces lie on each "
                           f"other: {names[0]} and {names[1]}; give the overlap one condition (the tag algebra "
                           "helps: 'A - B')")


def solve_system(K, f, constraints, dirichlet, solver="auto", tol=1e-10, maxiter=None,
                 options: dict | None = None, keep: bool = False) -> SystemSolution:
    """Eliminate constraints and Dirichlet data from ``K u = f`` (K symmetric, as every form here), solve, expand.

    ``constraints``: :class:`iga.discretisation.constraints.Constraints` or None; ``dirichlet``:
    :class:`iga.discretisation.dirichlet.DirichletData`; ``options``: passed to :func:`solvers.solve` (the spline
    structure of :mod:`iga.discretisation.multilevel`).  K is consumed (it may be modified).  ``keep``: solve by a
    prepared solver (``solver`` one of :data:`_KEEPABLE`) kept in :attr:`SystemSolution.again`.
    """
    nred = K.shape[0] if constraints is None else constraints.P.shape[1]
    dofs, g = dirichlet.dofs, dirichlet.values
    free = complement(nred, dofs)
    reaction_dofs = dofs
    induced = 0
    if constraints is None:  # one unconstrained patch: eliminate by row and column selection
        Kd = K[reaction_dofs]  # rows needed for the reaction fluxes; K itself is consumed
        A, rhs = eliminate(K, f, free, dofs, g, in_place=True)
        del K
    else:
        Pf, offset, reaction_dofs, induced = reduction(constraints, dirichlet, K.shape[0])
        A = project_symmetric(K, Pf)  # (10-30% faster than Pf^T K Pf)
        rhs = Pf.T @ (f - K @ offset)
    options = dict(options or {})
    for key in ("near_nullspace", "node_slots"):  # per reduced unknown (nred, ...): restricted to the free ones
        value = options.pop(key, None)
        if value is not None and A.shape[0] == len(free):
            options[key] = np.asarray(value)[free]
    prepared = None
    if keep and solver in _KEEPABLE:  # one factorisation (or hierarchy) for this solve and the adjoint's
        prepared = solvers.prepare(A, solver, tol, maxiter)
        x, info = prepared(rhs)
        info = replace(info, setup_s=prepared.setup_s)
    else:
        x, info = solvers.solve(A, rhs, method=solver, tol=tol, maxiter=maxiter, overwrite_a=True,  # A is ours
                                **options)
    reduced = int(A.shape[0])
    if constraints is None:
        u = np.zeros(nred)
        u[dofs] = g
        u[free] = x
        reaction = Kd @ u - f[reaction_dofs]
        prescribed = u[reaction_dofs]
    else:
        u = Pf @ x + offset
        reaction = (constraints.P.T @ (K @ u - f))[reaction_dofs]
        owner = owners_of(constraints.dof_master, constraints.P.shape[1])[reaction_dofs]
        prescribed = u[owner] if np.all(owner >= 0) else None
    again = None
    if prepared is not None:
        if constraints is None:
            def again(load):  # noqa: E306 (the same system, another load, zero Dirichlet data)
                out = np.zeros(nred)
                out[free] = prepared(np.asarray(load, float)[free])[0]
                return out
        else:
            def again(load):  # noqa: E306
                return Pf @ prepared(Pf.T @ np.asarray(load, float))[0]
    return SystemSolution(u, reaction_dofs, reaction, info, reduced, induced, prescribed, again)
