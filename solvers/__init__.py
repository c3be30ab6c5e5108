"""Linear solvers behind one backend-neutral interface (sparse matrices only).

This package knows nothing about splines: a symmetric positive (semi-)definite
sparse matrix, a right-hand side and options go in; a solution vector and a
:class:`SolveInfo` come out.  Backends are registered by name, so a
distributed backend (PETSc) can be added without touching the callers:

    >>> import numpy as np, scipy.sparse as sp
    >>> from solvers import solve
    >>> A = sp.diags([[-1.0] * 9, [2.0] * 10, [-1.0] * 9], [-1, 0, 1], format="csr")
    >>> x, info = solve(A, np.ones(10), method="cg", tol=1e-12)
    >>> info.method, bool(np.allclose(A @ x, 1.0))
    ('cg', True)

Built-in backends
-----------------
``direct``   SciPy SuperLU (CHOLMOD via scikit-sparse when installed).
``amg-cg``   conjugate gradients preconditioned by smoothed-aggregation AMG (pyamg's hierarchy,
             the V-cycle of :mod:`solvers.amg`); strongly coupled unknowns (thin features) are
             relaxed together (:mod:`solvers.clusters`; option ``block_theta``, None to turn it off).
``cg``       conjugate gradients with a Jacobi preconditioner (for comparison).
``fd-cg``    conjugate gradients preconditioned by fast diagonalization (:mod:`solvers.kronecker`); needs
             the option ``kronecker`` (a :class:`solvers.kronecker.KroneckerSum` close to A, or a list
             of them, one per diagonal block of A: block fast diagonalization).
``gmg-cg``   conjugate gradients preconditioned by a geometric multigrid V-cycle (:mod:`solvers.multigrid`);
             needs the option ``prolongations`` (sparse matrices, finest level first).
``petsc``    PETSc's CG with GAMG (or hypre) when petsc4py is installed (extra ``[mpi]``); under
             ``mpiexec`` :mod:`iga.distributed.solve` assembles and solves across the ranks.
``auto``     ``direct`` up to :data:`AUTO_DIRECT_LIMIT` unknowns (or the option ``direct_limit``); above,
             ``fd-cg`` when a ``kronecker``
             option is given, else ``amg-cg``.
"""

from __future__ import annotations

import importlib.util
import time
from typing import Callable

import numpy as np
import scipy.sparse as sp

from . import clusters
from .info import SolveInfo
from .krylov import checked_direct, factorise, preconditioned_cg, relative_residual
from .prepared import PreparedSolver, prepare
from .errors import SolverError
from geometry.errors import show
from geometry.numbers import is_flag, is_integer, is_real

__all__ = ["SolverError", "SolveInfo", "solve", "register", "backends", "AUTO_DIRECT_LIMIT", "prepare",
           "PreparedSolver"]

#: Above this many unknowns ``auto`` leaves the direct solver: SuperLU fills in badly on one 3-D IGA patch
#: (docs/performance.md).  A caller whose system fills in less passes its own ``direct_limit``.
AUTO_DIRECT_LIMIT = 2_000


_BACKENDS: dict[str, Callable] = {}
_OPTIONS: dict[str, set] = {}
COMMON_OPTIONS = {"overwrite_a"}


def register(name: str, fn: Callable | None = None, options=()):
    """Register ``fn(A, b, tol, maxiter, **options) -> (x, SolveInfo)`` under ``name`` (decorator or call).

    ``options``: the names of the backend's own options (beyond ``overwrite_a``);
    :func:`solve` refuses any other.
    """

    def deco(f):
        _BACKENDS[name] = f
        _OPTIONS[name] = COMMON_OPTIONS | set(options)
        return f

    return deco(fn) if fn is not None else deco


def backends() -> list[str]:
    """Names of the registered backends."""
    return sorted(_BACKENDS) + ["auto"]


