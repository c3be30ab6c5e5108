"""Distributed assembly and solve on PETSc (petsc4py, MPI): ``mpiexec -n R iga run CONFIG.toml``.

With ``solver="petsc"`` under ``mpiexec -n R``, every rank builds the model and its spaces (replicated:
about 60 MiB of objects per rank for the 1M-unknown cross lattice; README), and assembles the volume terms
and the Neumann and Robin faces of its own patches only, then works in its own numbering (its DOFs, its
closure's constraints; only the gathered solution has the whole model's size).  Patches are partitioned by :func:`partition`: the patch
graph (an edge per interface) is ordered by reverse Cuthill-McKee (SciPy), which keeps neighbouring tiles
together, and cut into R consecutive parts of about equal unknowns.  Each rank builds the constraints its
own DOFs read on its patches and the few neighbours their classes reach, with the Dirichlet data of those
patches' faces (:mod:`iga.distributed.rank_setup`, :mod:`iga.distributed.rank_constraints`); the reduced unknowns are numbered by
owner, a class known on every rank by its smallest DOF and owned by the rank of that DOF's patch, so no
rank forms the whole prolongation (where Dirichlet slot faces tie unknowns of the whole model together,
every rank builds the whole model's constraints instead).  Each rank reduces its part,
``A_r = Pl^T K_r Pl`` (``sum_r A_r`` is the serial reduced matrix) over the unknowns its rows read.  The
rows of ``A_r`` that other ranks own are sent to them (one ``Alltoallv`` per array of their CSR rows:
:func:`_route_rows`), summed there, and the owned rows preallocate and fill the MPIAIJ matrix exactly
(``createAIJ(csr=...)``, the same in every petsc4py from 3.18 on; no triplets).  CG with GAMG solves it;
each rank asks the owners for the values of the unknowns it shares with them, expands its patches'
coefficients, and the coefficients are gathered on every rank by patch, so post-processing follows the
serial path (each rank writes its VTU piece, rank 0 the index and the summary).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from geometry.resources import usable_cores
from solvers import SolveInfo
from solvers.indexing import complement
from solvers.petsc_ksp import ksp_solve, near_nullspace, petsc

from iga.errors import ProblemError
from iga.app.memory import return_freed_memory
from iga.distributed.rank_constraints import alltoallv, local_prolongation, patch_pairs, ranges
from iga.discretisation.system import SystemSolution, reduction

__all__ = ["world", "launched", "load_petsc", "solve_world", "partition", "solve_system", "is_root", "mpiexec",
           "launch_env", "owned_dofs", "summed"]

# what an MPI launcher leaves in its children's environment: a process that inherits it (a test run, a script
# that once initialised PETSc as a singleton) would start its own mpiexec as a rank of the old job
_INHERITED = ("OMPI_", "PMIX_", "PMI_", "PRTE_", "HYDRA_", "MPIR_")


def world():
    """(communicator, rank, size) of the MPI world under an MPI launcher (``mpiexec -n 1`` too: one rank runs
    the same distributed path, so that its memory and time compare with more ranks) when mpi4py is
    installed; None otherwise (serial runs never import MPI)."""
    if not launched():
        return None
    try:
        from mpi4py import MPI
    except ImportError:
        return None
    comm = MPI.COMM_WORLD
    _share_cores(comm)
    return comm, comm.Get_rank(), comm.Get_size()


def launched() -> bool:
    """Whether this process was started by an MPI launcher (``mpiexec``): from its environment alone, without
    loading MPI."""
    import os

    return any(k in os.environ for k in ("PMI_RANK", "PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_RANK"))


def load_petsc():
    """petsc4py's ``PETSc`` module, with freed large arrays returned to the system once it is loaded
    (:func:`iga.app.memory.return_freed_memory`, replacing whatever the process had set, a
    :func:`iga.app.memory.retain_freed_memory` included): loading Debian's PETSc turns off the unmapping of freed
    arrays for the whole process, and a distributed solve is there to divide memory among ranks: 4 ranks of
    the 21^3 cross lattice peaked at 938-945 MiB per rank with it off, 870-876 MiB with it on, at the price of
    fresh page faults (their assembly took 2.9-4.2 s instead of 1.4-1.8 s on this VM, where fresh memory
    is slow to fault in)."""
    PETSc = petsc()
    return_freed_memory()
    return PETSc


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


def solve_world(solution):
    """(communicator, rank, size) of the distributed solve that gave ``solution`` (a heat or elastic solution
    whose record holds the partition of :func:`partition`), None for a serial solve's."""
    record = getattr(solution, "record", None)
    return world() if getattr(record, "partition", None) is not None else None


