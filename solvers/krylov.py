"""The two ways the backends solve: a sparse factorisation (:func:`factorise`) and preconditioned conjugate
gradients with the checks every iterative backend shares (:func:`preconditioned_cg`)."""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from geometry import progress

from .errors import SolverError
from .info import SolveInfo

__all__ = ["factorise", "preconditioned_cg", "relative_residual", "checked_direct"]


def relative_residual(A, x, b) -> float:
    """||b - A x|| / ||b|| (||b - A x|| for b = 0)."""
    nb = np.linalg.norm(b)
    return float(np.linalg.norm(b - A @ x) / (nb if nb > 0 else 1.0))


def checked_direct(A, x, b, tol: float) -> float:
    """The relative residual of a factorised solve x of A x = b; :class:`SolverError` where it is not finite or
    above max(1e-6, 1e3 tol) (a nearly singular matrix)."""
    res = relative_residual(A, x, b)
    if not np.all(np.isfinite(x)) or res > max(1e-6, 1e3 * tol):
        raise SolverError(f"direct solve is inaccurate: relative residual {res:.2e} (matrix nearly singular)")
    return res


def factorise(A):
    """(solve function of a right-hand side, method name) of a sparse factorisation of the symmetric positive
    definite matrix A: CHOLMOD when scikit-sparse is installed, else SuperLU."""
    try:
        from sksparse.cholmod import cholesky  # optional, much faster for SPD systems
    except ImportError:
        cholesky = None
    if cholesky is not None:
        try:
            return cholesky(sp.csc_matrix(A)), "direct (CHOLMOD)"
        except Exception as exc:  # CholmodNotPositiveDefiniteError and friends
            raise SolverError(f"CHOLMOD factorisation failed ({exc}); the matrix is singular or indefinite") from None
    try:  # a symmetric ordering of A + A^T: 3-6x faster than SuperLU's default COLAMD on 3-D spline matrices
        lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise SolverError(
            f"the system matrix is singular ({exc}): the conditions leave the solution undetermined (a heat "
            "problem needs a Dirichlet or Robin condition on every connected piece, an elastic one supports "
            "against every rigid motion of every piece)"
        ) from None
    return lu.solve, "direct (SuperLU)"


def preconditioned_cg(A, b, M, tol, maxiter, name, t_setup, extra, x0=None):
    """CG on ``A`` (a sparse matrix or a LinearOperator computing its product) preconditioned by ``M``, from
    ``x0`` (default zero)."""
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
            x, _flag = spla.cg(A, b, x0=x0, rtol=tol, atol=0.0, maxiter=maxiter, M=M, callback=count)
    finally:
        if bar is not None:
            bar.close()
    t2 = time.perf_counter()
    res = relative_residual(A, x, b)
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
