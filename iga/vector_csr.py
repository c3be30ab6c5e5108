"""The component-major CSR arrays of a c-component operator (c = 3: linear elasticity; c = 1: heat, the
block-diagonal stiffness of the patches), filled patch by patch.

Unknown ``a * n + i`` is component a (x, y, z) of scalar DOF i (n scalar
DOFs in all), so block (a, b) of patch m lives on m's scalar pattern.  Row
``a n + offset_m + i`` holds scalar row i of m's blocks (a, 0), ..., (a, c - 1)
one after the other, their columns shifted by 0, n, ...: with
``before_m`` the scalar non-zeros of the patches ahead of m (nnz in all),
the row starts at ``a c nnz + c (before_m + indptr_m[i])`` and entry k of
block (a, b) sits ``b len_i + k`` into it.  Every position is known before
anything is computed, so the assembly writes each entry once, where it
belongs: no per-block matrices, no block-diagonal concatenation, no
reordering pass (:mod:`iga.elastic_volume`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry.ranges import concatenated_ranges

from .assembly import CSRPattern, _band_limits
from .errors import ProblemError
from .memory import streamed_empty

__all__ = ["VectorCSR", "pattern_nnz"]


def pattern_nnz(space) -> int:
    """Non-zeros of ``space``'s banded pattern (:func:`iga.assembly.pattern`), from the band limits alone."""
    total = 1
    for d in space.dirs:
        lo, hi = _band_limits(d.n, d.degree)
        total *= int((hi - lo + 1).sum())
    return total