@register("direct")
def _direct(A, b, tol, maxiter, **options):
    t0 = time.perf_counter()
    solve_factored, name = factorise(A)
    t1 = time.perf_counter()
    x = solve_factored(b)
    t2 = time.perf_counter()
    return x, SolveInfo(name, 0, checked_direct(A, x, b, tol), t1 - t0, t2 - t1)


@register("amg-cg", options=("near_nullspace", "node_slots", "block_theta"))
def _amg_cg(A, b, tol, maxiter, **options):
    if importlib.util.find_spec("pyamg") is None:
        raise SolverError("the 'amg-cg' solver needs pyamg: pip install pyamg")
    from .amg import AMGPreconditioner

    t0 = time.perf_counter()
    M = AMGPreconditioner(A, overwrite=bool(options.get("overwrite_a", False)),
                          near_nullspace=options.get("near_nullspace"), node_slots=options.get("node_slots"),
                          block_theta=options.get("block_theta", clusters.THETA))
    setup = time.perf_counter() - t0
    return preconditioned_cg(M.system_operator(), b, M.operator(), tol, maxiter, "amg-cg", setup, M.info)


@register("fd-cg", options=("kronecker",))
def _fd_cg(A, b, tol, maxiter, **options):
    from .kronecker import BlockFastDiagonalization, FastDiagonalization, KroneckerSum

    ks = options.get("kronecker")
    blocks = isinstance(ks, (list, tuple)) and len(ks) > 0 and all(isinstance(k, KroneckerSum) for k in ks)
    if not (isinstance(ks, KroneckerSum) or blocks):
        raise SolverError("the 'fd-cg' solver needs the option kronecker=solvers.kronecker.KroneckerSum(...) (the "
                          "tensor-product structure of A), or a list of them for the diagonal blocks of A; "
                          "iga.HeatProblem.solve and iga.ElasticityProblem.solve supply it for single patches")
    t0 = time.perf_counter()
    M = BlockFastDiagonalization(ks, A) if blocks else FastDiagonalization(ks, A)
    return preconditioned_cg(A, b, M.operator(), tol, maxiter, "fd-cg", time.perf_counter() - t0, {})


@register("gmg-cg", options=("prolongations",))
def _gmg_cg(A, b, tol, maxiter, **options):
    from .multigrid import Multigrid

    P = options.get("prolongations")
    if not P:
        raise SolverError("the 'gmg-cg' solver needs the option prolongations=[P_0, P_1, ...] (sparse, finest "
                          "first); iga.HeatProblem.solve supplies the spline refinement matrices")
    t0 = time.perf_counter()
    M = Multigrid(A, P)
    return preconditioned_cg(A, b, M.operator(), tol, maxiter, "gmg-cg", time.perf_counter() - t0, M.info)


@register("petsc", options=("pc", "petsc_options", "near_nullspace"))
def _petsc(A, b, tol, maxiter, **options):
    from .amg import checked_near_nullspace
    from .petsc_ksp import serial

    modes = options.get("near_nullspace")
    x, its, reason, setup, solve_s = serial(A, b, tol, maxiter, options.get("pc", "gamg"),
                                            options.get("petsc_options"),
                                            None if modes is None else checked_near_nullspace(modes, A.shape[0]))
    res = relative_residual(A, x, b)
    if reason < 0 or not np.all(np.isfinite(x)) or res > 10 * tol:
        raise SolverError(f"PETSc CG did not converge (reason {reason}): relative residual {res:.2e} after {its} "
                          "iterations; the system may be singular (too few boundary conditions?) or need more "
                          "iterations (maxiter)")
    return x, SolveInfo(f"petsc ({options.get('pc', 'gamg')})", its, res, setup, solve_s)


@register("cg")
def _jacobi_cg(A, b, tol, maxiter, **options):
    t0 = time.perf_counter()
    d = A.diagonal()
    if np.any(d <= 0):
        raise SolverError("Jacobi-CG needs a positive diagonal; the matrix is not positive definite")
    M = sp.diags(1.0 / d)
    return preconditioned_cg(A, b, M, tol, maxiter, "cg", time.perf_counter() - t0, {})


