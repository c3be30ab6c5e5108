"""Sum-factorised assembly of tensor-product forms, written straight into CSR.

A bilinear form on a tensor-product space is a sum of *terms*

    a(N_i, N_j) = sum_terms  sum_q  F(q) prod_k  d^{a_k} N_{i_k}(q_k) d^{b_k} N_{j_k}(q_k),

with a field ``F`` on the tensor grid of Gauss points (it already contains
quadrature weights, |J| and the material) and derivative orders ``(a_k, b_k)``
per direction.  We contract one quadrature axis at a time, last direction
first: each contraction is one sparse ``(n_k (2 p_k + 1)) x nq_k`` matrix
(built once per 1-D space from the windowed tables of
:class:`iga.discretisation.space.Space1D`) times the field laid out with the contracted axis
first, so NumPy never gathers or copies windows.  A quadrature axis of length
``nq_k`` becomes a pair (basis index ``i_k``, band offset ``d_k``).  No element
matrices and no COO triplets are formed; the banded result is gathered once
into the CSR data of a fixed pattern.  Terms that share the first direction's
derivative orders are summed before the last (most expensive) contraction.

Everything is batched over patches that share a space (trailing axis P).
This is the NumPy/SciPy path; :mod:`iga.assembly.compiled` computes the same
stiffness with compiled kernels (numba) for large 3-D patches.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from geometry.cache import memo
import scipy.sparse as sp

from geometry.ranges import concatenated_ranges
from geometry.resources import usable_cores

from iga.errors import ProblemError
from iga.discretisation.space import Space1D, TensorSpace


def stage_matrix(sp1: Space1D, a: int, b: int | None) -> sp.csr_matrix:
    """Sparse contraction matrix of one direction.

    ``b is None``: load-vector stage, shape (n, nq): row i holds d^a N_i at the
    quadrature points.  Otherwise (n (2p+1), nq): row (i, d) holds
    d^a N_i d^b N_{i+d-p} at the quadrature points.
    """
    key = ("stage", a, b)
    cache = sp1.tables
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
    contiguous rows of X, faster than batched per-element GEMMs on tiny
    (2p+1) x g blocks or window gathers (docs/performance.md).
    """
    M = stage_matrix(sp1, a, b)
    rest = X.shape[1:]
    Y = _spmm(M, X.reshape(X.shape[0], -1))
    return Y.reshape((sp1.n,) + ((2 * sp1.degree + 1,) if b is not None else ()) + rest)


def _spmm(M: sp.csr_matrix, X: np.ndarray) -> np.ndarray:
    """M @ X for a dense X, with the output rows split over the CPU cores when large.

    SciPy's sparse kernels release the GIL, so threads scale; splitting rows
    needs no copy of X.
    """
    workers = usable_cores()
    if workers == 1 or X.size < (1 << 20) or M.shape[0] < 2 * workers:
        return np.asarray(M @ X)
    cuts = np.linspace(0, M.shape[0], workers + 1).astype(int)
    Y = np.empty((M.shape[0], X.shape[1]))

    def part(k):
        Y[cuts[k] : cuts[k + 1]] = M[cuts[k] : cuts[k + 1]] @ X

    with ThreadPoolExecutor(workers) as pool:  # per call: starting threads is tiny next to 1M-entry products
        list(pool.map(part, range(workers)))
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
        groups.setdefault(tuple(variants[0]), []).append((F, variants))
    out = None
    sp0 = space.dirs[0]
    # one group at a time (its partial sum, then its last contraction): bounded memory
    for (a, b), members in groups.items():
        X = None
        for F, variants in members:
            Y = _run(space, F, variants, 1) if space.dim > 1 else np.array(np.moveaxis(F, 0, -1))  # own copy: X += Y
            if X is None:
                X = Y
            else:
                X += Y
            del Y
        R = _contract_first(_to_front(X, 0), sp0, a, b)
        del X
        if out is None:
            out = R
        else:
            out += R
        del R
    return out


