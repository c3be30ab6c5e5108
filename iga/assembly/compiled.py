"""Optional compiled kernels for large 3-D assemblies (numba, the ``fast`` extra).

The NumPy/SciPy path of :mod:`iga.assembly.tensor` contracts one quadrature axis
at a time over whole arrays: every stage writes and re-reads arrays of
hundreds of MB, then the banded result is gathered into CSR order and added
to its transpose.  Here the same sum factorisation runs slab by slab of
direction-1 elements (:class:`FormAccumulator`): per slab the geometry
is evaluated from the spline coefficients (:func:`grid_derivs`), the metric
coefficients computed (:func:`metric_fields`; both in one pass by
:func:`metric_slabs` for patches without placement or map and with constant
conductivity and source), and the stiffness contracted in a few MB of
scratch; rows are completed in a small banded ring buffer and written into
the CSR data once.  The source load is contracted slab by slab too
(``load3``).  No full-grid field, banded array, gather
index or transpose pass exists: a third to half of the NumPy path's peak
memory and 2-4x its speed (``benchmarks/heat_performance.py --numpy``).
:func:`compact_rows_cols` eliminates Dirichlet unknowns inside the matrix's
own arrays.  The sums are the same as the NumPy path's, in a different
order, so results agree to rounding (``tests/test_fast_paths.py``).

Used for 3-D spaces when numba imports and a group of patches has at least
:data:`MIN_POINTS` quadrature points (below that, the import and thread
start-up are not worth it, and small analyses such as the heat-sink demo
never load numba).  Without numba, nothing changes.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from geometry.cache import memo
import scipy.sparse as sp

from iga.errors import ProblemError
from geometry.compiled.lock import locked
from geometry.compiled._fast import grid_tables, readonly

from iga.assembly.tensor import CACHE_NNZ, CSRPattern, band_limits
from iga.assembly.terms import DIFFUSION, FormTerms, elastic_block
from iga.discretisation.space import Space1D, TensorSpace

#: quadrature points (over all patches of a group) from which the compiled kernels assemble the scalar form
#: (six coefficient terms per point); a form of more terms per point takes them from proportionally fewer
#: points (:func:`applies`)
MIN_POINTS = 200_000

# imported on first use, as geometry.compiled._fast: importing numba costs memory and time that small analyses should not pay
AVAILABLE = importlib.util.find_spec("numba") is not None

_VARIANTS = ((0, 0), (0, 1), (1, 0), (1, 1))


def applies(space: TensorSpace, n_patches: int, terms: int = 6) -> bool:
    """Whether the compiled kernels assemble ``n_patches`` patches on ``space``, for a form of ``terms``
    parametric coefficient terms per Gauss point (6: the scalar stiffness, :func:`form_csr`; 45: the
    six computed blocks of elasticity, :func:`elastic_into`).  The threshold is on work, points times
    terms: what :data:`MIN_POINTS` points of the scalar form take."""
    return AVAILABLE and space.dim == 3 and n_patches * space.nq_total * terms >= MIN_POINTS * 6


def _kernels():
    from iga.assembly import _assembly_kernels

    return _assembly_kernels


def _metric_kernels():
    from iga.assembly import _metric_kernels

    return _metric_kernels


def _tables(sp1: Space1D) -> dict:
    """Band and element tables of one direction in the kernel's layout (cached on the space)."""
    cache = sp1.tables.get("fast")
    if cache is None:
        p, g, n = sp1.degree, sp1.g, sp1.n
        W = np.ascontiguousarray(np.stack([sp1.W(a, b) for a, b in _VARIANTS]))  # (4, n, D, L)
        nz = (W != 0).any(axis=0)  # (n, D, L): window points where some variant is non-zero
        has = nz.any(axis=-1)
        lo = np.where(has, nz.argmax(axis=-1), 0)
        hi = np.where(has, sp1.L - nz[..., ::-1].argmax(axis=-1), 0)
        blo, bhi = band_limits(n, p)
        # first basis function on each element: knot span of the element's left end, minus p
        first = np.searchsorted(sp1.knots, sp1.breaks[:-1], side="right") - 1 - p
        loc = first[:, None] + np.arange(p + 1)[None, :]  # (E, p+1)
        cols = np.arange(sp1.E)[:, None] * g + np.arange(g)[None, :]  # (E, g)
        b = sp1.B[:, loc[:, :, None], cols[:, None, :]]  # (2, E, p+1, g)
        # elements in the support of each function: first[e] in [i - p, i] (first is non-decreasing)
        i = np.arange(n)
        cache = {
            "W": W, "r": np.ascontiguousarray(np.stack([lo, hi], axis=-1).astype(np.int64)),
            "s": (sp1.start * g).astype(np.int64), "lo": blo.astype(np.int64),
            "c": (bhi - blo + 1).astype(np.int64), "b": np.ascontiguousarray(b), "first": first.astype(np.int64),
            "elo": np.searchsorted(first, i - p, side="left").astype(np.int64),
            "ehi": np.searchsorted(first, i, side="right").astype(np.int64),
        }
        for key, v in cache.items():
            cache[key] = readonly(v, v.dtype)
        sp1.tables["fast"] = cache
    return cache


