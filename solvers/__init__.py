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
``auto``     ``direct`` up to :data:`AUTO_DIRECT_LIMIT` unknowns; above, ``fd-cg`` when a ``kronecker``
             option is given, else ``amg-cg``.
"""

from __future__ import annotations

import importlib.util
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import clusters
from .errors import SolverError
from geometry import progress
from geometry.errors import show
from geometry.numbers import is_flag, is_integer, is_real

__all__ = ["SolverError", "SolveInfo", "solve", "register", "backends", "AUTO_DIRECT_LIMIT"]

#: Above this many unknowns ``auto`` uses AMG-CG: SuperLU fills in badly on 3-D IGA matrices
#: (docs/performance.md).
AUTO_DIRECT_LIMIT = 2_000


@dataclass
class SolveInfo:
    """Diagnostics of one solve.

    method : backend name actually used
    iterations : Krylov iterations (0 for direct)
    residual : final relative residual ||b - A x|| / ||b||
    setup_s, solve_s : seconds spent in factorisation/hierarchy set-up and in the solve
    extra : backend-specific details (e.g. AMG levels and operator complexity)
    """

    method: str
    iterations: int
    residual: float
    setup_s: float
    solve_s: float
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The diagnostics as a plain dictionary (for JSON summaries)."""
        return {"method": self.method, "iterations": self.iterations, "residual": self.residual,
                "setup_s": self.setup_s, "solve_s": self.solve_s, **self.extra}


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


def _residual(A, x, b) -> float:
    nb = np.linalg.norm(b)
    return float(np.linalg.norm(b - A @ x) / (nb if nb > 0 else 1.0))


@register("direct")
def _direct(A, b, tol, maxiter, **options):
    t0 = time.perf_counter()
    try:
        from sksparse.cholmod import cholesky  # optional, much faster for SPD systems

        try:
            factor = cholesky(sp.csc_matrix(A))
            t1 = time.perf_counter()
            x = factor(b)
            name = "direct (CHOLMOD)"
        except Exception as exc:  # CholmodNotPositiveDefiniteError and friends
            raise SolverError(f"CHOLMOD factorisation failed ({exc}); the matrix is singular or indefinite") from None
    except ImportError:
        try:
            lu = spla.splu(sp.csc_matrix(A))
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(
                f"the system matrix is singular ({exc}): the conditions leave the solution undetermined (a heat "
                "problem needs a Dirichlet or Robin condition on every connected piece, an elastic one supports "
                "against every rigid motion of every piece)"
            ) from None
        t1 = time.perf_counter()
        x = lu.solve(b)
        name = "direct (SuperLU)"
    t2 = time.perf_counter()
    res = _residual(A, x, b)
    if not np.all(np.isfinite(x)) or res > max(1e-6, 1e3 * tol):
        raise SolverError(f"direct solve is inaccurate: relative residual {res:.2e} (matrix nearly singular)")
    return x, SolveInfo(name, 0, res, t1 - t0, t2 - t1)


def _krylov(A, b, M, tol, maxiter, name, t_setup, extra):
    """CG on ``A`` (a sparse matrix or a LinearOperator computing its product) preconditioned by ``M``."""
    it = [0]
    # no total: CG stops at the tolerance, long before maxiter, so a bar to maxiter would show a false ETA
    bar = progress.bar(None, total=None, desc=name, unit="it", min_items=0) if progress.active() else None

    def count(_):
        it[0] += 1
        if bar is not None:
            bar.update(1)

    t1 = time.perf_counter()
    try:
        with np.errstate(all="ignore"):  # a singular system shows up as non-finite values, reported below
            x, _flag = spla.cg(A, b, rtol=tol, atol=0.0, maxiter=maxiter, M=M, callback=count)
    finally:
        if bar is not None:
            bar.close()
    t2 = time.perf_counter()
    res = _residual(A, x, b)
    if not np.all(np.isfinite(x)):
        raise SolverError(
            f"{name} broke down with non-finite values after {it[0]} iterations (residual undefined): "
            "the matrix is singular or indefinite: the conditions leave the solution undetermined (a heat problem "
            "needs a Dirichlet or Robin condition on every connected piece, an elastic one supports against every "
            "rigid motion of every piece)"
        )
    if res > 10 * tol and _flag == 0:  # CG's own residual converged, the true one did not: rounding
        raise SolverError(
            f"{name} stopped at its tolerance after {it[0]} iterations, but the true relative residual is "
            f"{res:.2e} (tolerance {tol:.0e}): the system is too ill-conditioned for that tolerance (very thin "
            "or stiff features); loosen tol (e.g. 1e-8) or use solver='direct'"
        )
    if res > 10 * tol:  # judged by the true residual: an iteration limit reached after convergence is no failure
        raise SolverError(
            f"{name} did not converge: relative residual {res:.2e} after {it[0]} iterations "
            f"(tolerance {tol:.0e}); the system may be singular (too few boundary conditions?) "
            "or need more iterations (maxiter)"
        )
    return x, SolveInfo(name, it[0], res, t_setup, t2 - t1, extra)


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
    return _krylov(M.system_operator(), b, M.operator(), tol, maxiter, "amg-cg", setup, M.info)


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
    return _krylov(A, b, M.operator(), tol, maxiter, "fd-cg", time.perf_counter() - t0, {})


@register("gmg-cg", options=("prolongations",))
def _gmg_cg(A, b, tol, maxiter, **options):
    from .multigrid import Multigrid

    P = options.get("prolongations")
    if not P:
        raise SolverError("the 'gmg-cg' solver needs the option prolongations=[P_0, P_1, ...] (sparse, finest "
                          "first); iga.HeatProblem.solve supplies the spline refinement matrices")
    t0 = time.perf_counter()
    M = Multigrid(A, P)
    return _krylov(A, b, M.operator(), tol, maxiter, "gmg-cg", time.perf_counter() - t0, M.info)


@register("petsc", options=("pc", "petsc_options"))
def _petsc(A, b, tol, maxiter, **options):
    from .petsc_ksp import serial

    x, its, reason, setup, solve_s = serial(A, b, tol, maxiter, options.get("pc", "gamg"),
                                            options.get("petsc_options"))
    res = _residual(A, x, b)
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
    return _krylov(A, b, M, tol, maxiter, "cg", time.perf_counter() - t0, {})


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
    if method == "auto":
        method = "direct" if n <= AUTO_DIRECT_LIMIT else ("fd-cg" if options.get("kronecker") is not None
                                                          else "amg-cg")
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