def load_form(space: TensorSpace, F: np.ndarray) -> np.ndarray:
    """sum_q F(q) N_i(q) for a field F (P,) + qshape -> (P,) + shape."""
    X = np.ascontiguousarray(np.moveaxis(F, 0, -1))  # (q_1, ..., q_d, P)
    for k in range(space.dim - 1, -1, -1):
        X = _contract_first(_to_front(X, k), space.dirs[k], 0, None)
        X = np.moveaxis(X, 0, k) if k > 0 else X
    return np.moveaxis(X, -1, 0)


def derivative_load_form(space: TensorSpace, terms) -> np.ndarray:
    """sum over terms of sum_q G(q) prod_k d^{a_k} N_{i_k}(q_k) for terms [(G (P,) + qshape, ((a_k, None),) * d)]
    -> (P,) + shape (a load that tests derivatives, e.g. int g div v)."""
    out = None
    for G, variants in terms:
        X = np.ascontiguousarray(np.moveaxis(G, 0, -1))
        for k in range(space.dim - 1, -1, -1):
            X = _contract_first(_to_front(X, k), space.dirs[k], variants[k][0], None)
            X = np.moveaxis(X, 0, k) if k > 0 else X
        out = X if out is None else out + X
    return np.moveaxis(out, -1, 0)


@dataclass(eq=False)
class CSRPattern:
    """CSR pattern of a banded tensor-product operator on one space.

    ``take[e]`` is the flat index, in the banded layout (n_1, D_1, ..., n_d,
    D_d), of CSR entry ``e``; ``transpose[e]`` is the CSR position of the
    mirrored entry (j, i), so ``data[transpose]`` is the data of the transpose.
    ``derived`` keeps index arrays computed from these once per pattern (the
    patterns themselves are cached by :func:`pattern`), e.g. the order of a
    component-major operator's rows (:func:`iga.assembly.vector_csr.interleaved`).
    """

    indptr: np.ndarray
    indices: np.ndarray
    take: np.ndarray
    transpose: np.ndarray
    n: int
    derived: dict = field(default_factory=dict, repr=False)


def band_limits(n: int, p: int):
    """Valid band offsets [lo, hi] per row of a 1-D band (column j = i + d - p inside [0, n))."""
    i = np.arange(n)
    return np.maximum(0, p - i), np.minimum(2 * p, n - 1 - i + p)


def _pattern_1d(n: int, p: int, itype) -> CSRPattern:
    lo, hi = band_limits(n, p)
    counts = hi - lo + 1
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    row = np.repeat(np.arange(n), counts)
    d = np.arange(indptr[-1]) - indptr[row] + lo[row]  # band offset of each entry
    j = row + d - p
    take = (row * (2 * p + 1) + d).astype(itype)
    transpose = (indptr[j] + (2 * p - d) - lo[j]).astype(itype)
    return CSRPattern(indptr, j.astype(np.int32), take, transpose, n)