def _structure(shape: tuple, degrees: tuple) -> CSRPattern:
    n = int(np.prod(shape))
    lims = [band_limits(m, p) for m, p in zip(shape, degrees)]
    los = [lo.astype(np.int64) for lo, _ in lims]
    cs = [(hi - lo + 1).astype(np.int64) for lo, hi in lims]
    counts = np.multiply.outer(np.multiply.outer(cs[0], cs[1]), cs[2])
    nnz = int(counts.sum())
    indptr = np.empty(n + 1, np.int64)
    indices = np.empty(nnz, np.int32 if n < 2**31 else np.int64)
    locked(_kernels().csr_structure3)(*(readonly(a, np.int64) for a in (los[0], cs[0], los[1], cs[1], los[2], cs[2])),
                              *degrees, indptr, indices)
    return CSRPattern(indptr, indices, None, None, n)


_cached_structure = memo(8)(_structure)


def row_pointers(space: TensorSpace) -> np.ndarray:
    """The CSR row pointers (ndof + 1,) of ``space``'s banded operators alone (:func:`structure` without its
    columns: for kernels that write the columns themselves)."""
    cs = [(hi - lo + 1).astype(np.int64) for lo, hi in (band_limits(d.n, d.degree) for d in space.dirs)]
    counts = np.multiply.outer(np.multiply.outer(cs[0], cs[1]), cs[2]).reshape(-1)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def structure(space: TensorSpace) -> CSRPattern:
    """CSR row pointers and columns of ``space``'s banded operators (same order as :func:`iga.assembly.tensor.pattern`).

    Only ``indptr``, ``indices`` and ``n`` are set: the kernel needs no gather
    or transpose index.  Small structures are cached and read-only; large ones
    (more than :data:`iga.assembly.tensor._CACHE_NNZ` entries) are built per call and
    belong to the caller (a matrix built on them may be modified in place).
    """
    key = (space.shape, tuple(s.degree for s in space.dirs))
    if space.ndof * int(np.prod([2 * p + 1 for p in key[1]])) > CACHE_NNZ:
        return _structure(*key)
    pat = _cached_structure(*key)
    for a in (pat.indptr, pat.indices):
        a.setflags(write=False)
    return pat


def compact_rows_cols(K, keep: np.ndarray):
    """``K[keep][:, keep]`` for a CSR matrix, computed in K's own memory; K is destroyed.

    ``keep``: sorted indices of the rows/columns to keep.  Returns the
    reduced CSR matrix, whose arrays are leading views of K's.  Arrays K
    shares read-only (a cached pattern's ``indptr`` and ``indices``) are
    copied first, never written.
    """
    indptr, indices, data = (a if a.flags.writeable and a.flags.c_contiguous else np.array(a)
                             for a in (K.indptr, K.indices, K.data))
    n = K.shape[0]
    new = np.full(n, -1, indices.dtype)
    new[keep] = np.arange(len(keep), dtype=indices.dtype)
    rows, nnz = locked(_kernels().compact_rows_cols)(indptr, indices, data, readonly(new, new.dtype))
    return sp.csr_matrix((data[:nnz], indices[:nnz], indptr[: rows + 1]), shape=(rows, rows))