class VectorCSR:
    """The (c n, c n) component-major CSR arrays of patches with DOF ranges ``offsets`` (n_patches + 1,) and
    scalar pattern sizes ``nnz`` (n_patches,), allocated once and written in place (module notes).

    ``indptr`` (c n + 1,) int64, ``indices`` (c^2 nnz,) int32 (int64 from 2^31 columns) and
    ``data`` (c^2 nnz,) float are left uninitialised: each patch's rows are written by :meth:`put` (NumPy)
    or by the compiled assembly (:func:`iga.fast_assembly.elastic_into`, the heat stiffness accumulator),
    patches left out on purpose (another MPI rank's) get empty rows by :meth:`skip`, and :meth:`matrix`
    refuses a layout with a patch left out otherwise.
    """

    def __init__(self, offsets: np.ndarray, nnz: np.ndarray, components: int = 3):
        self.offsets = np.asarray(offsets, np.int64)
        nnz = np.asarray(nnz, np.int64)
        self.c = c = int(components)
        self.n = int(self.offsets[-1])
        self.before = np.concatenate([[0], np.cumsum(nnz)[:-1]]).astype(np.int64)
        self.nnz = int(nnz.sum())
        self.indptr = np.empty(c * self.n + 1, np.int64)
        self.indptr[-1] = c * c * self.nnz
        # one component: written once in row order, then streamed, so small pages (iga.memory.streamed_empty);
        # several: each block pass writes a third of every row and the lower blocks are scattered, where huge
        # pages save TLB misses (24^3 elastic assembly: best of 6, 0.20 s on small pages, 0.14 s on NumPy's)
        empty = streamed_empty if c == 1 else np.empty
        self.indices = empty(c * c * self.nnz, np.int64 if c * self.n > np.iinfo(np.int32).max else np.int32)
        self.data = empty(c * c * self.nnz)
        self._written = np.zeros(len(nnz), bool)

    def bases(self, members, a: int) -> np.ndarray:
        """Where the rows of component a of each of ``members`` start: a c nnz + c before_m (len(members),)."""
        return a * self.c * self.nnz + self.c * self.before[np.asarray(members)]

    def put_rows(self, members, indptr: np.ndarray) -> None:
        """Write where the rows of ``members`` (patches sharing the scalar row pointers ``indptr``) start, for
        every component: row a n + offset_m + i at a c nnz + c (before_m + indptr[i])."""
        members = np.asarray(members)
        indptr = np.asarray(indptr, np.int64)
        local = self.offsets[members][:, None] + np.arange(len(indptr) - 1)
        for a in range(self.c):
            self.indptr[a * self.n + local] = self.bases(members, a)[:, None] + self.c * indptr[:-1]

    def skip(self, members) -> None:
        """Empty rows for ``members`` (given zero non-zeros at construction: another rank assembles them)."""
        members = np.asarray(members, np.int64)
        if len(members) and np.any(self.before[members] != np.r_[self.before, self.nnz][members + 1]):
            raise ProblemError("only patches given no non-zeros can be skipped")
        sizes = (self.offsets[members + 1] - self.offsets[members]).astype(np.int64)
        rows = concatenated_ranges(self.offsets[members], sizes)
        for a in range(self.c):
            self.indptr[a * self.n + rows] = np.repeat(self.bases(members, a), sizes)
        self.mark(members)

    def mark(self, members) -> None:
        """Record that the rows of ``members`` were written (by the compiled assembly)."""
        self._written[np.asarray(members)] = True

    def put(self, members, pat: CSRPattern, blocks: dict) -> None:
        """Write the rows of ``members`` (patches sharing the scalar pattern ``pat``): ``blocks[(a, b)]`` the data
        (len(members), pat nnz) of block (a, b), all c^2 present."""
        members = np.asarray(members)
        c = self.c
        indptr = np.asarray(pat.indptr, np.int64)
        if c == 1 and self._put_strided(members, pat, blocks[(0, 0)]):
            return
        length = np.diff(indptr)
        row = np.repeat(np.arange(pat.n), length)
        start = indptr[:-1][row]
        rel = c * start + (np.arange(len(row)) - start)  # entry k's place in its vector row, less b len
        shift = length[row]
        offsets = self.offsets[members]
        cols = np.asarray(pat.indices, np.int64)[None, :] + offsets[:, None]
        self.put_rows(members, indptr)
        for a in range(c):
            base = self.bases(members, a)
            for b in range(c):
                pos = base[:, None] + (rel + b * shift)[None, :]
                if a == 0:
                    self.indices[pos] = cols + b * self.n
                self.data[pos] = blocks[(a, b)]
        # the columns of rows a >= 1 are those of a = 0, c nnz further on (a measured alternative,
        # gathering each component's rows through one permutation, was slower)
        seg = c * self.before[members][:, None] + np.arange(c * len(row))
        for a in range(1, c):
            self.indices[c * a * self.nnz + seg] = self.indices[seg]
        self.mark(members)

    def _put_strided(self, members, pat: CSRPattern, data: np.ndarray) -> bool:
        """One component, members whose blocks lie at equal strides (the same tile patch in every cell of a
        regular paving): the blocks are written through strided views, without index arrays; False (nothing
        written) otherwise."""
        first = self.before[members]
        step = np.diff(first)
        size = len(pat.indices)
        # equal, increasing strides no shorter than a block: the strided windows are disjoint and in bounds
        if not len(members) or (len(members) > 1 and not (np.all(step == step[0]) and step[0] >= size)):
            return False
        stride = int(step[0]) if len(members) > 1 else 0
        self.put_rows(members, pat.indptr)
        for target, values in ((self.data, data), (self.indices, None)):
            view = np.lib.stride_tricks.as_strided(target[int(first[0]):], shape=(len(members), size),
                                                   strides=(stride * target.itemsize, target.itemsize))
            if values is None:
                view[...] = np.asarray(pat.indices)[None, :]
                view += self.offsets[members].astype(target.dtype)[:, None]
            else:
                view[...] = values
        self.mark(members)
        return True

    def matrix(self) -> sp.csr_matrix:
        """The operator, once every patch is written (its arrays, not copies)."""
        if not self._written.all():
            missing = np.flatnonzero(~self._written)
            raise ProblemError(f"the operator is incomplete: patches {missing[:5].tolist()} were not "
                               "assembled")
        return sp.csr_matrix((self.data, self.indices, self.indptr), shape=(self.c * self.n, self.c * self.n))