def solve(A, b, method: str = "auto", tol: float = 1e-10, maxiter: int | None = None, **options):
    """Solve ``A x = b`` for a sparse symmetric positive definite ``A``.

    Parameters
    ----------
    A : scipy sparse matrix (n, n)
    b : array (n,)
    method : a name from :func:`backends`
    tol : relative residual tolerance for iterative methods
    maxiter : iteration limit (default: 1000 for AMG-CG, 20 n for CG)
    options : backend options; every backend accepts ``overwrite_a`` (default
        False): True lets it modify ``A``'s values (``amg-cg`` then scales
        them in place instead of copying them), for callers that no longer
        need A

    Returns ``(x, SolveInfo)``.  Raises :class:`SolverError` for non-finite
    input, a singular matrix, or an iteration that does not converge (the
    message carries the residual and the iteration count).
    """
    if not sp.issparse(A):
        raise SolverError(f"A must be a scipy sparse matrix, got {type(A).__name__}")
    n = A.shape[0]
    b = np.asarray(b, float)
    if A.shape != (n, n) or b.shape != (n,):
        raise SolverError(f"shapes do not match: A {A.shape}, b {b.shape}")
    if n == 0:
        return np.zeros(0), SolveInfo("empty", 0, 0.0, 0.0, 0.0)
    data = A.data if hasattr(A, "data") else sp.csr_matrix(A).data
    if not np.all(np.isfinite(data)) or not np.all(np.isfinite(b)):
        raise SolverError("the system contains non-finite values (NaN or inf); check the material data and loads")
    if not isinstance(method, str) or (method != "auto" and method not in _BACKENDS):
        raise SolverError(f"unknown solver {show(method)}; choose one of {backends()}")
    if not (is_real(tol) and 0 < tol < 1):
        raise SolverError(f"tol must be a number in (0, 1), got {show(tol)}")
    if maxiter is not None and not (is_integer(maxiter)
                                    and maxiter >= 1):
        raise SolverError(f"maxiter must be an integer >= 1, got {show(maxiter)}")
    limit = options.pop("direct_limit", AUTO_DIRECT_LIMIT)
    if not is_integer(limit) or limit < 0:
        raise SolverError(f"direct_limit must be a number of unknowns (an integer >= 0), got {show(limit)}")
    if method == "auto":
        method = "direct" if n <= limit else ("fd-cg" if options.get("kronecker") is not None else "amg-cg")
        # the spline structure is offered to auto; the method it picks takes what it uses
        options = {k: v for k, v in options.items() if k in _OPTIONS[method] or k not in ("kronecker", "prolongations", "near_nullspace", "node_slots")}
    if not is_flag(options.get("overwrite_a", False)):
        raise SolverError(f"overwrite_a must be True or False, got {show(options['overwrite_a'])} (a string or "
                          "number would be read as true and let the solver modify your matrix)")
    prol = options.get("prolongations")
    if prol is not None and not (isinstance(prol, (list, tuple)) and all(sp.issparse(P) for P in prol)):
        raise SolverError(f"prolongations must be a list of sparse matrices (finest level first), got {show(prol)}")
    unknown = sorted(set(options) - _OPTIONS[method])
    if unknown:
        raise SolverError(f"unknown option {show(unknown[0])} for the {method} solver; it takes "
                          f"{sorted(_OPTIONS[method])}")
    if maxiter is None:
        maxiter = 1000 if method in ("amg-cg", "fd-cg", "gmg-cg", "petsc") else 20 * n
    if not np.any(b):
        return np.zeros(n), SolveInfo(method, 0, 0.0, 0.0, 0.0)
    return _BACKENDS[method](A, b, tol, maxiter, **options)

