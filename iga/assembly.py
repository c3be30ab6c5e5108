"""Sum-factorised assembly of tensor-product forms, written straight into CSR.

A bilinear form on a tensor-product space is a sum of *terms*

    a(N_i, N_j) = sum_terms  sum_q  F(q) prod_k  d^{a_k} N_{i_k}(q_k) d^{b_k} N_{j_k}(q_k),

with a field ``F`` on the tensor grid of Gauss points (it already contains
quadrature weights, |J| and the material) and derivative orders ``(a_k, b_k)``
per direction.  We contract one quadrature axis at a time against the windowed
1-D tables of :class:`iga.space.Space1D`, last direction first, turning a
quadrature axis of length ``nq_k`` into a pair (basis index ``i_k``, band
offset ``d_k``).  No element matrices and no COO triplets are ever formed; the
banded result maps onto a fixed CSR pattern.  Terms that share the first
direction's derivative orders are summed before the final (most expensive)
contraction, so the stiffness needs 4 final contractions instead of 9.

Everything is batched over patches that share a space (leading axis P).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .space import Space1D, TensorSpace


def _contract(X: np.ndarray, axis: int, sp1: Space1D, table: np.ndarray) -> np.ndarray:
    """Replace quadrature axis ``axis`` of X by ``(n,)`` (table (n, L)) or ``(n, D)`` (table (n, D, L))."""
    Xm = np.moveaxis(X, axis, -1)
    lead = Xm.shape[:-1]
    M = int(np.prod(lead, dtype=int))
    Xp = np.empty((M, sp1.nq + 1))
    Xp[:, :-1] = Xm.reshape(M, sp1.nq)
    Xp[:, -1] = 0.0  # the pad column that out-of-range window points read
    G = Xp[:, sp1.qidx]  # (M, n, L)
    if table.ndim == 2:  # load vector: (M, n, L) . (n, L) -> (M, n)
        R = np.einsum("mnl,nl->mn", G, table)
        return np.moveaxis(R.reshape(lead + (sp1.n,)), -1, axis)
    # (n, M, L) @ (n, L, D) -> (n, M, D): one small GEMM per basis index
    R = np.matmul(G.transpose(1, 0, 2), table.transpose(0, 2, 1))
    R = R.transpose(1, 0, 2).reshape(lead + (sp1.n, table.shape[1]))
    return np.moveaxis(R, (-2, -1), (axis, axis + 1))


def banded_form(space: TensorSpace, terms) -> np.ndarray:
    """Assemble ``terms`` = [(F, ((a_1, b_1), ..., (a_d, b_d))), ...] with F of shape (P,) + qshape.

    Returns the banded array (P, n_1, D_1, ..., n_d, D_d) with D_k = 2 p_k + 1:
    entry [i, d] couples DOF i with j = i + d - p in every direction.
    """
    d = space.dim
    groups: dict = {}
    for F, variants in terms:
        X = F
        for k in range(d - 1, 0, -1):  # last direction first; axis k+1 (after P) is still quadrature
            a, b = variants[k]
            X = _contract(X, 1 + k, space.dirs[k], space.dirs[k].W(a, b))
        key = tuple(variants[0])
        groups[key] = X if key not in groups else groups[key] + X
    out = None
    for (a, b), X in groups.items():
        R = _contract(X, 1, space.dirs[0], space.dirs[0].W(a, b))
        out = R if out is None else out + R
    return out


def load_form(space: TensorSpace, F: np.ndarray) -> np.ndarray:
    """sum_q F(q) N_i(q) for a field F (P,) + qshape -> (P,) + shape."""
    X = F
    for k in range(space.dim - 1, -1, -1):
        X = _contract(X, 1 + k, space.dirs[k], space.dirs[k].window_values(0))
    return X


@dataclass(eq=False)
class CSRPattern:
    """CSR pattern of a banded tensor-product operator on one space.

    ``take`` selects, from the banded array (n_1, ..., n_d, D_1, ..., D_d)
    flattened, the entries that exist, in CSR order.
    """

    indptr: np.ndarray
    indices: np.ndarray
    take: np.ndarray
    n: int


@lru_cache(maxsize=32)
def _pattern(shape: tuple, degrees: tuple) -> CSRPattern:
    d = len(shape)
    Ds = [2 * p + 1 for p in degrees]
    grids = np.meshgrid(*[np.arange(n) for n in shape], *[np.arange(D) for D in Ds], indexing="ij")
    valid = np.ones(grids[0].shape, bool)
    col = np.zeros(grids[0].shape, np.int64)
    for k in range(d):
        j = grids[k] + grids[d + k] - degrees[k]
        valid &= (j >= 0) & (j < shape[k])
        col = col * shape[k] + np.clip(j, 0, shape[k] - 1)
    n = int(np.prod(shape))
    valid = valid.reshape(n, -1)
    counts = valid.sum(axis=1)
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    take = np.flatnonzero(valid.ravel())
    indices = col.reshape(-1)[take]
    return CSRPattern(indptr, indices, take, n)


def pattern(space: TensorSpace) -> CSRPattern:
    return _pattern(space.shape, tuple(s.degree for s in space.dirs))


def banded_to_csr_data(space: TensorSpace, banded: np.ndarray) -> np.ndarray:
    """(P, n_1, D_1, ..., n_d, D_d) -> (P, nnz) CSR data in :func:`pattern` order."""
    d = space.dim
    P = banded.shape[0]
    perm = [0] + [1 + 2 * k for k in range(d)] + [2 + 2 * k for k in range(d)]
    flat = np.transpose(banded, perm).reshape(P, -1)
    return flat[:, pattern(space).take]


def block_diagonal_csr(blocks, n_total: int) -> sp.csr_matrix:
    """Global CSR from per-patch blocks [(offset, CSRPattern, data (nnz,)), ...] sorted by offset."""
    blocks = sorted(blocks, key=lambda t: t[0])
    indptr = [np.zeros(1, np.int64)]
    indices, data = [], []
    nnz = 0
    expected = 0
    for off, pat, dat in blocks:
        if off != expected:
            raise AssertionError("patch DOF ranges must be contiguous")
        indptr.append(pat.indptr[1:] + nnz)
        indices.append(pat.indices + off)
        data.append(dat)
        nnz += len(dat)
        expected = off + pat.n
    if expected != n_total:
        raise AssertionError("patch DOF ranges do not cover the system")
    idx = np.concatenate(indices)
    return sp.csr_matrix(
        (np.concatenate(data), idx.astype(np.int32) if n_total < 2**31 else idx, np.concatenate(indptr)),
        shape=(n_total, n_total),
    )