def summed(comm, values: dict) -> dict:
    """{key: the sum over the ranks of ``values[key]``} (numbers or arrays; keys a rank lacks count as zero)."""
    out: dict = {}
    for part in comm.allgather(values):
        for key, v in part.items():
            out[key] = out.get(key, 0.0) + v
    return out


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
    pairs, _ = patch_pairs(problem.model)
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    order = reverse_cuthill_mckee((G + G.T).tocsr(), symmetric_mode=True)
    sizes = np.diff(problem.offsets)[order].astype(float)
    cuts = np.searchsorted(np.cumsum(sizes), np.arange(1, size) * sizes.sum() / size)
    for k in range(size - 1):  # at least one patch per rank (a loop over ranks, not patches)
        cuts[k] = min(max(cuts[k], cuts[k - 1] + 1 if k else 1), n - (size - 1 - k))
    part = np.empty(n, np.int64)
    part[order] = np.searchsorted(cuts, np.arange(n), side="right")
    return part


def _route_rows(comm, A, b, gid, starts):
    """This rank's rows of the reduced system (``starts``: first global row of every rank) as a CSR matrix
    (``m x nfree``) and right-hand side, summed over the contributions of every rank.

    ``A`` (CSR, square) and ``b`` hold this rank's part of ``Pf^T K Pf`` and of the load over the reduced
    unknowns its rows read, numbered ``gid`` (sorted global numbers), in which every rank owns consecutive
    rows; the rows of each other rank form one contiguous range of ``A``'s entries, sent as it is (only the
    rows this rank touched, with their lengths: one ``Alltoallv`` per array).  No triplet arrays and no copy
    of the whole reduced matrix are made: the 21^3 cross lattice built its matrix at 2.9 GiB per rank on 2
    ranks by triplets.
    """
    rank = comm.Get_rank()
    nfree = int(starts[-1])
    # the columns in their own width (int32 below 2^31 unknowns): no widened copy of every local entry
    gidc = gid.astype(np.int32) if nfree < 2**31 else gid
    lengths = np.diff(A.indptr)
    touched = np.flatnonzero((lengths > 0) | (b != 0))
    cut = np.searchsorted(gid[touched], starts)  # touched rows of each rank: touched[cut[q]:cut[q + 1]]
    row_cut = np.searchsorted(gid, starts)  # local rows of each rank
    cut_nnz = A.indptr[row_cut]  # entries of each rank's rows: A.data[cut_nnz[q]:cut_nnz[q + 1]]
    rows_per, nnz_per = np.diff(cut), np.diff(cut_nnz)
    rows, _ = alltoallv(comm, gid[touched].astype(np.int64), rows_per, keep_own=False)
    lens, _ = alltoallv(comm, lengths[touched].astype(np.int64), rows_per, keep_own=False)
    rhs, _ = alltoallv(comm, np.asarray(b[touched], np.float64), rows_per, keep_own=False)
    cols, _ = alltoallv(comm, gidc[A.indices], nnz_per, keep_own=False)
    vals, _ = alltoallv(comm, np.asarray(A.data, np.float64), nnz_per, keep_own=False)
    lo, hi = int(starts[rank]), int(starts[rank + 1])
    a, e = int(row_cut[rank]), int(row_cut[rank + 1])  # this rank's own rows: local a..e = global lo..hi
    s, t = int(A.indptr[a]), int(A.indptr[e])
    local = sp.csr_matrix((A.data[s:t], gidc[A.indices[s:t]], A.indptr[a:e + 1] - s), shape=(hi - lo, nfree))
    if len(vals):  # this rank's own rows plus the rows the other ranks sent
        local = local + sp.csr_matrix((vals, (np.repeat(rows - lo, lens), cols)), shape=local.shape)
    local = sp.csr_matrix(local)
    local.sum_duplicates()
    local.sort_indices()
    own_b = np.asarray(b[a:e], np.float64) + np.bincount(rows - lo, rhs, minlength=hi - lo)
    return local, own_b


