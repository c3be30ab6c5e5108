"""Distributed assembly and solve on PETSc (petsc4py, MPI): ``mpiexec -n R iga run CONFIG.toml``.

With ``solver="petsc"`` under ``mpiexec`` with R > 1 ranks, every rank
builds the model, its spaces, the constraint prolongation and the Dirichlet
data (replicated: they are small beside the matrix), and assembles the
volume and boundary terms of its own patches only.  Patches are partitioned
by :func:`partition`: the patch graph (an edge per interface) is ordered by
reverse Cuthill-McKee (SciPy), which keeps neighbouring tiles together, and
cut into R consecutive parts of about equal unknowns.  Each rank reduces its
part, ``A_r = Pf^T K_r Pf`` (``sum_r A_r`` is the serial reduced matrix), and
PETSc assembles the MPIAIJ matrix from the ranks' COO triplets (off-rank
rows are communicated by PETSc); the reduced unknowns are numbered so that
each rank owns those its patches touch first.  CG with GAMG solves it; the
solution is gathered on every rank, so post-processing and output follow
the serial path (rank 0 writes).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from geometry.resources import usable_cores
from solvers import SolveInfo
from solvers.petsc_ksp import ksp_solve, petsc

from .errors import ProblemError
from .system import SystemSolution, reduction

__all__ = ["world", "partition", "solve_system", "is_root"]


def world():
    """(communicator, rank, size) of the MPI world when it has more than one rank and petsc4py is installed;
    None otherwise (serial runs never import MPI)."""
    import os

    if not any(k in os.environ for k in ("PMI_RANK", "PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_RANK")):
        return None
    try:
        from mpi4py import MPI
    except ImportError:
        return None
    comm = MPI.COMM_WORLD
    if comm.Get_size() == 1:
        return None
    _share_cores(comm)
    return comm, comm.Get_rank(), comm.Get_size()


def _share_cores(comm) -> None:
    """Give each rank its share of the node's cores for the compiled (numba) kernels: ranks x threads
    above the core count made the assembly 20x slower (threads of different ranks wait on each other).
    Idempotent (the thread count is the process's), so every call of :func:`world` may run it."""
    import importlib.util

    if importlib.util.find_spec("numba") is None:
        return
    import numba
    from mpi4py import MPI

    local = comm.Split_type(MPI.COMM_TYPE_SHARED).Get_size()
    numba.set_num_threads(max(1, min(numba.config.NUMBA_NUM_THREADS, usable_cores() // local)))


def is_root() -> bool:
    """Whether this process writes output and prints (rank 0, or a serial run)."""
    w = world()
    return w is None or w[1] == 0


def partition(problem, size: int) -> np.ndarray:
    """The rank of every patch: reverse Cuthill-McKee order of the patch graph, cut into ``size`` parts of
    about equal unknowns."""
    n = len(problem.model.patches)
    if size > n:
        raise ProblemError(f"{size} MPI ranks for {n} patch{'' if n == 1 else 'es'}: every rank needs at least one "
                           f"patch; run with mpiexec -n {n} or fewer")
    pairs = np.array([(i.a[0], i.b[0]) for i in problem.model.interfaces], dtype=np.int64).reshape(-1, 2)
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    order = reverse_cuthill_mckee((G + G.T).tocsr(), symmetric_mode=True)
    sizes = np.diff(problem.offsets)[order].astype(float)
    cuts = np.searchsorted(np.cumsum(sizes), np.arange(1, size) * sizes.sum() / size)
    for k in range(size - 1):  # at least one patch per rank (a loop over ranks, not patches)
        cuts[k] = min(max(cuts[k], cuts[k - 1] + 1 if k else 1), n - (size - 1 - k))
    part = np.empty(n, np.int64)
    part[order] = np.searchsorted(cuts, np.arange(n), side="right")
    return part


def solve_system(K, f, constraints, dirichlet, tol, maxiter, part, comm, offsets, pc: str = "gamg",
                 petsc_options=None) -> SystemSolution:
    """The distributed twin of :func:`iga.system.solve_system`: K and f hold this rank's patches only
    (``part``: the rank of every patch, ``offsets``: the patches' first DOFs)."""
    PETSc = petsc()
    from mpi4py import MPI

    rank, size = comm.Get_rank(), comm.Get_size()
    ndof = K.shape[0]
    t0 = time.perf_counter()
    Pf, offset, reaction_dofs, induced = reduction(constraints, dirichlet, ndof)
    t_reduction = time.perf_counter() - t0  # replicated: every rank forms the whole prolongation
    nfree = Pf.shape[1]
    # owner of a reduced unknown: the lowest rank whose patches touch it; number unknowns by owner
    dof_rank = np.repeat(part, np.diff(offsets))
    Pc = Pf.tocsc()
    touched = np.diff(Pc.indptr) > 0
    owner = np.zeros(nfree, np.int64)
    owner[touched] = np.minimum.reduceat(dof_rank[Pc.indices], Pc.indptr[:-1][touched])
    order = np.argsort(owner, kind="stable")
    new = np.empty(nfree, np.int64)
    new[order] = np.arange(nfree)
    counts = np.bincount(owner, minlength=size)
    lo = int(counts[:rank].sum())
    A = (Pf.T @ K @ Pf).tocoo()
    rhs = np.ascontiguousarray(Pf.T @ (f - K @ offset))
    comm.Allreduce(MPI.IN_PLACE, rhs, op=MPI.SUM)
    rhs = rhs[order]
    M = PETSc.Mat().create(comm=comm)
    M.setSizes(((int(counts[rank]), nfree), (int(counts[rank]), nfree)))
    M.setType("aij")
    M.setPreallocationCOO(new[A.row].astype(PETSc.IntType), new[A.col].astype(PETSc.IntType))
    M.setValuesCOO(A.data, addv=PETSc.InsertMode.ADD_VALUES)
    M.assemble()
    b = PETSc.Vec().createMPI((int(counts[rank]), nfree), comm=comm)
    b.setArray(rhs[lo:lo + counts[rank]])
    x = b.duplicate()
    t_build = time.perf_counter() - t0
    its, reason, setup, solve_s = ksp_solve(M, b, x, tol, maxiter if maxiter else 1000, pc, petsc_options)
    r = b.duplicate()
    M.mult(x, r)
    r.axpy(-1.0, b)
    nb = b.norm()
    res = float(r.norm() / (nb if nb > 0 else 1.0))
    xs = np.concatenate(comm.allgather(x.getArray().copy()))[new]
    for obj in (M, b, x, r):
        obj.destroy()
    if reason < 0 or res > 10 * tol or not np.all(np.isfinite(xs)):
        raise ProblemError(f"PETSc CG on {size} ranks did not converge (reason {reason}): relative residual "
                           f"{res:.2e} after {its} iterations")
    u = Pf @ xs + offset
    P = sp.identity(ndof, format="csr") if constraints is None else constraints.P
    reaction = np.ascontiguousarray((P.T @ (K @ u - f))[reaction_dofs])
    comm.Allreduce(MPI.IN_PLACE, reaction, op=MPI.SUM)
    info = SolveInfo(f"petsc ({pc}, {size} ranks)", its, res, setup + t_build, solve_s,
                     {"ranks": size, "owned_unknowns": counts.tolist(), "reduction_s": t_reduction,
                      "matrix_s": t_build - t_reduction, "ksp_setup_s": setup})
    return SystemSolution(u, reaction_dofs, reaction, info, nfree, induced)

