"""Sum-factorised assembly of tensor-product forms, written straight into CSR.

A bilinear form on a tensor-product space is a sum of *terms*

    a(N_i, N_j) = sum_terms  sum_q  F(q) prod_k  d^{a_k} N_{i_k}(q_k) d^{b_k} N_{j_k}(q_k),

with a field ``F`` on the tensor grid of Gauss points (it already contains
quadrature weights, |J| and the material) and derivative orders ``(a_k, b_k)``
per direction.  We contract one quadrature axis at a time, last direction
first: each contraction is one sparse ``(n_k (2 p_k + 1)) x nq_k`` matrix
(built once per 1-D space from the windowed tables of
:class:`iga.space.Space1D`) times the field laid out with the contracted axis
first, so NumPy never gathers or copies windows.  A quadrature axis of length
``nq_k`` becomes a pair (basis index ``i_k``, band offset ``d_k``).  No element
matrices and no COO triplets are formed; the banded result is gathered once
into the CSR data of a fixed pattern.  Terms that share the first direction's
derivative orders are summed before the last (most expensive) contraction.

Everything is batched over patches that share a space (trailing axis P).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .space import Space1D, TensorSpace


def stage_matrix(sp1: Space1D, a: int, b: int | None) -> sp.csr_matrix:
    """Sparse contraction matrix of one direction.

    ``b is None``: load-vector stage, shape (n, nq): row i holds d^a N_i at the
    quadrature points.  Otherwise (n (2p+1), nq): row (i, d) holds
    d^a N_i d^b N_{i+d-p} at the quadrature points.
    """
    key = (a, b)
    cache = sp1.__dict__.setdefault("_stage", {})
    if key not in cache:
        W = sp1.window_values(a)[:, None, :] if b is None else sp1.W(a, b)  # (n, D, L)
        n, D, L = W.shape
        rows = np.broadcast_to(np.arange(n * D).reshape(n, D, 1), W.shape).ravel()
        cols = np.broadcast_to(sp1.qidx[:, None, :], W.shape).ravel()
        vals = W.ravel()
        keep = (cols < sp1.nq) & (vals != 0)
        cache[key] = sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(n * D, sp1.nq))
    return cache[key]


def _contract_first(X: np.ndarray, sp1: Space1D, a: int, b: int | None) -> np.ndarray:
    """Contract the first (quadrature) axis of X (nq, ...) -> (n, D, ...), or (n, ...) for a load stage.

    One sparse (n D) x nq matrix times X viewed as (nq, rest): SciPy streams
    contiguous rows of X, and measured faster than batched per-element GEMMs
    (tiny (2p+1) x g blocks) or window gathers.
    """
    M = stage_matrix(sp1, a, b)
    rest = X.shape[1:]
    Y = _spmm(M, X.reshape(X.shape[0], -1))
    return Y.reshape((sp1.n,) + ((2 * sp1.degree + 1,) if b is not None else ()) + rest)


_POOL = None


def _spmm(M: sp.csr_matrix, X: np.ndarray) -> np.ndarray:
    """M @ X for a dense X, with the output rows split over the CPU cores when large.

    SciPy's sparse kernels release the GIL, so threads scale (measured 1.6x on
    2 cores); splitting rows needs no copy of X.
    """
    global _POOL
    workers = os.cpu_count() or 1
    if workers == 1 or X.size < (1 << 20) or M.shape[0] < 2 * workers:
        return np.asarray(M @ X)
    if _POOL is None:
        _POOL = ThreadPoolExecutor(workers)
    cuts = np.linspace(0, M.shape[0], workers + 1).astype(int)
    Y = np.empty((M.shape[0], X.shape[1]))

    def part(k):
        Y[cuts[k] : cuts[k + 1]] = M[cuts[k] : cuts[k + 1]] @ X

    list(_POOL.map(part, range(workers)))
    return Y


def _to_front(X: np.ndarray, axis: int) -> np.ndarray:
    return np.ascontiguousarray(np.moveaxis(X, axis, 0))


def _run(space: TensorSpace, F: np.ndarray, variants, upto: int) -> np.ndarray:
    """Contract directions d-1 .. upto of F (P, q_1, ..., q_d); returns axes-first layout.

    Output layout: (q_1 .. q_upto-1 still quadrature ..., then for contracted
    directions k = upto..d-1: (n_k, D_k), then P), with the next axis to
    contract (upto - 1) in front when upto > 0.
    """
    d = space.dim
    X = np.ascontiguousarray(np.moveaxis(F, 0, -1))  # (q_1, ..., q_d, P)
    for k in range(d - 1, upto - 1, -1):
        X = _to_front(X, k)  # the quadrature axis of direction k, which sits at position k
        a, b = variants[k]
        X = _contract_first(X, space.dirs[k], a, b)
        # X: (n_k, D_k, q_1 .. q_{k-1}, [previous (n, D) pairs], P) -> move the pair after q_{k-1}
        X = np.moveaxis(X, (0, 1), (k, k + 1)) if k > 0 else X
    return X


def banded_form(space: TensorSpace, terms) -> np.ndarray:
    """Assemble ``terms`` = [(F, ((a_1, b_1), ..., (a_d, b_d))), ...], F of shape (P,) + qshape.

    Returns the banded array (n_1, D_1, ..., n_d, D_d, P), D_k = 2 p_k + 1:
    entry [i, d] couples DOF i with j = i + d - p in every direction.
    """
    groups: dict = {}
    for F, variants in terms:
        X = _run(space, F, variants, 1) if space.dim > 1 else np.ascontiguousarray(np.moveaxis(F, 0, -1))
        key = tuple(variants[0])
        groups[key] = X if key not in groups else groups[key] + X
    out = None
    sp0 = space.dirs[0]
    for (a, b), X in groups.items():
        R = _contract_first(_to_front(X, 0), sp0, a, b)
        out = R if out is None else out + R
    return out


def load_form(space: TensorSpace, F: np.ndarray) -> np.ndarray:
    """sum_q F(q) N_i(q) for a field F (P,) + qshape -> (P,) + shape."""
    X = np.ascontiguousarray(np.moveaxis(F, 0, -1))  # (q_1, ..., q_d, P)
    for k in range(space.dim - 1, -1, -1):
        X = _contract_first(_to_front(X, k), space.dirs[k], 0, None)
        X = np.moveaxis(X, 0, k) if k > 0 else X
    return np.moveaxis(X, -1, 0)


@dataclass(eq=False)
class CSRPattern:
    """CSR pattern of a banded tensor-product operator on one space.

    ``take[e]`` is the flat index, in the banded layout (n_1, D_1, ..., n_d,
    D_d), of CSR entry ``e``; ``transpose[e]`` is the CSR position of the
    mirrored entry (j, i), so ``data[transpose]`` is the data of the transpose.
    """

    indptr: np.ndarray
    indices: np.ndarray
    take: np.ndarray
    transpose: np.ndarray
    n: int


@lru_cache(maxsize=16)
def _pattern(shape: tuple, degrees: tuple) -> CSRPattern:
    d = len(shape)
    Ds = [2 * p + 1 for p in degrees]
    itype = np.int64 if int(np.prod(shape)) * int(np.prod(Ds)) >= 2**31 else np.int32

    def bcast(arr_k, k):
        # (n_k, D_k) -> broadcastable to (n_1, .., n_d, D_1, .., D_d) (CSR order: rows, then band)
        sh = [1] * (2 * d)
        sh[k], sh[d + k] = arr_k.shape
        return arr_k.reshape(sh)

    valid = None
    col = None
    banded = None
    mirror = None
    for k in range(d):
        n, D, p = shape[k], Ds[k], degrees[k]
        i = np.arange(n)[:, None]
        dd = np.arange(D)[None, :]
        j = i + dd - p
        ok = (j >= 0) & (j < n)
        jc = np.clip(j, 0, n - 1)
        v = bcast(ok, k)
        valid = v if valid is None else valid & v
        c = bcast(jc.astype(itype), k)
        col = c if col is None else col * n + c
        # flat index in the banded layout (n_1, D_1, n_2, D_2, ...)
        bi = bcast((i * D + dd).astype(itype), k)
        banded = bi if banded is None else banded * (n * D) + bi
        mi = bcast((jc * D + (2 * p - dd)).astype(itype), k)  # entry (j, 2p - d): the mirror
        mirror = mi if mirror is None else mirror * (n * D) + mi
    n_rows = int(np.prod(shape))
    full = tuple(shape) + tuple(Ds)
    valid = np.broadcast_to(valid, full).reshape(n_rows, -1)
    counts = valid.sum(axis=1)
    indptr = np.zeros(n_rows + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    sel = np.flatnonzero(valid.ravel())
    indices = np.broadcast_to(col, full).reshape(-1)[sel].astype(np.int32 if n_rows < 2**31 else np.int64)
    take = np.broadcast_to(banded, full).reshape(-1)[sel]
    # CSR position of each banded index, then of each mirror
    pos = np.full(int(np.prod([n * D for n, D in zip(shape, Ds)])), -1, dtype=itype)
    pos[take] = np.arange(len(take), dtype=itype)
    transpose = pos[np.broadcast_to(mirror, full).reshape(-1)[sel]]
    return CSRPattern(indptr, indices, take, transpose, n_rows)


def pattern(space: TensorSpace) -> CSRPattern:
    return _pattern(space.shape, tuple(s.degree for s in space.dirs))


def banded_to_csr_data(space: TensorSpace, banded: np.ndarray) -> np.ndarray:
    """(n_1, D_1, ..., n_d, D_d, P) banded array -> (P, nnz) CSR data in :func:`pattern` order."""
    P = banded.shape[-1]
    return banded.reshape(-1, P)[pattern(space).take].T


def block_diagonal_csr(blocks, n_total: int) -> sp.csr_matrix:
    """Global CSR from per-patch blocks [(offset, CSRPattern, data (nnz,)), ...]."""
    blocks = sorted(blocks, key=lambda t: t[0])
    if len(blocks) == 1 and blocks[0][0] == 0 and blocks[0][1].n == n_total:
        _, pat, dat = blocks[0]
        return sp.csr_matrix((dat, pat.indices, pat.indptr), shape=(n_total, n_total))
    indptr = [np.zeros(1, np.int64)]
    indices, data = [], []
    nnz = 0
    expected = 0
    for off, pat, dat in blocks:
        if off != expected:
            raise AssertionError("patch DOF ranges must be contiguous")
        indptr.append(pat.indptr[1:] + nnz)
        indices.append(pat.indices.astype(np.int64) + off)
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


def stiffness_data(space: TensorSpace, C: dict) -> np.ndarray:
    """CSR data (P, nnz) of sum_rs int C_rs d_r N_i d_s N_j for a symmetric C.

    ``C[(r, s)]`` for r <= s, each (P,) + qshape.  With D the diagonal terms
    and S the off-diagonal ones (r < s), K = D + S + S^T = H + H^T for
    H = D / 2 + S: all six terms go through one banded form, and the transpose
    is a gather of the CSR data.
    """
    d = space.dim
    terms = []
    for (r, s), F in C.items():
        variants = tuple((int(k == r), int(k == s)) for k in range(d))
        terms.append((0.5 * F if r == s else F, variants))
    H = banded_to_csr_data(space, banded_form(space, terms))
    H += H[:, pattern(space).transpose]
    return H
