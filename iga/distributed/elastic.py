"""The distributed elastic solve (``ElasticityProblem.solve(solver="petsc")`` under ``mpiexec -n R``).

Each rank assembles the stiffness, the body and thermal loads and the tractions of its own patches only (the
patches :func:`iga.distributed.solve.partition` gives it); the point loads and springs, which are cheap, are
formed on every rank and cut to its DOFs.  The constraints and the Dirichlet data are the whole model's on every
rank (as for heat where slot faces tie the model together), the DOFs are numbered component after component
as in a serial solve, and :func:`iga.distributed.solve.solve_system` reduces, distributes and solves with CG
and GAMG, given the six rigid modes at every reduced unknown as its near-nullspace (without them GAMG's
aggregates of scalar unknowns cannot represent rotations and its iterations grow with the model).  The
displacements are gathered on every rank; the load vector and the reactions are summed over the ranks, so the
:class:`iga.elasticity.solution.ElasticSolution` built from them is the serial one (work balance, face
forces, holds and springs included).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from iga.discretisation.multilevel import owners_of
from iga.distributed import solve as distributed

__all__ = ["ElasticShare", "share_of", "solve_elastic"]


class ElasticShare:
    """One rank's share of a distributed elastic solve: ``comm``, ``rank``, ``size``, ``part`` (the rank of
    every patch), ``patches`` (this rank's, a set) and ``own`` (its DOFs, component after component)."""

    def __init__(self, problem, world):
        self.comm, self.rank, self.size = world
        self.part = distributed.partition(problem, self.size)
        self.patches = set(np.flatnonzero(self.part == self.rank).tolist())
        self.offsets = problem.offsets
        self.own = distributed.owned_dofs(self.part, problem.offsets, self.rank, 3)

    def own_diagonal(self, S: sp.spmatrix) -> sp.csr_matrix:
        """The diagonal matrix ``S`` (springs) kept on this rank's DOFs only."""
        d = np.zeros(S.shape[0])
        d[self.own] = S.diagonal()[self.own]
        return sp.diags(d, format="csr")

    def whole(self, f: np.ndarray) -> np.ndarray:
        """The whole load vector from every rank's ``f`` (its own DOFs' entries are its own: the rest is summed
        from the other ranks)."""
        from mpi4py import MPI

        mine = np.zeros_like(f)
        mine[self.own] = f[self.own]
        out = np.empty_like(f)
        self.comm.Allreduce(mine, out, op=MPI.SUM)
        return out


def share_of(problem, solver: str) -> ElasticShare | None:
    """This rank's :class:`ElasticShare` for ``solver="petsc"`` under an MPI launcher, else None (serial)."""
    world = distributed.world() if solver == "petsc" else None
    return ElasticShare(problem, world) if world else None


def solve_elastic(share: ElasticShare, K, f, constraints, dd, tol, maxiter, modes):
    """(:class:`iga.discretisation.system.SystemSolution` with the reactions summed over the ranks, the whole
    load vector): the distributed solve of this rank's ``K`` (its patches' rows, the springs cut to its DOFs)
    and ``f``; ``modes`` the rigid modes at every reduced unknown (the near-nullspace)."""
    from mpi4py import MPI

    whole = share.whole(f)
    res = distributed.solve_system([K, f], constraints, dd, tol, maxiter, share.part, share.comm, share.offsets,
                                   components=3, modes=modes)
    reaction = np.empty_like(res.reaction)
    share.comm.Allreduce(np.ascontiguousarray(res.reaction), reaction, op=MPI.SUM)
    # the prescribed unknowns' values, read off the gathered displacements as the serial solve does
    owner = res.reaction_dofs if constraints is None else \
        owners_of(constraints.dof_master, constraints.P.shape[1])[res.reaction_dofs]
    prescribed = res.u[owner] if np.all(owner >= 0) else None
    return replace(res, reaction=reaction, prescribed=prescribed), whole