def _pattern_combine(n0: int, p0: int, B: CSRPattern, banded_B: int, itype) -> CSRPattern:
    """Pattern of (1-D band in the leading direction) x (pattern B of the remaining directions).

    Rows (i0, rB) in C order; each row's entries run over the valid offsets
    d0 and, within each, over row rB of B, so columns stay sorted.  The
    entries of one leading row i0 follow a template of B's arrays; for rows
    whose band and whose neighbours' bands are full (all but about 4 p0 rows)
    every array is ``i0 * stride + template``, written in one pass.
    """
    D0 = 2 * p0 + 1
    nB, nnzB = B.n, len(B.indices)
    lo, hi = band_limits(n0, p0)
    c0 = hi - lo + 1
    cB = np.diff(B.indptr)
    rowB = np.repeat(np.arange(nB), cB)
    start = np.zeros(n0 + 1, np.int64)
    np.cumsum(c0 * nnzB, out=start[1:])
    indptr = np.concatenate([(start[:-1, None] + c0[:, None] * B.indptr[None, :-1]).ravel(), [start[-1]]])
    total = int(start[-1])
    indices = np.empty(total, np.int32 if n0 * nB < 2**31 else np.int64)
    take = np.empty(total, itype)
    transpose = np.empty(total, itype)
    within = B.transpose.astype(np.int64) - B.indptr[B.indices]  # mirror's position inside its B row
    colB = B.indices.astype(np.int64)
    templates: dict = {}

    def template(l0, m0):
        # CSR order of one leading row: (rB, k0, eB within row rB) -> entry eB of B and offset index k0
        if (l0, m0) not in templates:
            k0 = np.arange(m0)[:, None]
            pos = (m0 * B.indptr[rowB][None, :] + k0 * cB[rowB][None, :]
                   + (np.arange(nnzB) - B.indptr[rowB])[None, :]).ravel()
            E = np.empty(m0 * nnzB, np.int64)
            K = np.empty(m0 * nnzB, np.int64)
            E[pos] = np.broadcast_to(np.arange(nnzB), (m0, nnzB)).ravel()
            K[pos] = np.broadcast_to(k0, (m0, nnzB)).ravel()
            templates[(l0, m0)] = (E, l0 + K)
        return templates[(l0, m0)]

    def row_arrays(i0):  # general formulas for one leading row
        E, d0 = template(int(lo[i0]), int(c0[i0]))
        j0 = i0 + d0 - p0
        cb = colB[E]
        ind = j0 * nB + cb
        tk = (i0 * D0 + d0) * banded_B + B.take[E]
        tr = start[j0] + c0[j0] * B.indptr[cb] + (2 * p0 - d0 - lo[j0]) * cB[cb] + within[E]
        return ind, tk, tr

    deep = np.arange(n0)
    deep = deep[(deep >= 2 * p0) & (deep <= n0 - 1 - 2 * p0)]
    for i0 in range(n0):
        if len(deep) and deep[0] <= i0 <= deep[-1]:
            continue
        a, b = int(start[i0]), int(start[i0 + 1])
        for out, val in zip((indices, take, transpose), row_arrays(i0)):
            out[a:b] = val
    if len(deep):
        r0, r1 = int(deep[0]), int(deep[-1])
        a, b = int(start[r0]), int(start[r1 + 1])
        R = r1 - r0 + 1
        ind, tk, tr = row_arrays(r0)  # row r0; row i0 adds (i0 - r0) * stride
        strides = (nB, D0 * banded_B, D0 * nnzB)
        steps = np.arange(R, dtype=np.int64)[:, None]
        for out, val, stride in zip((indices, take, transpose), (ind, tk, tr), strides):
            np.add((steps * stride).astype(out.dtype), val.astype(out.dtype)[None, :], out=out[a:b].reshape(R, -1))
    return CSRPattern(indptr, indices, take, transpose, n0 * nB)


@memo(16)
def _pattern(shape: tuple, degrees: tuple) -> CSRPattern:
    """CSR pattern of a banded tensor-product operator, built direction by direction (last first)."""
    Ds = [2 * p + 1 for p in degrees]
    banded = int(np.prod([n * D for n, D in zip(shape, Ds)]))
    nnz_max = int(np.prod(shape)) * int(np.prod(Ds))
    itype = np.int64 if max(banded, nnz_max) >= 2**31 else np.int32
    pat = _pattern_1d(shape[-1], degrees[-1], itype)
    size = shape[-1] * Ds[-1]
    for n, p in zip(reversed(shape[:-1]), reversed(degrees[:-1])):
        pat = _pattern_combine(n, p, pat, size, itype)
        size *= n * (2 * p + 1)
    return pat


CACHE_NNZ = 1 << 24  # larger patterns are rebuilt rather than kept (8 bytes per entry each)


def pattern(space: TensorSpace) -> CSRPattern:
    """CSR pattern of ``space``'s banded operators (cached for the many small spaces of micro-structures)."""
    degrees = tuple(s.degree for s in space.dirs)
    nnz_max = space.ndof * int(np.prod([2 * p + 1 for p in degrees]))
    if nnz_max > CACHE_NNZ:
        return _pattern.__wrapped__(space.shape, degrees)
    pat = _pattern(space.shape, degrees)
    for a in (pat.indptr, pat.indices):  # shared by every matrix built on it: nobody may write
        a.setflags(write=False)
    return pat