def _scratch(space: TensorSpace, n_patches: int, terms: int, scratch=None):
    """A slab kernel's scratch (ring, Z, Y): the ring of banded rows of the p1 + 1 direction-1 indices a slab
    touches (zero; each kernel pass leaves it zero again), its partial contractions Z (one row per term) and
    Y, allocated once: fresh memory per slab is page-faulted in again.  ``scratch`` from an earlier pass on
    the same space and patches is reused (its Z holds ``terms`` rows or more: the leading part is taken)."""
    (_, n2, n3), (p1, p2, p3) = space.shape, [d.degree for d in space.dirs]
    g1, nq2 = space.dirs[0].g, space.dirs[1].nq
    zshape = (g1, terms, nq2, n3, 2 * p3 + 1)
    if scratch is not None and scratch[1].size >= np.prod(zshape):
        ring, Z, Y = scratch
        return ring, Z.reshape(-1)[:int(np.prod(zshape))].reshape(zshape), Y
    ring = np.zeros((n_patches, p1 + 1, 2 * p1 + 1, n2, (2 * p2 + 1) * n3 * (2 * p3 + 1)))
    return ring, np.empty(zshape), np.empty((g1, 4, n2, 2 * p2 + 1, n3, 2 * p3 + 1))


def scalar_destinations(n_patches: int, nnz: int) -> np.ndarray:
    """The slab kernels' ``dest`` (P, 4) for data (P, nnz) flattened: patch pi's row i from pi nnz + indptr[i],
    no columns written (the pattern has them; :func:`iga.assembly._assembly_kernels._flush_row`)."""
    dest = np.zeros((n_patches, 4), np.int64)
    dest[:, 0] = np.arange(n_patches) * nnz
    dest[:, 1] = 1
    dest[:, 3] = -1
    return readonly(dest, np.int64)


