"""Distributed assembly and solve on PETSc (petsc4py, MPI): ``mpiexec -n R iga run CONFIG.toml``.

With ``solver="petsc"`` under ``mpiexec -n R``, every rank
builds the model, its spaces, the constraint prolongation and the Dirichlet
data (replicated: about 300 MiB per rank of the 1M-unknown cross lattice,
the part of its memory that does not fall as 1/R; README), and assembles the
volume terms and the Neumann and Robin faces of its own patches only.  Patches are partitioned
by :func:`partition`: the patch graph (an edge per interface) is ordered by
reverse Cuthill-McKee (SciPy), which keeps neighbouring tiles together, and
cut into R consecutive parts of about equal unknowns.  Each rank reduces its
part, ``A_r = Pf^T K_r Pf`` (``sum_r A_r`` is the serial reduced matrix), in a numbering of the reduced
unknowns in which each rank owns, as consecutive rows, those its patches touch first.  The rows of
``A_r`` that other ranks own are sent to them (one ``Alltoallv`` per array of their CSR rows:
:func:`_route_rows`), summed there, and the owned rows preallocate and fill the MPIAIJ matrix exactly
(``createAIJ(csr=...)``, the same in every petsc4py from 3.18 on; no triplets).  CG with GAMG solves it; the
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

__all__ = ["world", "solve_world", "partition", "solve_system", "is_root", "mpiexec", "launch_env"]

# what an MPI launcher leaves in its children's environment: a process that inherits it (a test run, a script
# that once initialised PETSc as a singleton) would start its own mpiexec as a rank of the old job
_INHERITED = ("OMPI_", "PMIX_", "PMI_", "PRTE_", "HYDRA_", "MPIR_")


def world():
    """(communicator, rank, size) of the MPI world under an MPI launcher (``mpiexec -n 1`` too: one rank runs
    the same distributed path, so that its memory and time compare with more ranks) when mpi4py is
    installed; None otherwise (serial runs never import MPI)."""
    import os

    if not any(k in os.environ for k in ("PMI_RANK", "PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_RANK")):
        return None
    try:
        from mpi4py import MPI
    except ImportError:
        return None
    comm = MPI.COMM_WORLD
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


def mpiexec() -> str | None:
    """The ``mpiexec`` to start ranks with: the one beside this Python (a virtual environment's, e.g. MPICH
    from pip), else the one on PATH (a distribution's Open MPI or MPICH), else None."""
    import shutil
    import sys
    from pathlib import Path

    beside = Path(sys.executable).parent / "mpiexec"
    return str(beside) if beside.is_file() else shutil.which("mpiexec")


def launch_env(base=None) -> dict:
    """An environment for starting ``mpiexec`` from Python, for either MPI family.

    The variables an MPI job left in ``base`` (default ``os.environ``) are
    dropped (under Open MPI a child ``mpiexec`` would otherwise exit 1
    without a word once this process had initialised MPI); Open MPI is
    allowed to run as root (containers, CI) and to place more ranks than
    cores (4 ranks on 2 cores).  MPICH ignores the Open MPI settings and
    oversubscribes by itself.
    """
    import os

    env = {k: v for k, v in (os.environ if base is None else base).items() if not k.startswith(_INHERITED)}
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")
    return env


def solve_world(problem):
    """(communicator, rank, size) of the distributed solve that gave ``problem`` its last solution (one
    partitioned by :func:`partition`), None after a serial solve."""
    return world() if getattr(problem, "partition", None) is not None else None


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


def _route_rows(comm, A, b, starts):
    """This rank's rows of the reduced system (``starts``: first global row of every rank) as a CSR matrix
    (``m x nfree``) and right-hand side, summed over the contributions of every rank.

    ``A`` (CSR, ``nfree x nfree``) and ``b`` (``nfree``) hold this rank's part of ``Pf^T K Pf`` and of the
    load in the global numbering, in which every rank owns consecutive rows; the rows of each other rank form
    one contiguous range of ``A``'s entries, sent as it is (only the rows this rank touched, with their
    lengths: one ``Alltoallv`` per array).  No triplet arrays and no copy of the whole reduced matrix are
    made: the 21^3 cross lattice built its matrix at 2.9 GiB per rank on 2 ranks by triplets.
    """
    from mpi4py import MPI

    rank, size = comm.Get_rank(), comm.Get_size()
    lengths = np.diff(A.indptr)
    touched = np.flatnonzero((lengths > 0) | (b != 0))
    cut = np.searchsorted(touched, starts)  # touched rows of each rank: touched[cut[q]:cut[q + 1]]
    cut_nnz = A.indptr[starts]  # entries of each rank's rows: A.data[cut_nnz[q]:cut_nnz[q + 1]]
    mine = np.zeros(size, bool)
    mine[rank] = True

    def exchange(a, counts, mpi_type):
        """Every rank's part of ``a`` except this rank's own (counts per destination), to its owner."""
        send = np.where(mine, 0, counts).astype(np.int64)
        recv = np.asarray(comm.alltoall(send.tolist()), np.int64)
        sdisp = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        rdisp = np.concatenate([[0], np.cumsum(recv)[:-1]]).astype(np.int64)
        out = np.empty(int(recv.sum()), a.dtype)
        comm.Alltoallv([np.ascontiguousarray(a), (send, sdisp), mpi_type], [out, (recv, rdisp), mpi_type])
        return out

    rows_per = np.diff(cut)
    nnz_per = np.diff(cut_nnz)
    rows = exchange(touched.astype(np.int64), rows_per, MPI.INT64_T)
    lens = exchange(lengths[touched].astype(np.int64), rows_per, MPI.INT64_T)
    rhs = exchange(np.asarray(b[touched], np.float64), rows_per, MPI.DOUBLE)
    # the columns in their own width (int32 below 2^31 unknowns): no widened copy of every local entry
    cols = exchange(A.indices, nnz_per, MPI.INT32_T if A.indices.dtype == np.int32 else MPI.INT64_T)
    vals = exchange(np.asarray(A.data, np.float64), nnz_per, MPI.DOUBLE)
    lo, hi = int(starts[rank]), int(starts[rank + 1])
    s, e = int(A.indptr[lo]), int(A.indptr[hi])
    local = sp.csr_matrix((A.data[s:e], A.indices[s:e], A.indptr[lo:hi + 1] - s), shape=(hi - lo, A.shape[1]))
    if len(vals):  # views of A's own rows (no copy) plus the rows the other ranks sent
        local = local + sp.csr_matrix((vals, (np.repeat(rows - lo, lens), cols)), shape=local.shape)
    local = sp.csr_matrix(local)
    local.sum_duplicates()
    local.sort_indices()
    own_b = np.asarray(b[lo:hi], np.float64) + np.bincount(rows - lo, rhs, minlength=hi - lo)
    return local, own_b


def _matrix(PETSc, comm, local, nfree):
    """The MPIAIJ matrix whose rows on this rank are ``local`` (CSR, summed): preallocated exactly from the
    rows (``createAIJ(csr=...)``, in every petsc4py from 3.18 on)."""
    m = local.shape[0]
    M = PETSc.Mat().createAIJ(size=((m, nfree), (m, nfree)), comm=comm,
                              csr=(local.indptr.astype(PETSc.IntType), local.indices.astype(PETSc.IntType),
                                   local.data))
    M.assemble()
    return M


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
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    Pn = sp.csr_matrix(Pf)  # columns relabelled to the owners' numbering (a permutation of the unknowns)
    Pn = sp.csr_matrix((Pn.data, new[Pn.indices], Pn.indptr), shape=Pn.shape)
    del Pf, Pc, dof_rank  # one copy of the prolongation is kept through the solve: Pn
    # K is symmetric, so (K Pn)^T Pn = A, and its CSC arrays are A's CSR arrays: no transposed copies
    C = (K @ Pn).T @ Pn
    A = sp.csr_matrix((C.data, C.indices, C.indptr), shape=C.shape)
    load = Pn.T @ (f - K @ offset)
    del C
    local, rhs = _route_rows(comm, A, load, starts)
    del A, load
    M = _matrix(PETSc, comm, local, nfree)
    del local
    b = PETSc.Vec().createMPI((int(counts[rank]), nfree), comm=comm)
    b.setArray(rhs)
    x = b.duplicate()
    t_build = time.perf_counter() - t0
    its, reason, setup, solve_s = ksp_solve(M, b, x, tol, maxiter if maxiter else 1000, pc, petsc_options)
    r = b.duplicate()
    M.mult(x, r)
    r.axpy(-1.0, b)
    nb = b.norm()
    res = float(r.norm() / (nb if nb > 0 else 1.0))
    xs = np.concatenate(comm.allgather(x.getArray().copy()))  # in the owners' numbering, as Pn's columns
    for obj in (M, b, x, r):
        obj.destroy()
    if reason < 0 or res > 10 * tol or not np.all(np.isfinite(xs)):
        raise ProblemError(f"PETSc CG on {size} ranks did not converge (reason {reason}): relative residual "
                           f"{res:.2e} after {its} iterations")
    u = Pn @ xs + offset
    P = sp.identity(ndof, format="csr") if constraints is None else constraints.P
    reaction = np.ascontiguousarray((P.T @ (K @ u - f))[reaction_dofs])
    comm.Allreduce(MPI.IN_PLACE, reaction, op=MPI.SUM)
    info = SolveInfo(f"petsc ({pc}, {size} ranks)", its, res, setup + t_build, solve_s,
                     {"ranks": size, "owned_unknowns": counts.tolist(), "reduction_s": t_reduction,
                      "matrix_s": t_build - t_reduction, "ksp_setup_s": setup})
    return SystemSolution(u, reaction_dofs, reaction, info, nfree, induced)

