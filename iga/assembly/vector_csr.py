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
reordering pass (:mod:`iga.elasticity.volume`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry.ranges import concatenated_ranges

from iga.assembly.tensor import CSRPattern, band_limits
from iga.errors import ProblemError
from iga.app.memory import streamed_empty

__all__ = ["VectorCSR", "pattern_nnz", "interleaved"]


def pattern_nnz(space) -> int:
    """Non-zeros of ``space``'s banded pattern (:func:`iga.assembly.tensor.pattern`), from the band limits alone."""
    total = 1
    for d in space.dirs:
        lo, hi = band_limits(d.n, d.degree)
        total *= int((hi - lo + 1).sum())
    return total


#: scalar non-zeros up to which a pattern keeps its interleaving order (24 bytes per non-zero for c = 3: 6 MiB)
_KEEP_NNZ = 1 << 18


def interleaved(pat: CSRPattern, c: int) -> np.ndarray:
    """The order (c nnz,) of c blocks' data on ``pat`` along the rows of one component of a component-major
    operator: stacked as entry b nnz + k of block b, they run as row 0 of blocks 0 .. c - 1, then row 1 of
    each, ... (module notes).  Kept on the pattern (``pat.derived``) when it is small (the many small patches of
    micro-structures, whose patterns :func:`iga.assembly.tensor.pattern` caches); a large one's is made each time."""
    key = ("interleaved", c)
    order = pat.derived.get(key)
    if order is None:
        indptr = np.asarray(pat.indptr, np.int64)
        nnz = int(indptr[-1])
        length = np.diff(indptr)
        row = np.repeat(np.arange(pat.n), length)
        start = indptr[:-1][row]
        # entry k of block b goes b len_i + (k - start_i) into row i's run, which starts at c start_i
        dest = (c * start + (np.arange(nnz) - start))[None, :] + np.arange(c)[:, None] * length[row][None, :]
        order = np.empty(c * nnz, np.int64)
        order[dest.ravel()] = np.arange(c * nnz)
        if nnz <= _KEEP_NNZ:
            pat.derived[key] = order
    return order


def _runs(target: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray | None:
    """A (len(starts), width) view of ``target`` from each start, when the starts step evenly by at least
    ``width`` (the runs are then disjoint); None otherwise."""
    step = np.diff(starts)
    if len(starts) > 1 and not (np.all(step == step[0]) and step[0] >= width):
        return None
    stride = int(step[0]) if len(starts) > 1 else 0
    return np.lib.stride_tricks.as_strided(target[int(starts[0]):], shape=(len(starts), width),
                                           strides=(stride * target.itemsize, target.itemsize))


def _write_runs(target: np.ndarray, starts: np.ndarray, values: np.ndarray) -> None:
    """target[starts[m] : starts[m] + width] = values[m] for every m (values (len(starts), width))."""
    if not len(starts):
        return
    view = _runs(target, starts, values.shape[1])
    if view is not None:
        view[...] = values
    else:
        target[starts[:, None] + np.arange(values.shape[1])] = values


class VectorCSR:
    """The (c n, c n) component-major CSR arrays of patches with DOF ranges ``offsets`` (n_patches + 1,) and
    scalar pattern sizes ``nnz`` (n_patches,), allocated once and written in place (module notes).

    ``indptr`` (c n + 1,) int64, ``indices`` (c^2 nnz,) int32 (int64 from 2^31 columns) and
    ``data`` (c^2 nnz,) float are left uninitialised: each patch's rows are written by :meth:`put` (NumPy)
    or by the compiled assembly (:func:`iga.assembly.compiled.elastic_into`, the heat stiffness accumulator),
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
        # one component: written once in row order, then streamed, so small pages (iga.app.memory.streamed_empty);
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
        (len(members), pat nnz) of block (a, b), all c^2 present.

        Each member's rows of component a are one run of c nnz entries: the blocks (a, 0), ..., (a, c - 1)
        stacked and gathered into row order (:func:`interleaved`; one component: as they are), written by one
        copy per component, through a strided view when the members' runs step evenly (the same tile patch in
        every cell of a regular paving), without index arrays."""
        members = np.asarray(members)
        c = self.c
        self.put_rows(members, pat.indptr)
        indices = np.asarray(pat.indices, self.indices.dtype)
        if c > 1:
            order = interleaved(pat, c)
            indices = np.concatenate([indices + b * self.n for b in range(c)])[order]
        cols = indices[None, :] + self.offsets[members].astype(self.indices.dtype)[:, None]
        for a in range(c):
            base = self.bases(members, a)
            values = np.concatenate([blocks[(a, b)] for b in range(c)], axis=1)[:, order] if c > 1 else blocks[(0, 0)]
            _write_runs(self.data, base, values)
            _write_runs(self.indices, base, cols)  # every component's rows read the same columns
        self.mark(members)

    def matrix(self) -> sp.csr_matrix:
        """The operator, once every patch is written (its arrays, not copies)."""
        if not self._written.all():
            missing = np.flatnonzero(~self._written)
            raise ProblemError(f"the operator is incomplete: patches {missing[:5].tolist()} were not "
                               "assembled")
        return sp.csr_matrix((self.data, self.indices, self.indptr), shape=(self.c * self.n, self.c * self.n))