def banded_to_csr_data(space: TensorSpace, banded: np.ndarray, pat: CSRPattern | None = None) -> np.ndarray:
    """(n_1, D_1, ..., n_d, D_d, P) banded array -> (P, nnz) CSR data in :func:`pattern` order."""
    P = banded.shape[-1]
    return banded.reshape(-1, P)[(pat or pattern(space)).take].T


def block_diagonal_csr(blocks, n_total: int, partial: bool = False) -> sp.csr_matrix:
    """Global CSR from per-patch blocks [(offset, CSRPattern, data (nnz,)), ...].

    ``partial``: the blocks may leave DOF ranges out (one MPI rank's patches); their rows stay empty.
    """
    blocks = sorted(blocks, key=lambda t: t[0])
    if len(blocks) == 1 and blocks[0][0] == 0 and blocks[0][1].n == n_total:
        _, pat, dat = blocks[0]
        return sp.csr_matrix((dat, pat.indices, pat.indptr), shape=(n_total, n_total))
    indptr = [np.zeros(1, np.int64)]
    indices, data = [], []
    nnz = 0
    expected = 0
    for off, pat, dat in blocks:
        if off != expected and not (partial and off > expected):
            raise ProblemError(f"patch DOF ranges must follow each other: a block starts at {off}, expected "
                               f"{expected} (the offsets do not match the spaces)")
        indptr.append(np.full(off - expected, nnz, np.int64))  # the empty rows of patches left out
        indptr.append(pat.indptr[1:] + nnz)
        indices.append(pat.indices.astype(np.int64) + off)
        data.append(dat)
        nnz += len(dat)
        expected = off + pat.n
    if expected != n_total and not partial:
        raise ProblemError(f"patch DOF ranges end at {expected}, but the system has {n_total} unknowns (the "
                           "offsets do not match the spaces)")
    indptr.append(np.full(n_total - expected, nnz, np.int64))
    idx = np.concatenate(indices)
    return sp.csr_matrix(
        (np.concatenate(data), idx.astype(np.int32) if n_total < 2**31 else idx, np.concatenate(indptr)),
        shape=(n_total, n_total),
    )


def stiffness_data(space: TensorSpace, C: dict, pat: CSRPattern | None = None) -> np.ndarray:
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
    pat = pat or pattern(space)
    H = banded_to_csr_data(space, banded_form(space, terms), pat)
    H += H[:, pat.transpose]
    return H


def add_within(K: sp.csr_matrix, M: sp.spmatrix) -> sp.csr_matrix:
    """``K + M`` written into K's values where M's non-zeros lie in K's pattern (a boundary mass inside the
    volume pattern of its patches: no second copy of K at the peak of the assembly), else a new matrix.

    Only the rows M touches are searched (one sorted search over their keys).  Returns K (modified) or the sum.
    """
    M = sp.csr_matrix(M)
    M.sum_duplicates()
    if M.nnz == 0:
        return K
    if not (K.has_sorted_indices and K.shape == M.shape):
        return (K + M).tocsr()
    rows = np.flatnonzero(np.diff(M.indptr))
    starts, ends = K.indptr[rows].astype(np.int64), K.indptr[rows + 1].astype(np.int64)
    lengths = ends - starts
    n = np.int64(K.shape[1])
    where = concatenated_ranges(starts, lengths)  # the positions of those rows' entries in K
    keys = np.repeat(np.arange(len(rows), dtype=np.int64), lengths) * n + K.indices[where]
    m_rows = np.repeat(np.arange(len(rows), dtype=np.int64), np.diff(M.indptr)[rows])
    wanted = m_rows * n + M.indices
    pos = np.searchsorted(keys, wanted)
    found = pos < len(keys)
    found[found] = keys[pos[found]] == wanted[found]
    if not found.all():
        return (K + M).tocsr()
    K.data[where[pos]] += M.data
    return K
