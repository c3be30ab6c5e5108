"""Smoothed-aggregation AMG preconditioner: pyamg's hierarchy on the Jacobi-scaled matrix, a lean V-cycle.

The hierarchy (aggregation, prolongators, Galerkin products, smoothers,
coarse solver) is pyamg's ``smoothed_aggregation_solver``, built for the
symmetrically scaled matrix  Â = S A S,  S = diag(A)^-1/2  (unit diagonal).
The preconditioner of A is then  M r = S V(S r)  with V one V-cycle on Â,
and CG runs on A itself, so its residual is the true one.  The V-cycle is
ours because pyamg's ``aspreconditioner`` runs ``solve(maxiter=1)``, which
computes the residual norm before and after the cycle: two matrix-vector
products per CG iteration that a preconditioner does not need.

Choices (the measurements behind them are in docs/performance.md):

* Chebyshev smoothing of degree 3 instead of symmetric Gauss-Seidel: on
  these wide stencils (125 entries per row at p = 2) one Gauss-Seidel sweep
  costs about three matrix-vector products, and the iteration counts barely differ.
* The scaling makes Chebyshev and prolongation smoothing robust to
  conductivity jumps (a jump of 1000 costs a few iterations, not hundreds).
* With unit diagonal, Richardson prolongation smoothing *is* Jacobi
  smoothing, and it reads the spectral radius cached on the matrix as
  ``A.rho`` (pyamg's own convention; :func:`spectral_radius`, 15 Lanczos
  steps), while pyamg's Jacobi option copies A twice and runs its own estimate.
* ``strength=None``: the strength matrix is A itself.  With smoothed
  aggregation's default ``theta = 0`` every coupling is strong anyway, so the
  aggregates are the same, without the copy of A.
* ``improve_candidates=None``: the near-null space S^-1 1 is exact for the
  scaled diffusion operator already; improving it costs set-up time and saves
  no iteration.
* Vector problems (elasticity) given their unknowns' places in nodes of three
  (``node_slots``) are solved node-major as a 3 x 3 block (BSR) matrix, the
  missing components of partly prescribed nodes as decoupled unit rows, and
  aggregated by node with pyamg's symmetric strength at ``theta = 0.1`` on the
  blocks' norms: on cross lattices 17-19 iterations instead of 25-29, flat
  under refinement, and faster (theta 0.2 and above coarsen too slowly: 61 and
  more).  On a plain p = 2 cube it costs iterations (22 instead of 14 at 24^3;
  theta 0 keeps 14 there but not the lattices' gain); single patches are
  solved by block fast diagonalization anyway (``iga.ElasticityProblem``).
* Strongly coupled unknowns are relaxed together: where the scaled matrix
  couples unknowns by ``|Â_ij| >= block_theta`` (0.5; thin features,
  slivers), Â is scaled further by the Cholesky factors of those clusters'
  blocks (:mod:`solvers.clusters`; vector problems cluster whole nodes),
  M r = S L^-T V(L^-1 S r), so the point smoother becomes a block smoother
  there.  The winged-duck V-model: 296 iterations -> 36; box u cylinder 31
  -> 13 (heat), 85 -> 57 (elasticity); models without such couplings get
  exactly the point-scaled hierarchy.  ``block_theta=None`` turns it off.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import clusters
from .errors import SolverError
from .indexing import complement
from geometry.numbers import TINY, is_real


def checked_near_nullspace(near_nullspace, n: int) -> np.ndarray:
    """``near_nullspace`` as a finite (n, k) array, or the project's error naming it."""
    B = np.asarray(near_nullspace, float)
    if B.ndim != 2 or B.shape[0] != n or not np.all(np.isfinite(B)):
        raise SolverError(f"near_nullspace must be a finite ({n}, k) array, got shape {B.shape}")
    return B


def _candidates(near_nullspace, s: np.ndarray) -> np.ndarray:
    """The near-nullspace of the scaled matrix S A S: S^-1 B (B the constants by default)."""
    if near_nullspace is None:
        return (1.0 / s)[:, None]
    return checked_near_nullspace(near_nullspace, len(s)) / s[:, None]


class _Scaled(sp.csr_matrix):
    """The Jacobi-scaled matrix S A S that the hierarchy is built on, with its spectral radius ``rho``:
    pyamg's convention is to read (and cache) ``rho`` on the matrix it is given."""

    rho: float


class _ScaledBlocks(sp.bsr_matrix):
    """:class:`_Scaled` in 3 x 3 blocks (node-major vector problems)."""

    rho: float


