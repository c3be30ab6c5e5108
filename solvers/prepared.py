"""One matrix, many right-hand sides: a solver prepared once (a factorisation or a preconditioner) and applied
to each new right-hand side, as time stepping needs (the matrix M / dt + K is the same for every step of one
size).

``direct`` keeps the sparse factorisation (CHOLMOD when scikit-sparse is installed, else SuperLU); ``amg-cg``
keeps the smoothed-aggregation hierarchy and starts CG from the caller's guess (the previous step's unknowns);
``cg`` keeps the Jacobi diagonal.  ``auto`` factorises up to :data:`PREPARED_DIRECT_LIMIT` unknowns (a
factorisation paid once is worth more here than in a single solve, :data:`solvers.AUTO_DIRECT_LIMIT`) and uses
AMG-CG above; :func:`factor_bytes` estimates the factors' memory for callers with a budget.

    >>> import numpy as np, scipy.sparse as sp
    >>> A = sp.diags([[-1.0] * 9, [2.0] * 10, [-1.0] * 9], [-1, 0, 1], format="csr")
    >>> solve = prepare(A, method="direct")
    >>> x, info = solve(np.ones(10))
    >>> y, _ = solve(2 * np.ones(10))
    >>> info.method, bool(np.allclose(A @ x, 1.0)), bool(np.allclose(y, 2 * x))
    ('direct (SuperLU)', True, True)
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from geometry.errors import show
from geometry.numbers import is_integer, is_real

from . import clusters
from .info import SolveInfo
from .krylov import checked_direct, factorise, preconditioned_cg
from .errors import SolverError

__all__ = ["PreparedSolver", "prepare", "PREPARED_DIRECT_LIMIT", "factor_bytes"]

#: ``auto`` factorises systems up to this many unknowns once and reuses the factors (a caller with a memory
#: budget compares :func:`factor_bytes` with it and asks for ``amg-cg`` where they would not fit).  Measured on the circular demo sink's step matrix M / dt + K
#: (benchmarks/transient.py): 62,800 unknowns factorised in 0.75 s, 26 ms a solve, against 0.6 s a step for
#: AMG-CG; 349k unknowns in 12.6 s and 1.7 GB, 0.37 s a solve, against 3.1 s of AMG set-up and 14 s a solve
PREPARED_DIRECT_LIMIT = 400_000


def factor_bytes(n: int) -> float:
    """The memory of a sparse factorisation of an n x n matrix of a 3-D spline space (bytes): 4.9 kB per
    unknown at 349k unknowns (SuperLU, minimum-degree ordering), growing as n^(4/3) (nested dissection)."""
    return 4.9e3 * n * (n / 3.5e5) ** (1.0 / 3.0)

_METHODS = ("direct", "amg-cg", "cg")


class PreparedSolver:
    """``solver(b, x0=None) -> (x, SolveInfo)`` for a fixed sparse symmetric positive definite matrix.

    ``setup_s`` is the time spent preparing (factorisation or hierarchy), paid once; each call's
    :class:`solvers.SolveInfo` reports its own solve time and ``setup_s`` 0.
    """

    def __init__(self, A, method: str = "auto", tol: float = 1e-10, maxiter: int | None = None,
                 block_theta=clusters.THETA):
        if not sp.issparse(A) or A.shape[0] != A.shape[1]:
            raise SolverError(f"A must be a square scipy sparse matrix, got {type(A).__name__} "
                              f"{getattr(A, 'shape', '')}")
        if not np.all(np.isfinite(A.data)):
            raise SolverError("the system contains non-finite values (NaN or inf); check the material data")
        if method != "auto" and method not in _METHODS:
            raise SolverError(f"a prepared solver is one of {['auto', *_METHODS]}, got {show(method)}")
        if not (is_real(tol) and 0 < tol < 1):
            raise SolverError(f"tol must be a number in (0, 1), got {show(tol)}")
        if maxiter is not None and not (is_integer(maxiter) and maxiter >= 1):
            raise SolverError(f"maxiter must be an integer >= 1, got {show(maxiter)}")
        n = A.shape[0]
        if method == "auto":
            method = "direct" if n <= PREPARED_DIRECT_LIMIT else "amg-cg"
        self.A, self.n, self.tol = sp.csr_matrix(A), n, tol
        self.maxiter = maxiter if maxiter is not None else (1000 if method == "amg-cg" else 20 * max(n, 1))
        t0 = time.perf_counter()
        self._solve, self._system, self._pre, self.name = None, self.A, None, method
        if n == 0:
            pass
        elif method == "direct":
            self._solve, self.name = factorise(self.A)
        elif method == "amg-cg":
            from .amg import AMGPreconditioner

            M = AMGPreconditioner(self.A, block_theta=block_theta)
            self._system, self._pre, self.extra = M.system_operator(), M.operator(), M.info
        else:
            d = self.A.diagonal()
            if np.any(d <= 0):
                raise SolverError("Jacobi-CG needs a positive diagonal; the matrix is not positive definite")
            self._pre = sp.diags(1.0 / d)
        self.setup_s = time.perf_counter() - t0

    def __call__(self, b, x0=None):
        b = np.asarray(b, float)
        if b.shape != (self.n,):
            raise SolverError(f"the right-hand side must have shape ({self.n},), got {b.shape}")
        if not np.all(np.isfinite(b)):
            raise SolverError("the right-hand side contains non-finite values (NaN or inf); check the loads")
        if self.n == 0 or not np.any(b):
            return np.zeros(self.n), SolveInfo(self.name, 0, 0.0, 0.0, 0.0)
        if self._solve is not None:
            t0 = time.perf_counter()
            x = self._solve(b)
            return x, SolveInfo(self.name, 0, checked_direct(self.A, x, b, self.tol), 0.0, time.perf_counter() - t0)
        x0 = None if x0 is None else np.asarray(x0, float)
        return preconditioned_cg(self._system, b, self._pre, self.tol, self.maxiter, self.name, 0.0,
                       getattr(self, "extra", {}), x0=x0)


def prepare(A, method: str = "auto", tol: float = 1e-10, maxiter: int | None = None) -> PreparedSolver:
    """A :class:`PreparedSolver` of ``A`` (``method``: ``auto``, ``direct``, ``amg-cg`` or ``cg``; ``tol``
    and ``maxiter`` for the iterative ones)."""
    return PreparedSolver(A, method, tol, maxiter)
