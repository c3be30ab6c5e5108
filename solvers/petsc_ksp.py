"""PETSc's Krylov solvers (KSP) behind the backend interface, serial or on an MPI communicator.

``petsc4py`` is optional (extra ``[mpi]``); without it the ``petsc`` backend
says how to install it.  Defaults: conjugate gradients with PETSc's algebraic
multigrid (``pc="gamg"``; ``"hypre"`` for BoomerAMG when PETSc was built with
hypre), relative tolerance ``tol``.  ``petsc_options`` are passed through as
PETSc options (e.g. ``{"pc_gamg_threshold": 0.02, "ksp_monitor": None}``),
applied after the defaults, so they win.
"""

from __future__ import annotations

import time

import numpy as np

from geometry.numbers import TINY

from .errors import SolverError

INSTALL = ("the 'petsc' solver needs petsc4py: pip install -e \".[mpi]\" (builds PETSc from source, about 30 "
           "minutes on 2 cores; see the README for the faster route with a system PETSc)")


def petsc():
    """The ``petsc4py.PETSc`` module, or :class:`SolverError` with the install command."""
    try:
        from petsc4py import PETSc
    except ImportError:
        raise SolverError(INSTALL) from None
    return PETSc


def ksp_solve(M, b_vec, x_vec, tol: float, maxiter: int, pc: str = "gamg", petsc_options=None):
    """CG on the assembled PETSc matrix ``M``; returns (iterations, converged reason, set-up s, solve s)."""
    PETSc = petsc()
    ksp = PETSc.KSP().create(comm=M.getComm())
    ksp.setOperators(M)
    ksp.setType("cg")
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)  # rtol on the true residual, as the other backends
    try:
        ksp.getPC().setType(pc)
    except PETSc.Error as exc:
        raise SolverError(f"PETSc has no preconditioner {pc!r} ({exc}); use pc='gamg' (built in) or a PETSc "
                          "built with --download-hypre for 'hypre'") from None
    ksp.setTolerances(rtol=tol, atol=0.0, max_it=int(maxiter))
    opts = PETSc.Options()
    given = {str(key).lstrip("-"): "" if value is None else str(value) for key, value in (petsc_options or {}).items()}
    before = {key: opts.getString(key) if opts.hasName(key) else None for key in given}
    for key, value in given.items():
        opts[key] = value
    added = _gamg_defaults(PETSc, opts, pc)
    t0 = time.perf_counter()
    try:
        ksp.setFromOptions()
        ksp.setUp()  # the multigrid levels' smoothers read their options (mg_levels_*) here
    finally:
        # this solve's options only: the options database is the process's, and a later solve must not
        # inherit them (a second call with other petsc_options used to run with the first call's still set)
        for key in added:
            opts.delValue(key)
        for key, value in before.items():
            if value is None:
                opts.delValue(key)
            else:
                opts[key] = value
    t1 = time.perf_counter()
    ksp.solve(b_vec, x_vec)
    t2 = time.perf_counter()
    reason = ksp.getConvergedReason()
    its = ksp.getIterationNumber()
    ksp.destroy()
    return its, reason, t1 - t0, t2 - t1


def near_nullspace(PETSc, comm, modes: np.ndarray, n: int):
    """The ``MatNullSpace`` of the k columns of ``modes`` (this rank's rows, in order, of an n-row matrix on the
    mpi4py communicator ``comm``; None: one process), for ``Mat.setNearNullSpace``: GAMG builds its coarse
    spaces from it (elasticity: the six rigid modes).  PETSc asks for orthonormal vectors: they come from the
    eigen-decomposition of the k x k Gram matrix summed over the ranks, dropping directions whose eigenvalue
    is below 1e-10 of the largest (a mode that the others already span)."""
    modes = np.asarray(modes, float)
    gram = modes.T @ modes
    if comm is not None:  # (None: one process)
        from mpi4py import MPI

        gram = comm.allreduce(gram, op=MPI.SUM)
    else:
        comm = PETSc.COMM_SELF
    w, V = np.linalg.eigh(gram)
    keep = w > 1e-10 * max(float(w.max()), TINY)
    basis = modes @ (V[:, keep] / np.sqrt(w[keep]))  # orthonormal columns over the ranks
    vectors = []
    for j in range(basis.shape[1]):
        v = PETSc.Vec().createMPI((basis.shape[0], n), comm=comm)
        v.setArray(np.ascontiguousarray(basis[:, j]))
        vectors.append(v)
    return PETSc.NullSpace().create(vectors=vectors, comm=comm)


def _gamg_defaults(PETSc, opts, pc: str) -> list:
    """Defaults of ours for GAMG that the user's options (``petsc_options``, ``PETSC_OPTIONS``) did not set;
    returns the keys added.

    GAMG coarsens its first level aggressively by default: from PETSc 3.19 on by MIS-2 on the squared graph
    (``pc_gamg_aggressive_coarsening``), before by squaring the graph (``pc_gamg_square_graph``).  On our
    operators (125-343 non-zeros a row) that graph is dear and the coarsening too coarse, so both are
    turned off.  PETSc 3.26, refined demo sink, one rank: 85 -> 65 CG iterations, matrix + set-up 9.3 ->
    7.2 s, peak 1.88 -> 1.60 GiB; the 1M-unknown lattice 17.8 -> 15.0 s, 3.31 -> 2.98 GiB.  PETSc 3.18,
    the sink on 4 ranks: 95 -> 63 iterations, CG 4.8 -> 3.3 s, peak unchanged; the lattice on 4 ranks
    14 iterations either way (``benchmarks/mpi_scaling.py --case``, with ``PETSC_OPTIONS``).
    """
    if pc != "gamg":
        return []
    key = "pc_gamg_aggressive_coarsening" if PETSc.Sys.getVersion() >= (3, 19, 0) else "pc_gamg_square_graph"
    if opts.hasName(key):
        return []
    opts[key] = "0"
    return [key]


def serial(A, b, tol, maxiter, pc="gamg", petsc_options=None, modes=None):
    """Solve with PETSc on one process: (x, iterations, reason, set-up s, solve s); ``modes`` (n, k): the
    near-nullspace GAMG coarsens with (elasticity: the rigid modes), or None."""
    PETSc = petsc()
    A = A.tocsr()
    M = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType),
                                                  A.data), comm=PETSc.COMM_SELF)
    M.assemble()
    if modes is not None:
        M.setNearNullSpace(near_nullspace(PETSc, None, modes, A.shape[0]))
    x = np.zeros_like(b)
    bv, xv = PETSc.Vec().createWithArray(np.array(b, float), comm=PETSc.COMM_SELF), \
        PETSc.Vec().createWithArray(x, comm=PETSc.COMM_SELF)
    its, reason, setup, solve = ksp_solve(M, bv, xv, tol, maxiter, pc, petsc_options)
    x = xv.getArray().copy()
    M.destroy()
    return x, its, reason, setup, solve