class FormAccumulator:
    """CSR operator of the form ``form`` (:class:`iga.assembly.terms.FormTerms`) on P patches sharing ``space``,
    added slab by slab of direction-1 elements.

    ``add(planes, C)`` takes the coefficient fields (form.fields, P, n) on the Gauss planes ``planes`` (a
    slice of whole elements along the first quadrature axis, as :meth:`iga.heat.volume.VolumeAssembler._slabs`
    yields them), in order; after the last element, :meth:`result` returns the pattern and the data (P, nnz).
    ``add(planes, C, L)`` also contracts a source field L (P, n) into :attr:`load` (P,) + space.shape.
    Rows are finished in a banded ring buffer of the p1 + 1 direction-1 indices a slab touches and written to
    ``data`` once, when complete.  ``into`` (csr, members, component a, component b): write block (a, b) of
    the patches' rows straight into a global :class:`iga.assembly.vector_csr.VectorCSR` (values and
    columns).  ``scratch``: the (ring, Z, Y) of an accumulator on the same space and patches that has
    finished (it leaves its ring zero), reused.
    """

    def __init__(self, space: TensorSpace, n_patches: int, form: FormTerms = DIFFUSION, into=None, scratch=None):
        self.space, self.form = space, form
        self.tables = [_tables(s) for s in space.dirs]
        self.n_patches = n_patches
        # the kernel writes the columns itself when it writes into a global CSR: only the row pointers needed
        self.pattern = structure(space) if into is None else CSRPattern(row_pointers(space), None, None, None,
                                                                        space.ndof)
        # every entry is written exactly once, when its row is complete: no zero-filling needed
        if into is None:
            self.data = np.empty((n_patches, len(self.pattern.indices)))
            self.out, self.cols = self.data.reshape(-1), np.empty(0, np.int32)
            self.dest = scalar_destinations(n_patches, self.data.shape[1])
        else:  # straight into the global CSR: values and columns (only where asked), rows written with block 0
            into = tuple(into) + (0, 0)[len(into) - 2:]
            self.data, self.out, self.cols, self.into = None, into[0].data, into[0].indices, into
            self.dest = _block_destinations(*into)
            if into[2:] == (0, 0):
                into[0].put_rows(into[1], self.pattern.indptr)
        self.ring, self.Z, self.Y = _scratch(space, n_patches, form.count, scratch)
        self.next_element = 0
        #: load vectors (P,) + space.shape, once a slab with a source field was added (else None)
        self.load = None

    def add(self, planes: slice, C: np.ndarray, L: np.ndarray | None = None) -> None:
        """Add the slab ``planes`` with coefficient fields C (form.fields, P, n) and optionally a source field L
        (P, n)."""
        g = self.space.dirs[0].g
        if planes.start % g or (planes.stop - planes.start) % g:
            raise ProblemError(f"slab {planes} does not cover whole elements ({g} Gauss planes each)")
        if planes.start != self.next_element * g:
            raise ProblemError(f"slabs must come in order: expected Gauss plane {self.next_element * g}, "
                               f"got {planes.start}")
        t1, t2, t3 = self.tables
        shape = (self.form.fields, self.n_patches, planes.stop - planes.start) + self.space.qshape[1:]
        C = readonly(np.reshape(C, shape))
        if L is not None:  # shaped before anything is added, so that a bad slab changes nothing
            L = readonly(np.reshape(L, shape[1:]))
        self.next_element = planes.stop // g
        p3, g3 = t3["b"].shape[2] - 1, t3["b"].shape[3]
        f = self.form
        locked(_kernels().form3_for(p3, g3))(C, f.field, f.variants, f.groups, f.symmetric, planes.start // g, t1["b"],
                                             t1["first"], t2["W"], t2["r"], t2["s"], t3["b"], t3["first"],
                                             readonly(self.pattern.indptr, np.int64), t1["lo"], t1["c"],
                                             t2["lo"], t2["c"], t3["lo"], t3["c"], self.ring, self.Z, self.Y,
                                             self.out, self.cols, self.dest)
        if L is not None:
            if self.load is None:
                self.load = np.zeros((self.n_patches,) + self.space.shape)
            locked(_kernels().load3)(L, planes.start // g, t1["b"], t1["first"], t2["b"], t2["elo"], t2["ehi"],
                                     t2["first"], t3["b"], t3["first"], self.load)

    def result(self) -> tuple[CSRPattern, np.ndarray | None]:
        """``(pattern, data (P, nnz))`` once every element has been added; data None when written ``into`` a
        global CSR (whose patches are then marked written, for a one-component operator)."""
        E1 = self.space.dirs[0].E
        if self.next_element != E1:
            raise ProblemError(f"form incomplete: elements {self.next_element}..{E1 - 1} of direction 1 "
                               "were not added")
        if self.data is None and self.into[0].c == 1:
            self.into[0].mark(self.into[1])
        return self.pattern, self.data


def _block_destinations(csr, members, a: int = 0, b: int = 0) -> np.ndarray:
    """The slab kernels' ``dest`` (P, 4) for block (a, b) of the patches ``members`` in the component-major
    ``csr`` (:class:`iga.assembly.vector_csr.VectorCSR`; block (0, 0) of a one-component one): rows of component
    a, entries of block b; columns written for component 0's rows only (a vector operator's other rows copy
    them, :func:`iga.assembly._elastic_kernels.mirror_lower`)."""
    members = np.asarray(members)
    P, k = len(members), csr.c
    cols = b * csr.n + csr.offsets[members] if a == 0 else np.full(P, -1)
    return readonly(np.stack([csr.bases(members, a), np.full(P, k), np.full(P, b), cols], axis=1), np.int64)


def form_csr(space: TensorSpace, C: np.ndarray, form: FormTerms = DIFFUSION) -> tuple[CSRPattern, np.ndarray]:
    """CSR pattern and data (P, nnz) of the form ``form`` with coefficient fields ``C`` (form.fields, P) +
    qshape (quadrature weights and |J| included), in one call over the whole grid.  For diffusion, the six
    symmetric fields in the pair order (0,0), (1,1), (2,2), (0,1), (0,2), (1,2), as
    :class:`iga.heat.volume.VolumeAssembler` builds them."""
    acc = FormAccumulator(space, C.shape[1], form)
    acc.add(slice(0, space.dirs[0].nq), C)
    return acc.result()


def _elastic_kernels():
    from iga.assembly import _elastic_kernels

    return _elastic_kernels


