"""Volume assembly of linear elasticity on the scalar spaces of a :class:`iga.discretisation.Discretisation`.

The displacement is numbered component-major: unknown ``a * ndof + i`` is
component a (x, y, z) of scalar DOF i, so each of the nine blocks K^{ab} lives
on the scalar sparsity pattern and the interface constraints of the scalar
problem apply to every component (:func:`vector_constraints`).  Patches
sharing a space and a tile spline are batched.  Large batches go through one
compiled kernel per block (:func:`iga.fast_assembly.elastic_blocks`, the
block's nine parametric coefficients formed on the fly); small ones through
NumPy: each block's symmetric part through the scalar stiffness form, an
off-diagonal block's antisymmetric part through three sum-factorised banded
terms (:func:`iga.assembly.banded_form`), the lower blocks as transposes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry import progress
from geometry.chain import patches_geometry_derivs_slabs

from . import fast_assembly
from .assembly import (banded_form, banded_to_csr_data, block_diagonal_csr, derivative_load_form, load_form,
                       pattern, stiffness_data)
from .coefficients import TENSOR_PAIRS
from .constraints import Constraints
from .elastic_forms import divergence_terms, lame, metric_rows, skew_terms, symmetric_fields
from .faces import chunks
from .geometry_eval import checked_det

__all__ = ["ElasticVolume", "vector_constraints", "component_major_csr"]

_SLAB_POINTS = 1 << 16


class ElasticVolume:
    """Stiffness (3 ndof x 3 ndof, CSR) and volume loads of all patches; ``disc`` the shared discretisation."""

    def __init__(self, disc):
        self.disc = disc

    def assemble(self, youngs, poisson, body=None, thermal=None):
        """(K, f, work): ``youngs``, ``poisson`` :class:`iga.coefficients.ScalarField` (Pa, -); ``body`` a
        vector field of x (N/m^3) or None; ``thermal`` a callable ``(patch index, x, params, chans) -> (N,)``
        of alpha (T - T_ref) or None.  ``work``: {"body": int f dV (N, (3,))}."""
        d = self.disc
        n = d.ndof
        blocks = {(a, b): [] for a in range(3) for b in range(3)}  # [(offset, pattern, data)] per block
        f = np.zeros(3 * n)
        total = np.zeros(3)
        work = [m for g in d.volume.groups.values() for m in chunks(g, 3 * d.spaces[g[0]].nq_total)]
        for members in progress.bar(work, desc="elastic assembly", unit="batch"):
            pat, data, loads, force = self._group(members, youngs, poisson, body, thermal)
            total += force
            for (a, b), dat in data.items():
                blocks[(a, b)] += [(int(d.offsets[i]), pat, dat[j]) for j, i in enumerate(members)]
            for a in range(3):
                if loads[a] is not None:
                    for j, i in enumerate(members):
                        f[a * n + d.offsets[i] : a * n + d.offsets[i + 1]] += loads[a][j].ravel()
        return component_major_csr({ab: block_diagonal_csr(bl, n) for ab, bl in blocks.items()}, n,
                                   d.volume.compiled), f, {"body": total}

    def _fields(self, members, youngs, poisson, body, thermal):
        """Metric rows c (3 rows x (3, M)), w/|det| (M,), lambda, mu (M,), body force (M, 3) or None and
        thermal divergence weight (M,) or None, on the Gauss grid of ``members`` (C order per patch)."""
        d = self.disc
        space = d.spaces[members[0]]
        patches = [d.model.patches[i] for i in members]
        where = f"patch {members[0]}" if len(members) == 1 else f"patches {members[0]}..{members[-1]}"
        w_rest = np.multiply.outer(space.dirs[1].qw, space.dirs[2].qw).ravel()
        parts = []
        for planes, x, D, chans in patches_geometry_derivs_slabs(patches, space.qaxes, _SLAB_POINTS,
                                                                  rows_multiple=space.dirs[0].g):
            P, m = x.shape[:2]
            xs = x.reshape(-1, 3)
            flat = {ch: np.reshape(v, -1) for ch, v in chans.items()}
            c, det = metric_rows(D)
            checked_det(det, where)
            w = np.broadcast_to(np.multiply.outer(space.dirs[0].qw[planes], w_rest).ravel(), (P, m)).reshape(-1)
            lam, mu = lame(youngs.values(xs, flat, where), poisson.values(xs, flat, where), where)
            adet = np.abs(det)
            fb = None if body is None else body.values(xs, where) * (adet * w)[:, None]
            th = None
            if thermal is not None:
                params = _slab_params(space, planes)
                strain = np.concatenate([thermal(i, x[j], params, {k: v[j] for k, v in chans.items()})
                                         for j, i in enumerate(members)])
                th = (3 * lam + 2 * mu) * strain * np.sign(det) * w
            parts.append((planes, c, w / adet, lam, mu, fb, th))
        return parts

    def _group(self, members, youngs, poisson, body, thermal):
        """Pattern, {(a, b): data (P, nnz)} of the nine blocks, loads [(P,) + shape or None] * 3, int f dV (3,)."""
        space = self.disc.spaces[members[0]]
        P = len(members)
        shape = (P,) + space.qshape
        parts = self._fields(members, youngs, poisson, body, thermal)

        def grid(values):  # slabs (P * m,) each -> (P,) + qshape
            return np.concatenate([v.reshape(P, -1) for v in values], axis=1).reshape(shape)

        c = [[grid([p[1][r][a] for p in parts]) for a in range(3)] for r in range(3)]
        fac, lam, mu = grid([p[2] for p in parts]), grid([p[3] for p in parts]), grid([p[4] for p in parts])
        if fast_assembly.applies(space, P):  # all six blocks in the compiled kernel, fields formed on the fly
            pat, data = fast_assembly.elastic_blocks(space, np.stack([c[r][a] for r in range(3) for a in range(3)]),
                                                     np.stack([fac * lam, fac * mu]))
        else:
            pat, data = pattern(space), {}
            for a in range(3):
                for b in range(a, 3):
                    # the symmetric part through the scalar stiffness form, the antisymmetric part of an
                    # off-diagonal block as B - B^T from three banded terms
                    S = symmetric_fields(c, fac, lam, mu, a, b)
                    data[(a, b)] = stiffness_data(space, {rs: S[j] for j, rs in enumerate(TENSOR_PAIRS)}, pat)
                    if a != b:
                        B = banded_to_csr_data(space, banded_form(space, skew_terms(c, fac, lam, mu, a, b, shape)),
                                               pat)
                        data[(a, b)] += B - B[:, pat.transpose]
                        data[(b, a)] = data[(a, b)][:, pat.transpose]  # the lower block: the transpose
        loads, force = [None, None, None], np.zeros(3)
        if parts[0][5] is not None:
            for a in range(3):
                F = grid([p[5][:, a] for p in parts])
                loads[a] = load_form(space, F)
                force[a] = float(F.sum())
        if parts[0][6] is not None:
            beta = grid([p[6] for p in parts])
            for a in range(3):
                L = derivative_load_form(space, divergence_terms(c, beta, a, shape))
                loads[a] = L if loads[a] is None else loads[a] + L
        return pat, data, loads, force


def component_major_csr(M: dict, n: int, compiled: bool = False) -> sp.csr_matrix:
    """The (3 n, 3 n) CSR of nine (n, n) blocks ``M[(a, b)]`` that share one pattern with sorted indices.

    ``compiled`` (the assembly loaded the compiled kernels anyway): in one compiled pass
    (:func:`iga.fast_assembly.component_major_csr`, 10x faster); otherwise, so that small analyses never
    import numba:

    Row a n + i holds row i of blocks (a, 0), (a, 1), (a, 2) one after the
    other, their columns shifted by 0, n, 2 n: index arithmetic on the shared
    pattern, without the COO round trip of ``scipy.sparse.bmat`` (5x faster,
    a third of the memory).
    """
    P = M[(0, 0)]
    if compiled and fast_assembly.AVAILABLE:
        return fast_assembly.component_major_csr(M, n)
    indptr, indices = P.indptr.astype(np.int64), P.indices.astype(np.int64)
    nnz = len(indices)
    length = np.diff(indptr)
    row = np.repeat(np.arange(n), length)
    k = np.arange(nnz)
    start = 3 * indptr[:-1][row]  # where scalar row i begins in its vector row, and entry k's offset in it
    offset = k - indptr[:-1][row]
    out_indices = np.empty(9 * nnz, np.int64 if 3 * n > np.iinfo(np.int32).max else np.int32)
    out_data = np.empty(9 * nnz)
    for a in range(3):
        for b in range(3):
            pos = a * 3 * nnz + start + b * length[row] + offset
            out_indices[pos] = indices + b * n
            out_data[pos] = M[(a, b)].data
    out_indptr = np.concatenate([a * 3 * nnz + 3 * indptr[:-1] for a in range(3)] + [[9 * nnz]])
    return sp.csr_matrix((out_data, out_indices, out_indptr), shape=(3 * n, 3 * n))


def _slab_params(space, planes) -> np.ndarray:
    """Parameters (m, 3) of the Gauss points of a slab of first-axis planes (C order)."""
    ax = [space.qaxes[0][planes], space.qaxes[1], space.qaxes[2]]
    return np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)


def vector_constraints(scalar: Constraints | None, ndof: int) -> Constraints | None:
    """The scalar prolongation applied to each displacement component (component-major numbering)."""
    if scalar is None:
        return None
    nred = scalar.P.shape[1]
    m = scalar.dof_master
    master = np.concatenate([np.where(m >= 0, m + a * nred, -1) for a in range(3)])
    return Constraints(sp.block_diag([scalar.P] * 3, format="csr"), master, dict(scalar.stats))