def spectral_radius(A, steps: int = 15) -> float:
    """Largest eigenvalue of a symmetric positive semi-definite ``A`` from ``steps`` Lanczos steps.

    Lanczos converges fastest at the ends of the spectrum; after about 15
    steps the largest Ritz value is within a few per cent below the true
    value, which the Chebyshev smoother's 10% margin (``upper_bound=1.1``)
    covers.  Deterministic (fixed start vector).
    """
    from scipy.linalg import eigvalsh_tridiagonal

    n = A.shape[0]
    v = np.random.default_rng(0).standard_normal(n)
    v /= np.linalg.norm(v)
    v_prev, beta = np.zeros(n), 0.0
    alphas, betas = [], []
    for _ in range(min(steps, n)):
        w = A @ v - beta * v_prev
        alpha = float(w @ v)
        w -= alpha * v
        alphas.append(alpha)
        beta = float(np.linalg.norm(w))
        if beta <= 1e-12 * max(abs(alpha), TINY):  # Lanczos breakdown: an invariant subspace
            break
        betas.append(beta)
        v_prev, v = v, w / beta
    return float(eigvalsh_tridiagonal(np.array(alphas), np.array(betas[: len(alphas) - 1]))[-1])


def permuted_padded(A: sp.csr_matrix, slots: np.ndarray, size: int) -> sp.csr_matrix:
    """The (size, size) CSR matrix with A[i, j] at (slots[i], slots[j]) and a unit diagonal on the rows no slot
    takes: A's rows taken in the order of their slots (SciPy's row gather), the columns renamed, the unit rows
    inserted (a COO round trip sorted all of A's non-zeros again: 1.9 s for 20 million, this a quarter)."""
    order = np.argsort(slots, kind="stable")  # A's rows in the order of their slots
    B = A[order]
    placed = slots[order]
    pads = complement(size, slots)
    before = np.searchsorted(placed, pads)  # taken rows above each unit row
    at = B.indptr[before]
    indices = np.insert(slots[B.indices], at, pads)
    data = np.insert(B.data, at, 1.0)
    lengths = np.ones(size, np.int64)
    lengths[placed] = np.diff(B.indptr)
    indptr = np.zeros(size + 1, np.int64)
    np.cumsum(lengths, out=indptr[1:])
    out = sp.csr_matrix((data, indices, indptr), shape=(size, size))
    out.sort_indices()  # the slots reorder the columns within a row
    return out


