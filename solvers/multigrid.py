"""Geometric multigrid with given prolongations: Galerkin coarse operators, Chebyshev-Jacobi smoothing.

The caller (for splines: :mod:`iga.discretisation.multilevel`, whose prolongations are the
knot-insertion refinement matrices of the nested spline spaces) hands in the
prolongations ``P_l`` from level l + 1 (coarser) to level l; the coarse
operators are the Galerkin products A_{l+1} = P_l^T A_l P_l, so the
hierarchy is exact for any nested spaces, constrained micro-structures
included.  Smoother: Chebyshev polynomials in D^-1 A over
[lambda_max / 30, 1.1 lambda_max] (Adams, Brezina, Hu and Tuminaro 2003),
degree 3 before and after the coarse correction: symmetric, so the V-cycle is
a CG preconditioner.  The coarsest level is factorised (SuperLU) when small,
otherwise solved by one smoothed-aggregation AMG V-cycle (:mod:`solvers.amg`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .amg import spectral_radius
from .errors import SolverError

__all__ = ["Multigrid", "chebyshev_smooth"]

_DIRECT_COARSE = 20_000  # coarsest levels up to this size are factorised, larger ones get an AMG V-cycle


def chebyshev_smooth(A, dinv: np.ndarray, x: np.ndarray, b: np.ndarray, lmax: float, degree: int,
                     ratio: float = 30.0) -> None:
    """``degree`` Chebyshev steps for A x = b preconditioned by D^-1 = ``dinv``, in place on ``x``.

    The polynomial is the one of least maximum on [lmax / ratio, 1.1 lmax] (the three-term recurrence of
    Saad, Iterative Methods, Algorithm 12.1).
    """
    lo, hi = lmax / ratio, 1.1 * lmax
    theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
    sigma = theta / delta
    rho = 1.0 / sigma
    r = b - A @ x
    d = dinv * r / theta
    for k in range(degree):
        x += d
        if k == degree - 1:
            break
        r -= A @ d
        rho_new = 1.0 / (2.0 * sigma - rho)
        d = rho_new * rho * d + (2.0 * rho_new / delta) * (dinv * r)
        rho = rho_new


class _Level:
    def __init__(self, A):
        self.A = sp.csr_matrix(A)
        d = self.A.diagonal()
        if np.any(d <= 0):
            i = int(np.argmin(d))
            raise SolverError(f"multigrid needs a positive diagonal on every level; entry {i} is {d[i]:g}")
        self.dinv = 1.0 / d
        s = np.sqrt(self.dinv)
        scaled = spla.LinearOperator(self.A.shape, matvec=lambda v: s * (self.A @ (s * v)), dtype=float)
        self.lmax = spectral_radius(scaled)


class Multigrid:
    """V-cycle preconditioner of ``A`` on the hierarchy given by ``prolongations`` (finest first)."""

    def __init__(self, A, prolongations, degree: int = 3):
        self.degree = int(degree)
        self.levels = [_Level(A)]
        self.P = []
        for i, P in enumerate(prolongations):
            P = sp.csr_matrix(P)
            if P.shape[0] != self.levels[-1].A.shape[0]:
                raise SolverError(f"prolongation {i} has {P.shape[0]} rows, level {i} has "
                                  f"{self.levels[-1].A.shape[0]} unknowns")
            self.P.append(P)
            self.levels.append(_Level((P.T @ self.levels[-1].A @ P).tocsr()))
        Ac = self.levels[-1].A
        if Ac.shape[0] <= _DIRECT_COARSE:
            try:
                self._lu = spla.splu(sp.csc_matrix(Ac))
            except RuntimeError as exc:
                raise SolverError(f"the coarsest multigrid level is singular ({exc})") from None
            self._coarse = self._lu.solve
        else:
            from .amg import AMGPreconditioner

            self._coarse = AMGPreconditioner(Ac)
        self.info = {"mg_levels": len(self.levels), "mg_sizes": [lv.A.shape[0] for lv in self.levels],
                     "operator_complexity": float(sum(lv.A.nnz for lv in self.levels) / self.levels[0].A.nnz)}

    def _cycle(self, lvl: int, b: np.ndarray) -> np.ndarray:
        if lvl == len(self.levels) - 1:
            return np.asarray(self._coarse(b)).ravel()
        L = self.levels[lvl]
        x = np.zeros_like(b)
        chebyshev_smooth(L.A, L.dinv, x, b, L.lmax, self.degree)
        x += self.P[lvl] @ self._cycle(lvl + 1, self.P[lvl].T @ (b - L.A @ x))
        chebyshev_smooth(L.A, L.dinv, x, b, L.lmax, self.degree)
        return x

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._cycle(0, np.ravel(np.asarray(r, float)))

    def operator(self) -> spla.LinearOperator:
        """M as a SciPy LinearOperator."""
        return spla.LinearOperator(self.levels[0].A.shape, matvec=self, dtype=float)