def _matrix(PETSc, comm, local, nfree, modes=None):
    """The MPIAIJ matrix whose rows on this rank are ``local`` (CSR, summed): preallocated exactly from the
    rows (``createAIJ(csr=...)``, in every petsc4py from 3.18 on); ``modes`` (its rows x k): the
    near-nullspace GAMG is given, or None."""
    m = local.shape[0]
    M = PETSc.Mat().createAIJ(size=((m, nfree), (m, nfree)), comm=comm,
                              csr=(local.indptr.astype(PETSc.IntType), local.indices.astype(PETSc.IntType),
                                   local.data))
    M.assemble()
    if modes is not None:
        M.setNearNullSpace(near_nullspace(PETSc, comm, modes, nfree))
    return M


def _columns(comm, Pf, constraints, dirichlet, part, offsets, rc, own, components=1):
    """(``Pl``, :class:`iga.distributed.rank_constraints.GlobalColumns`): the rows ``own`` of ``Pf`` (this rank's DOFs)
    over the reduced unknowns they read, numbered globally.  ``rc`` (:class:`iga.distributed.rank_constraints.
    RankConstraints`) given: ``constraints`` are this rank's, in its closure numbering, a class is known by
    its smallest global DOF and owned by the rank of that DOF's patch; None: the whole model's, a column is
    known by its index and owned by the lowest rank whose patches touch it (``components``: the DOFs are that many
    copies of the patches' DOFs, one per field component, :mod:`iga.elasticity`)."""
    if rc is not None:
        free = complement(constraints.P.shape[1], dirichlet.dofs)
        keys = rc.keys()[free]
        owner = part[np.searchsorted(offsets, keys, side="right") - 1]  # the rank of the key's patch
        return local_prolongation(comm, Pf, keys, owner, own)
    dof_rank = np.tile(np.repeat(part, np.diff(offsets)), components)
    Pc = sp.csc_matrix(Pf)
    touched = np.diff(Pc.indptr) > 0
    owner = np.zeros(Pf.shape[1], np.int64)
    owner[touched] = np.minimum.reduceat(dof_rank[Pc.indices], Pc.indptr[:-1][touched])
    del Pc
    return local_prolongation(comm, Pf, np.arange(Pf.shape[1]), owner, own)


def _own_block(K, own: np.ndarray) -> sp.csr_matrix:
    """K (CSR, ndof x ndof, entries only in the rows and columns ``own``: this rank's patches, whose blocks
    do not couple) as the own x own matrix, in K's own data and column arrays (renumbered in place):
    no copy of the stiffness and no array of the whole model's size is kept."""
    indptr = np.concatenate([[0], K.indptr[own + 1]]).astype(K.indptr.dtype)
    if indptr[-1] != K.nnz:
        raise ProblemError("the stiffness of this rank holds entries outside its patches; report this model")
    loc = np.full(K.shape[0], -1, K.indices.dtype)
    loc[own] = np.arange(len(own), dtype=K.indices.dtype)
    step = 1 << 22
    for s in range(0, K.nnz, step):  # in place, a slab at a time (no second index array)
        K.indices[s:s + step] = loc[K.indices[s:s + step]]
    return sp.csr_matrix((K.data, K.indices, indptr), shape=(len(own), len(own)))


def owned_dofs(part, offsets, rank: int, components: int = 1) -> np.ndarray:
    """The DOFs of ``rank``'s patches, in the numbering of ``components`` fields one after the other (heat 1,
    elasticity 3: component-major), component by component."""
    mine = np.flatnonzero(part == rank)
    dofs = ranges(offsets[mine], offsets[mine + 1])
    return np.concatenate([dofs + a * int(offsets[-1]) for a in range(components)])


def _owned_modes(modes, constraints, dirichlet, n: int, cols, rank: int) -> np.ndarray:
    """The rows of ``modes`` (one per reduced unknown of ``constraints``, or per DOF of n without them) at this
    rank's rows of the matrix: the free unknowns it owns (global numbers ``lo .. hi - 1``, in order)."""
    free = complement(n if constraints is None else constraints.P.shape[1], dirichlet.dofs)
    lo, hi = cols.starts[rank], cols.starts[rank + 1]
    return np.asarray(modes)[free][cols.source[(cols.gid >= lo) & (cols.gid < hi)]]


def _allgather_patches(comm, u_own, part, offsets, components=1) -> np.ndarray:
    """The whole coefficient vector from every rank's values on its own patches, ``u_own`` (one
    ``Allgatherv``)."""
    idx = [owned_dofs(part, offsets, q, components) for q in range(comm.Get_size())]
    counts = [len(i) for i in idx]
    buf = np.empty(int(sum(counts)))
    comm.Allgatherv(np.ascontiguousarray(u_own, np.float64), [buf, counts])
    out = np.empty(int(offsets[-1]) * components)
    out[np.concatenate(idx)] = buf
    return out