class AMGPreconditioner:
    """Preconditioner of a symmetric positive definite CSR matrix A: M r = S V(S r) (see the module notes).

    ``overwrite=True`` lets it scale A's own ``data`` in place (A then holds
    S A S; :meth:`system_operator` still applies the original A) instead of
    scaling a copy of the values (8 bytes per non-zero).  ``near_nullspace``
    (n, k): the vectors A nearly annihilates (the rigid-body modes of
    elasticity); default the constants (diffusion).  ``node_slots`` (n,):
    each unknown's place 3 node + component, for vector problems aggregated by
    node (module notes); A is then copied, node-major, whatever ``overwrite``.
    ``block_theta``: the coupling of the scaled matrix from which unknowns (nodes, for vector problems)
    are relaxed together (module notes), None for point relaxation only.
    """

    def __init__(self, A, max_coarse: int = 500, degree: int = 3, overwrite: bool = False, near_nullspace=None,
                 node_slots=None, block_theta: float | None = clusters.THETA):
        import pyamg
        from pyamg.util.utils import scale_columns, scale_rows

        if block_theta is not None and (isinstance(block_theta, bool) or not (
                is_real(block_theta) and 0 < block_theta <= 1)):
            raise SolverError(f"block_theta must be a number in (0, 1] (the coupling of the unit-diagonal matrix from "
                              f"which unknowns are relaxed together) or None to relax point by point, got "
                              f"{block_theta!r}")
        self.slots = None
        if node_slots is not None:  # node-major 3 x 3 blocks (module notes): A and B padded and permuted
            A, near_nullspace = self._node_major(A, node_slots, near_nullspace)
            overwrite = True  # the padded copy is ours
        A = sp.csr_matrix(A)
        if not A.has_sorted_indices:
            if overwrite:
                A.sort_indices()
            else:  # sorting in place would reorder the caller's arrays
                A = A.sorted_indices()
        d = A.diagonal()
        if not np.all(d > 0):
            i = int(np.argmin(d))
            raise SolverError(f"AMG needs a positive diagonal, but diagonal entry {i} is {d[i]:g}: "
                              "the matrix is not positive definite")
        self.s = 1.0 / np.sqrt(d)
        # our own matrix object (a copy, or with overwrite a view of the caller's arrays), so the spectral
        # radius pyamg caches on it is not left on the caller's matrix
        A = _Scaled((A.data if overwrite else A.data.copy(), A.indices, A.indptr), shape=A.shape)
        scale_rows(A, self.s, copy=False)
        scale_columns(A, self.s, copy=False)
        B = _candidates(near_nullspace, self.s)
        self.clusters = None
        if block_theta is not None:  # thin features: relaxed by blocks (module notes); vector problems by node
            try:
                self.clusters = clusters.ClusterScaling.of(A, block_theta, node=3 if self.slots is not None else 1)
            except np.linalg.LinAlgError:
                raise SolverError("AMG needs a positive definite matrix, but a block of strongly coupled unknowns "
                                  "is not: the matrix is not positive definite") from None
            if self.clusters is not None:
                Ab = self.clusters.scale(A)
                A = _Scaled((Ab.data, Ab.indices, Ab.indptr), shape=Ab.shape)
                B = self.clusters.candidates(B)
        A.rho = spectral_radius(A)
        self.scaled = A
        smoother = ("chebyshev", {"degree": degree})
        strength = None
        if self.slots is not None:  # the blocks replace the CSR storage (the system operator applies them too)
            A = _ScaledBlocks(A.tobsr(blocksize=(3, 3)))
            A.rho = self.scaled.rho
            self.scaled = A
            strength = ("symmetric", {"theta": 0.1})
            max_coarse = max(1, max_coarse // 3)  # pyamg counts block rows
        self.ml = pyamg.smoothed_aggregation_solver(
            A, B=B, symmetry="symmetric", max_coarse=max_coarse, strength=strength,
            # a sparse LU of the coarsest level: pyamg's default pseudo-inverse made every cycle 3.4x slower on
            # a p = 2 elastic cube of 114k unknowns (coarsest level 2058: a dense SVD and dense products)
            coarse_solver="splu",
            improve_candidates=None, smooth=("richardson", {"omega": 4.0 / 3.0}),
            presmoother=smoother, postsmoother=smoother)
        self.levels = self.ml.levels

    def _node_major(self, A, node_slots, B):
        """(A, B) permuted and padded to node-major order: unknown i at ``node_slots[i]`` (distinct, in
        [0, 3 M)); the unused slots become unit rows with zero near-nullspace rows, decoupled."""
        slots = np.asarray(node_slots)
        n = A.shape[0]
        if slots.shape != (n,) or slots.dtype.kind not in "iu" or len(np.unique(slots)) != n or slots.min() < 0:
            raise SolverError(f"node_slots must be {n} distinct non-negative integers (each unknown's place "
                              "3 node + component)")
        size = 3 * (int(slots.max()) // 3 + 1)
        Ap = permuted_padded(sp.csr_matrix(A), slots, size)
        Bp = None
        if B is not None:
            B = checked_near_nullspace(B, n)
            Bp = np.zeros((size, B.shape[1]))
            Bp[slots] = B
        self.slots, self.size = slots, size
        return Ap, Bp

    def _pad(self, x: np.ndarray) -> np.ndarray:
        if self.slots is None:
            return x
        out = np.zeros(self.size)
        out[self.slots] = x
        return out

    def _unpad(self, x: np.ndarray) -> np.ndarray:
        return x if self.slots is None else x[self.slots]

    @property
    def info(self) -> dict:
        """Levels of the hierarchy, its operator complexity and the clusters relaxed together (if any)."""
        out = {"amg_levels": len(self.levels), "operator_complexity": float(self.ml.operator_complexity())}
        if self.clusters is not None:
            out.update(self.clusters.info)
        return out

    def _cycle(self, lvl: int, b: np.ndarray) -> np.ndarray:
        level = self.levels[lvl]
        A = level.A
        x = np.zeros_like(b)
        level.presmoother(A, x, b)
        bc = level.R @ (b - A @ x)
        if lvl == len(self.levels) - 2:
            xc = np.asarray(self.ml.coarse_solver(self.levels[-1].A, bc)).reshape(bc.shape)
        else:
            xc = self._cycle(lvl + 1, bc)
        x += level.P @ xc
        level.postsmoother(A, x, b)
        return x

    def __call__(self, r: np.ndarray) -> np.ndarray:
        b = self.s * self._pad(np.ravel(r))
        cs = self.clusters
        if cs is not None:
            b = cs.lower(b)
        if len(self.levels) == 1:
            x = np.asarray(self.ml.coarse_solver(self.levels[0].A, b)).ravel()
        else:
            x = self._cycle(0, b)
        if cs is not None:
            x = cs.lower_t(x)
        return self._unpad(self.s * x)

    @property
    def shape(self) -> tuple:
        n = self.scaled.shape[0] if self.slots is None else len(self.slots)
        return (n, n)

    def operator(self) -> spla.LinearOperator:
        """M as a SciPy LinearOperator (the preconditioner of :func:`scipy.sparse.linalg.cg`)."""
        return spla.LinearOperator(self.shape, matvec=self, dtype=float)

    def system_operator(self) -> spla.LinearOperator:
        """The original A, applied through the scaled storage: A x = S^-1 (Â (S^-1 x)) (padded and permuted
        back for node-major storage)."""
        s, Ah, cs = self.s, self.scaled, self.clusters
        if cs is not None:  # A = S^-1 L Â_b L^T S^-1
            return spla.LinearOperator(
                self.shape, matvec=lambda x: self._unpad(cs.factor(Ah @ cs.factor_t(self._pad(np.ravel(x)) / s)) / s),
                dtype=float)
        return spla.LinearOperator(self.shape, matvec=lambda x: self._unpad((Ah @ (self._pad(np.ravel(x)) / s)) / s),
                                   dtype=float)
