"""Fast diagonalization: the inverse of a Kronecker-sum operator, applied in O(n^(1 + 1/d)) operations.

For an operator with tensor-product structure (Sangalli and Tani 2016, Section 3; Lynch, Rice and Thomas
1964)

    A_FD = sum_k c_k  M_1 x ... x K_k x ... x M_d,

with symmetric positive definite 1-D "stiffness" K_k and "mass" M_k, the
generalized eigendecompositions K_k U_k = M_k U_k Lambda_k (U_k^T M_k U_k = I)
give A_FD^-1 = (U_1 x ... x U_d) diag(1 / sum_k c_k lambda_k) (U_1 x ... x U_d)^T,
applied by 2d dense products along one direction at a time.  As a
preconditioner of a matrix A that is only close to A_FD (a curved geometry,
a varying coefficient) it is scaled by D = diag(A_FD) / diag(A) (Sangalli and
Tani 2016, Section 4.2): M^-1 = D^1/2 A_FD^-1 D^1/2, which equals A_FD^-1 when
A = A_FD.  Nothing here knows about splines: the caller hands in the 1-D matrices.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from .errors import SolverError

__all__ = ["KroneckerSum", "FastDiagonalization", "BlockFastDiagonalization"]


class KroneckerSum:
    """The data of A_FD: per direction (K_k, M_k) dense (n_k, n_k) and the coefficients c_k > 0.

    The unknowns are numbered in C order over the shape (n_1, ..., n_d).
    """

    def __init__(self, stiffness, mass, coefficients):
        self.K = [np.asarray(k, float) for k in stiffness]
        self.M = [np.asarray(m, float) for m in mass]
        self.c = np.asarray(coefficients, float).ravel()
        d = len(self.K)
        if not (d == len(self.M) == len(self.c) and d >= 1):
            raise SolverError(f"a Kronecker sum needs one (K, M, c) per direction, got {len(self.K)}, "
                              f"{len(self.M)}, {len(self.c)}")
        for k, (K, M) in enumerate(zip(self.K, self.M)):
            if K.ndim != 2 or K.shape[0] != K.shape[1] or M.shape != K.shape:
                raise SolverError(f"direction {k}: K and M must be equal square matrices, got {K.shape}, {M.shape}")
        if not np.all(np.isfinite(self.c)) or np.any(self.c <= 0):
            raise SolverError(f"Kronecker-sum coefficients must be positive and finite, got {self.c.tolist()}")
        self.shape = tuple(K.shape[0] for K in self.K)
        self.n = int(np.prod(self.shape))

    def diagonal(self) -> np.ndarray:
        """diag(A_FD) (n,), C order."""
        out = np.zeros(self.shape)
        for k in range(len(self.K)):
            term = np.ones(())
            for j in range(len(self.K)):
                term = np.multiply.outer(term, np.diag(self.K[j] if j == k else self.M[j]))
            out += self.c[k] * term
        return out.ravel()

    def matvec(self, x: np.ndarray) -> np.ndarray:
        """A_FD x (for tests and diagnostics)."""
        X = np.reshape(x, self.shape)
        out = np.zeros(self.shape)
        for k in range(len(self.K)):
            out += self.c[k] * _modes(X, [self.K[j] if j == k else self.M[j] for j in range(len(self.K))])
        return out.ravel()


def _modes(X: np.ndarray, mats) -> np.ndarray:
    """X multiplied along every direction k by mats[k] (mats[k] @ along axis k); dense BLAS products."""
    for k, A in enumerate(mats):
        X = np.moveaxis(np.tensordot(A, X, axes=(1, k)), 0, k)
    return X


class FastDiagonalization:
    """M^-1 = D^1/2 A_FD^-1 D^1/2 for a matrix ``A`` close to the Kronecker sum ``ks`` (see the module notes).

    ``A``: the sparse matrix to precondition (only its diagonal is read; None: no scaling); ``diagonal``:
    that diagonal (n,) instead of A.
    """

    def __init__(self, ks: KroneckerSum, A=None, diagonal=None):
        self.ks = ks
        self.U, lam = [], []
        for k, (K, M) in enumerate(zip(ks.K, ks.M)):
            try:
                w, U = sla.eigh(K, M)
            except (np.linalg.LinAlgError, ValueError) as exc:
                raise SolverError(f"fast diagonalization: direction {k}: the 1-D mass matrix is not positive "
                                  f"definite ({exc})") from None
            self.U.append(U)
            lam.append(w)
        denom = np.zeros(ks.shape)
        for k, w in enumerate(lam):
            shape = [1] * len(ks.shape)
            shape[k] = len(w)
            denom = denom + ks.c[k] * w.reshape(shape)
        if np.any(denom <= 0):
            raise SolverError("fast diagonalization: the Kronecker sum is singular (a direction without "
                              "Dirichlet ends has a zero eigenvalue); it needs a Dirichlet side")
        self.inv = 1.0 / denom
        self.scale = None
        if A is not None or diagonal is not None:
            if A is not None and A.shape != (ks.n, ks.n):
                raise SolverError(f"fast diagonalization: the matrix is {A.shape}, the Kronecker sum {ks.n}")
            d = A.diagonal() if diagonal is None else np.asarray(diagonal, float)
            if d.shape != (ks.n,):
                raise SolverError(f"fast diagonalization: the diagonal has shape {d.shape}, the Kronecker sum {ks.n}")
            if not np.all(d > 0):
                raise SolverError("fast diagonalization needs a positive diagonal; the matrix is not positive "
                                  "definite")
            self.scale = np.sqrt(ks.diagonal() / d)
        self.UT = [U.T.copy() for U in self.U]

    def __call__(self, r: np.ndarray) -> np.ndarray:
        r = np.ravel(r)
        if self.scale is not None:
            r = self.scale * r
        X = _modes(r.reshape(self.ks.shape), self.UT) * self.inv
        x = _modes(X, self.U).ravel()
        return x if self.scale is None else self.scale * x

    def operator(self) -> spla.LinearOperator:
        """M as a SciPy LinearOperator."""
        return spla.LinearOperator((self.ks.n, self.ks.n), matvec=self, dtype=float)


class BlockFastDiagonalization:
    """Block-diagonal M^-1 = diag(M_1^-1, ..., M_m^-1), one :class:`FastDiagonalization` per diagonal block of
    ``A``: the blocks ``blocks`` (Kronecker sums) take consecutive unknowns, in order (the displacement
    components of one elastic patch, each close to a Kronecker sum of its own coefficients).
    """

    def __init__(self, blocks, A):
        sizes = [ks.n for ks in blocks]
        if sum(sizes) != A.shape[0]:
            raise SolverError(f"block fast diagonalization: the blocks hold {sum(sizes)} unknowns, the matrix "
                              f"{A.shape[0]}")
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])
        d = A.diagonal()
        self.parts = [FastDiagonalization(ks, diagonal=d[lo:hi]) for ks, lo, hi in
                      zip(blocks, self.bounds[:-1], self.bounds[1:])]

    def __call__(self, r: np.ndarray) -> np.ndarray:
        r = np.ravel(r)
        return np.concatenate([fd(r[lo:hi]) for fd, lo, hi in zip(self.parts, self.bounds[:-1], self.bounds[1:])])

    def operator(self) -> spla.LinearOperator:
        """M as a SciPy LinearOperator."""
        n = int(self.bounds[-1])
        return spla.LinearOperator((n, n), matvec=self, dtype=float)