def elastic_into(space: TensorSpace, members, G: np.ndarray, LM: np.ndarray, out) -> None:
    """Write the elastic stiffness of the patches ``members`` (sharing ``space``) into the component-major
    operator ``out`` (:class:`iga.assembly.vector_csr.VectorCSR`), every entry once, where it belongs.

    ``G`` (9, P) + qshape: the metric rows, ``G[3 r + k] = c_r[k]`` (:func:`iga.elasticity.forms.metric_rows`);
    ``LM`` (2, P) + qshape: lambda w / |det J| and mu w / |det J| (Pa).  Block (a, b) couples component a of
    the test functions (rows) with component b of the trial functions.  The six upper blocks are forms of the
    one form kernel (:func:`iga.assembly.terms.elastic_block`: a diagonal block the symmetric six-field form,
    an off-diagonal one nine fields), their fields formed slab by slab (:func:`_elastic_block_fields`), data
    written as rows complete and columns for component 0's rows; the lower blocks are copied from the upper
    ones' transposes (the pattern's mirrored band offsets), and the other components' columns from component
    0's, by one parallel pass.  The NumPy reference is :func:`iga.elasticity.forms.block_terms`.
    """
    pat = structure(space)
    P = G.shape[1]
    p1, p2, p3 = [d.degree for d in space.dirs]
    G, LM = readonly(G), readonly(LM)
    members = np.asarray(members)
    indptr = readonly(pat.indptr, np.int64)
    g = space.dirs[0].g
    rest = space.nq_total // space.dirs[0].nq
    step = g * max(1, _ELASTIC_SLAB_POINTS // (rest * g))  # Gauss planes per slab, whole elements
    scratch = _scratch(space, P, elastic_block(0, 1).count)  # the six passes share it (each leaves it zero)
    fields = np.empty(9 * P * min(step, space.dirs[0].nq) * rest)  # the fields of a slab, allocated once
    for a in range(3):
        for b in range(a, 3):
            acc = FormAccumulator(space, P, elastic_block(a, b), into=(out, members, a, b), scratch=scratch)
            for q0 in range(0, space.dirs[0].nq, step):
                planes = slice(q0, min(q0 + step, space.dirs[0].nq))
                acc.add(planes, _elastic_block_fields(G, LM, a, b, planes, fields))
            acc.result()
    kernels = _elastic_kernels()
    t1, t2, t3 = (_tables(s) for s in space.dirs)
    before = readonly(out.before[members], np.int64)
    transpose = np.empty(len(pat.indices), np.int64)
    locked(kernels.transpose_positions)(indptr, t1["lo"], t1["c"], t2["lo"], t2["c"], t3["lo"], t3["c"],
                                        p1, p2, p3, transpose)
    locked(kernels.mirror_lower)(indptr, readonly(pat.indices, pat.indices.dtype), readonly(transpose, np.int64),
                                 before, out.nnz, out.data, out.indices)
    out.mark(members)


#: Gauss points per slab of the elastic blocks' fields (nine fields of a slab, formed then contracted)
_ELASTIC_SLAB_POINTS = 1 << 16


def _elastic_block_fields(G: np.ndarray, LM: np.ndarray, a: int, b: int, planes: slice,
                          scratch: np.ndarray) -> np.ndarray:
    """The fields of elastic block (a, b) on the Gauss planes ``planes``, compiled: on a diagonal block the six
    symmetric C_rs = (lf + mf) c_r[a] c_s[a] + mf c_r . c_s (pair order of
    :data:`iga.assembly.terms.SYMMETRIC_PAIRS`), off it the nine F_rs = lf c_r[a] c_s[b] + mf c_r[b] c_s[a]
    (index 3 r + s); G (9, P) + qshape and LM (2, P) + qshape on the whole grid (read-only, contiguous);
    written into the leading part of ``scratch`` (fresh memory per slab is page-faulted in again).
    Formulas in :func:`iga.assembly._metric_kernels.elastic_block_fields`."""
    P, rest = G.shape[1], int(np.prod(G.shape[3:]))
    shape = (6 if a == b else 9, P, planes.stop - planes.start) + G.shape[3:]
    F = scratch[:int(np.prod(shape))].reshape(shape)
    locked(_metric_kernels().elastic_block_fields)(G.reshape(9, P, -1), LM.reshape(2, P, -1), a, b,
                                                   planes.start * rest, F.reshape(shape[0], P, -1))
    return F


def metric_fields(D, kval, fval, w):
    """Compiled stiffness coefficients C (6, M), source load L (M,) and det J (M,).

    D: [dx/du, dx/dv, dx/dw], each (P, n, 3) with M = P n; kval the
    conductivity, (M,) isotropic or (M, 6) tensor components (xx, yy, zz, xy,
    xz, yz); fval, w (M,) source and quadrature weights.  Formulas in
    :func:`iga.assembly._metric_kernels.metric_fields`.
    """
    Du, Dv, Dw = (np.reshape(d, (-1, 3)) for d in D)
    M = len(Du)
    C, L, det = np.empty((6, M)), np.empty(M), np.empty(M)
    kval = np.asarray(kval, float)
    if kval.ndim == 2:
        kiso, ktensor = readonly(np.zeros(M)), readonly(np.broadcast_to(kval, (M, 6)))
    else:
        kiso, ktensor = readonly(np.broadcast_to(kval, (M,))), readonly(np.zeros((0, 6)))
    fval = readonly(np.broadcast_to(np.asarray(fval, float), (M,)))
    locked(_metric_kernels().metric_fields)(readonly(Du), readonly(Dv), readonly(Dw), kiso, ktensor, fval,
                                    readonly(np.broadcast_to(np.asarray(w, float), (M,))), C, L, det)
    return C, L, det


def elastic_metric(D, lam, mu, w, start: int, G: np.ndarray, LM: np.ndarray) -> np.ndarray:
    """Write the elastic kernels' fields of one slab into G (9, P, N) and LM (2, P, N) from grid position
    ``start`` on, compiled: D [dx/du, dx/dv, dx/dw] each (P, n, 3); lam, mu (P n,) Pa; w (P n,) quadrature
    weights.  Returns det J (P n,).  Formulas in :func:`iga.assembly._metric_kernels.elastic_metric`."""
    Du, Dv, Dw = (readonly(np.reshape(d, (-1, 3))) for d in D)
    M = len(Du)
    det = np.empty(M)
    locked(_metric_kernels().elastic_metric)(Du, Dv, Dw, *(readonly(np.broadcast_to(np.asarray(v, float), (M,)))
                                                           for v in (lam, mu, w)), int(start), G, LM, det)
    return det


def metric_slabs(spline, space: TensorSpace, points_per_slab: int, kval, fval: float):
    """:func:`grid_derivs` and :func:`metric_fields` fused, for x = spline(xi) with constant k and f.

    Yields ``(planes, C (6, n), L (n,), det (n,))`` per slab of whole
    direction-0 elements (about ``points_per_slab`` points; at least one
    element) of ``space``'s Gauss grid, as the two-pass route would.  For
    patches without placement or deformation map, with a constant
    conductivity (a number, or six tensor components) and a number for the
    source (:class:`iga.heat.volume.VolumeAssembler`).
    """
    axes = space.qaxes
    tables = grid_tables(spline, axes)
    hom = spline.homogeneous
    if hom.shape[-1] != (4 if spline.is_rational else 3):  # channels are not needed: coordinates (and weight)
        hom = hom[..., [0, 1, 2, -1] if spline.is_rational else [0, 1, 2]]
    hom = readonly(hom)
    kval = np.asarray(kval, float)
    iso = kval.ndim == 0
    K = readonly(np.array([kval, kval, kval, 0.0, 0.0, 0.0]) if iso else kval.reshape(6))
    qw = [readonly(d.qw) for d in space.dirs]
    g, nq0 = space.dirs[0].g, space.dirs[0].nq
    rest = space.dirs[1].nq * space.dirs[2].nq
    rows = g * max(1, points_per_slab // (rest * g))
    (f0, B0), (f1, B1), (f2, B2) = tables
    for a in range(0, nq0, rows):
        b = min(a + rows, nq0)
        n = (b - a) * rest
        C, L, det = np.empty((6, n)), np.empty(n), np.empty(n)
        locked(_metric_kernels().geometry_metric3)(hom, spline.is_rational, a, b, f0, B0, f1, B1, f2, B2, iso, K,
                                             float(fval), *qw, C, L, det)
        yield slice(a, b), C, L, det