def solve_system(system: list, constraints, dirichlet, tol, maxiter, part, comm, offsets, pc: str = "gamg",
                 petsc_options=None, rc=None, components: int = 1, modes=None) -> SystemSolution:
    """The distributed twin of :func:`iga.discretisation.system.solve_system`: ``system`` = [K, f] holds this rank's patches
    only (``part``: the rank of every patch, ``offsets``: the patches' first DOFs); the list is emptied, and
    K and f are cut to this rank's DOFs at once (K in its own arrays) and released once the reduced matrix
    is built (only the rows that the reactions read are kept), so that GAMG's set-up does not stand on
    them.  ``rc``: this rank's constraints (:mod:`iga.distributed.rank_constraints`; ``constraints`` and ``dirichlet``
    then in its closure numbering), or None when ``constraints`` are the whole model's.  The reaction
    returned is this rank's part (its rows of ``K u - f``): the sum over the ranks is the serial one.
    ``components``: DOFs numbered field component after component (elasticity: 3; then ``rc`` must be None);
    ``modes`` (reduced unknowns x k): the near-nullspace GAMG coarsens with (elasticity: the rigid modes at
    each reduced unknown, :func:`iga.elasticity.rigid.rigid_modes`), restricted here to the free ones."""
    PETSc = load_petsc()

    rank, size = comm.Get_rank(), comm.Get_size()
    own_g = owned_dofs(part, offsets, rank, components)  # this rank's DOFs, global numbers
    K, f = system
    system.clear()
    K, f = _own_block(K, own_g), np.asarray(f[own_g])
    n = len(rc.rows) if rc is not None else int(offsets[-1]) * components  # the numbering of the constraints' rows
    own = rc.own if rc is not None else own_g  # this rank's DOFs in it
    t0 = time.perf_counter()
    Pf, offset, reaction_dofs, induced = reduction(constraints, dirichlet, n)
    offset = offset[own]
    Pl, cols = _columns(comm, Pf, constraints, dirichlet, part, offsets, rc, own, components)
    if modes is not None:
        modes = _owned_modes(modes, constraints, dirichlet, n, cols, rank)
    del Pf  # one copy of the prolongation is kept through the solve: this rank's rows, Pl
    t_reduction = time.perf_counter() - t0
    nfree = int(cols.starts[-1])
    counts = np.diff(cols.starts)
    # K is symmetric, so (K Pl)^T Pl = A, and its CSC arrays are A's CSR arrays: no transposed copies
    C = (K @ Pl).T @ Pl
    A = sp.csr_matrix((C.data, C.indices, C.indptr), shape=C.shape)
    load = Pl.T @ (f - K @ offset)
    del C
    P = sp.identity(n, format="csr") if constraints is None else constraints.P
    P = sp.csr_matrix(P[own])
    # the rows of the DOFs whose classes' reactions are reported: a surface's worth of K
    read = np.flatnonzero(np.diff(sp.csr_matrix(P[:, reaction_dofs]).indptr))
    Kd, Pd, fd = K[read], P[read], f[read]
    del K, f, P
    local, rhs = _route_rows(comm, A, load, cols.gid, cols.starts)
    del A, load
    M = _matrix(PETSc, comm, local, nfree, modes)
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
    x_owned = x.getArray().copy()
    for obj in (M, b, x, r):
        obj.destroy()
    finite = comm.allreduce(bool(np.all(np.isfinite(x_owned))), op=_land())
    if reason < 0 or res > 10 * tol or not finite:
        raise ProblemError(f"PETSc CG on {size} ranks did not converge (reason {reason}): relative residual "
                           f"{res:.2e} after {its} iterations")
    u = Pl @ cols.gather(comm, x_owned) + offset  # this rank's DOFs
    reaction = np.ascontiguousarray((Pd.T @ (Kd @ u - fd))[reaction_dofs])  # this rank's rows: Solution sums
    u = _allgather_patches(comm, u, part, offsets, components)
    info = SolveInfo(f"petsc ({pc}, {size} ranks)", its, res, setup + t_build, solve_s,
                     {"ranks": size, "owned_unknowns": counts.tolist(), "reduction_s": t_reduction,
                      "matrix_s": t_build - t_reduction, "ksp_setup_s": setup,
                      "constraints": "per rank" if rc is not None else "replicated"})
    return SystemSolution(u, reaction_dofs, reaction, info, nfree, induced)


def _land():
    from mpi4py import MPI

    return MPI.LAND
