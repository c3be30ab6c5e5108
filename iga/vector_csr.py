"""The component-major CSR arrays of a three-component operator (linear elasticity), filled patch by patch.

Unknown ``a * n + i`` is component a (x, y, z) of scalar DOF i (n scalar
DOFs in all), so block (a, b) of patch m lives on m's scalar pattern.  Row
``a n + offset_m + i`` holds scalar row i of m's blocks (a, 0), (a, 1),
(a, 2) one after the other, their columns shifted by 0, n, 2 n: with
``before_m`` the scalar non-zeros of the patches ahead of m (nnz in all),
the row starts at ``a 3 nnz + 3 (before_m + indptr_m[i])`` and entry k of
block (a, b) sits ``b len_i + k`` into it.  Every position is known before
anything is computed, so the assembly writes each entry once, where it
belongs: no per-block matrices, no block-diagonal concatenation, no
reordering pass (:mod:`iga.elastic_volume`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .assembly import CSRPattern, _band_limits
from .errors import ProblemError

__all__ = ["VectorCSR", "pattern_nnz"]


def pattern_nnz(space) -> int:
    """Non-zeros of ``space``'s banded pattern (:func:`iga.assembly.pattern`), from the band limits alone."""
    total = 1
    for d in space.dirs:
        lo, hi = _band_limits(d.n, d.degree)
        total *= int((hi - lo + 1).sum())
    return total


class VectorCSR:
    """The (3 n, 3 n) component-major CSR arrays of patches with DOF ranges ``offsets`` (n_patches + 1,) and
    scalar pattern sizes ``nnz`` (n_patches,), allocated once and written in place (module notes).

    ``indptr`` (3 n + 1,) int64, ``indices`` (9 nnz,) int32 (int64 from 2^31 columns) and ``data``
    (9 nnz,) float are left uninitialised: each patch's rows are written by :meth:`put` (NumPy) or by the
    compiled assembly (:func:`iga.fast_assembly.elastic_into`), and :meth:`matrix` refuses a layout with a
    patch left out.
    """

    def __init__(self, offsets: np.ndarray, nnz: np.ndarray):
        self.offsets = np.asarray(offsets, np.int64)
        nnz = np.asarray(nnz, np.int64)
        self.n = int(self.offsets[-1])
        self.before = np.concatenate([[0], np.cumsum(nnz)[:-1]]).astype(np.int64)
        self.nnz = int(nnz.sum())
        self.indptr = np.empty(3 * self.n + 1, np.int64)
        self.indptr[-1] = 9 * self.nnz
        self.indices = np.empty(9 * self.nnz, np.int64 if 3 * self.n > np.iinfo(np.int32).max else np.int32)
        self.data = np.empty(9 * self.nnz)
        self._written = np.zeros(len(nnz), bool)

    def bases(self, members, a: int) -> np.ndarray:
        """Where the rows of component a of each of ``members`` start: a 3 nnz + 3 before_m (len(members),)."""
        return a * 3 * self.nnz + 3 * self.before[np.asarray(members)]

    def put_rows(self, members, indptr: np.ndarray) -> None:
        """Write where the rows of ``members`` (patches sharing the scalar row pointers ``indptr``) start, for
        all three components: row a n + offset_m + i at a 3 nnz + 3 (before_m + indptr[i])."""
        members = np.asarray(members)
        indptr = np.asarray(indptr, np.int64)
        local = self.offsets[members][:, None] + np.arange(len(indptr) - 1)
        for a in range(3):
            self.indptr[a * self.n + local] = self.bases(members, a)[:, None] + 3 * indptr[:-1]

    def mark(self, members) -> None:
        """Record that the rows of ``members`` were written (by the compiled assembly)."""
        self._written[np.asarray(members)] = True

    def put(self, members, pat: CSRPattern, blocks: dict) -> None:
        """Write the rows of ``members`` (patches sharing the scalar pattern ``pat``): ``blocks[(a, b)]`` the data
        (len(members), pat nnz) of block (a, b), all nine present."""
        members = np.asarray(members)
        indptr = np.asarray(pat.indptr, np.int64)
        length = np.diff(indptr)
        row = np.repeat(np.arange(pat.n), length)
        start = indptr[:-1][row]
        rel = 3 * start + (np.arange(len(row)) - start)  # entry k's place in its vector row, less b len
        shift = length[row]
        offsets = self.offsets[members]
        cols = np.asarray(pat.indices, np.int64)[None, :] + offsets[:, None]
        self.put_rows(members, indptr)
        for a in range(3):
            base = self.bases(members, a)
            for b in range(3):
                pos = base[:, None] + (rel + b * shift)[None, :]
                if a == 0:
                    self.indices[pos] = cols + b * self.n
                self.data[pos] = blocks[(a, b)]
        # the columns of rows a = 1, 2 are those of a = 0, 3 nnz further on (a measured alternative,
        # gathering each component's rows through one permutation, was slower)
        seg = 3 * self.before[members][:, None] + np.arange(3 * len(row))
        for a in (1, 2):
            self.indices[3 * a * self.nnz + seg] = self.indices[seg]
        self.mark(members)

    def matrix(self) -> sp.csr_matrix:
        """The operator, once every patch is written (its arrays, not copies)."""
        if not self._written.all():
            missing = np.flatnonzero(~self._written)
            raise ProblemError(f"the elastic operator is incomplete: patches {missing[:5].tolist()} were not "
                               "assembled")
        return sp.csr_matrix((self.data, self.indices, self.indptr), shape=(3 * self.n, 3 * self.n))
