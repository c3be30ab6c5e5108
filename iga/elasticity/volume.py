"""Volume assembly of linear elasticity on the scalar spaces of a :class:`iga.discretisation.setting.Discretisation`.

The displacement is numbered component-major: unknown ``a * ndof + i`` is
component a (x, y, z) of scalar DOF i, so each of the nine blocks K^{ab} lives
on the scalar sparsity pattern and the interface constraints of the scalar
problem apply to every component (:func:`vector_constraints`).  Patches
sharing a space and a tile spline are batched, and every batch writes its
rows straight into the operator's final arrays (:class:`iga.assembly.vector_csr.VectorCSR`).
Large batches go through one compiled kernel per upper block
(:func:`iga.assembly.compiled.elastic_into`, the block's parametric coefficients
formed on the fly, the lower blocks copied as transposes); small ones, and patches in the NURBS basis
(:mod:`iga.discretisation.rational`, whose rewritten forms add first- and zero-order terms), as each upper
block's parametric terms in one form (:func:`iga.assembly.forms.terms_data`: the same form kernel for large
groups, NumPy's sum-factorised banded form for small ones), the lower blocks as transposes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry import progress
from geometry.patches.chain import patches_geometry_derivs_slabs

from iga.assembly import compiled as fast_assembly
from iga.assembly.forms import terms_data
from iga.assembly.tensor import derivative_load_form, load_form, pattern
from iga.discretisation.constraints import Constraints
from iga.elasticity.forms import block_terms, divergence_terms, metric_rows
from iga.discretisation.faces import chunks
from iga.discretisation.jacobians import checked_det
from iga.discretisation.rational import nurbs_scale, rational_form, rational_load_terms, weight_fields
from iga.assembly.vector_csr import VectorCSR

__all__ = ["ElasticVolume", "vector_constraints"]

_SLAB_POINTS = 1 << 16
#: parametric coefficient terms per Gauss point of the six computed blocks (3 x 6 symmetric + 3 x 9): the
#: work measure of :func:`iga.assembly.compiled.applies`
ELASTIC_TERMS = 45


class ElasticVolume:
    """Stiffness (3 ndof x 3 ndof, CSR) and volume loads of all patches; ``disc`` the shared discretisation."""

    def __init__(self, disc):
        self.disc = disc

    def assemble(self, material, body=None, thermal=None, patches=None):
        """(K, f, work): ``material`` an :mod:`iga.elasticity.material` material (isotropic or cubic); ``body`` a
        vector field of x (N/m^3) or None; ``thermal`` a callable ``(patch index, x, params, chans) -> (N,)``
        of alpha (T - T_ref) or None; ``patches``: a set of patch indices (one MPI rank's share) whose volumes
        alone are integrated, or None for all.  ``work``: {"body": int f dV (N, (3,)) over those patches}."""
        d = self.disc
        n = d.ndof
        chosen, groups = d.volume.share(patches)
        K = VectorCSR(d.offsets, d.volume.nnz * chosen)
        K.skip(np.flatnonzero(~chosen))  # (another rank's patches: empty rows)
        f = np.zeros(3 * n)
        total = np.zeros(3)
        work = [m for g in groups for m in chunks(g, 3 * d.spaces[g[0]].nq_total)]
        for members in progress.bar(work, desc="elastic assembly", unit="batch"):
            loads, force = self._group(members, material, body, thermal, K)
            total += force
            for a in range(3):
                if loads[a] is not None:
                    for j, i in enumerate(members):
                        f[a * n + d.offsets[i] : a * n + d.offsets[i + 1]] += loads[a][j].ravel()
        return K.matrix(), f, {"body": total}

    def _fields(self, members, material, body, thermal, compiled=False):
        """The fields of the assembly on the Gauss grid of ``members``, each (..., P) + qshape: G (9, ...) the
        metric rows (``G[3 r + k] = c_r[k]``, :func:`iga.elasticity.forms.metric_rows`), LM (2, ...) lambda w /
        |det J| and mu w / |det J| (Pa; a cubic material's kappa w / |det J| a third row), the weighted body
        force (3, ...) (N) or None and the thermal
        divergence weight (...) or None.  ``compiled``: geometry and metric in the numba kernels; the slabs
        write straight into the fields."""
        d = self.disc
        space = d.spaces[members[0]]
        patches = [d.model.patches[i] for i in members]
        P, N = len(members), space.nq_total
        where = f"patch {members[0]}" if P == 1 else f"patches {members[0]}..{members[-1]}"
        w_rest = np.multiply.outer(space.dirs[1].qw, space.dirs[2].qw).ravel()
        rest = len(w_rest)
        G, LM = np.empty((9, P, N)), np.empty((2 if material.kind == "isotropic" else 3, P, N))
        fb = None if body is None else np.empty((3, P, N))
        th = None if thermal is None else np.empty((P, N))
        lo, hi = np.inf, -np.inf  # det range over all slabs: a sign change between slabs is a fold too
        for planes, x, D, chans in patches_geometry_derivs_slabs(patches, space.qaxes, _SLAB_POINTS,
                                                                  rows_multiple=space.dirs[0].g, compiled=compiled):
            m, at = x.shape[1], slice(planes.start * rest, planes.stop * rest)
            xs = x.reshape(-1, 3)
            flat = {ch: np.reshape(v, -1) for ch, v in chans.items()}
            w = np.broadcast_to(np.multiply.outer(space.dirs[0].qw[planes], w_rest).ravel(), (P, m)).reshape(-1)
            mod = material.moduli(xs, flat, where)
            lam, mu = mod.lam, mod.mu
            if compiled:
                det = fast_assembly.elastic_metric(D, lam, mu, w, at.start, G, LM)
            else:
                c, det = metric_rows(D)
                G[:, :, at] = np.reshape(c, (9, P, m))
                rows = [lam, mu] if mod.kappa is None else [lam, mu, mod.kappa]
                LM[:, :, at] = (np.stack(rows) * (w / np.abs(det))).reshape(len(rows), P, m)
            a, b = checked_det(det, where)
            lo, hi = min(lo, a), max(hi, b)
            if fb is not None:
                fb[:, :, at] = (body.values(xs, where) * (np.abs(det) * w)[:, None]).T.reshape(3, P, m)
            if th is not None:
                params = _slab_params(space, planes)
                strain = np.concatenate([thermal(i, x[j], params, {k: v[j] for k, v in chans.items()})
                                         for j, i in enumerate(members)])
                th[:, at] = (mod.dilatation * strain * np.sign(det) * w).reshape(P, m)
        checked_det(np.array([lo, hi]), where)
        shape = (P,) + space.qshape
        return (G.reshape((9,) + shape), LM.reshape((len(LM),) + shape), None if fb is None else fb.reshape((3,) + shape),
                None if th is None else th.reshape(shape))

    def _group(self, members, material, body, thermal, K: VectorCSR):
        """Write the stiffness of ``members`` into K; returns loads [(P,) + shape or None] * 3 and int f dV (3,)."""
        space = self.disc.spaces[members[0]]
        shape = (len(members),) + space.qshape
        w = self.disc.weights[members[0]]  # the NURBS basis (iga.discretisation.rational): forms scaled by w
        # (the compiled kernel forms the isotropic coefficients; a cubic material's go through the terms)
        compiled = w is None and material.kind == "isotropic" and fast_assembly.applies(space, len(members),
                                                                                        terms=ELASTIC_TERMS)
        G, LM, fb, th = self._fields(members, material, body, thermal, compiled)
        c = [[G[3 * r + a] for a in range(3)] for r in range(3)]
        nurbs = None
        if w is not None:
            nurbs = weight_fields(self.disc.model.patches[members[0]].spline, space, len(members))
        if compiled:  # the compiled kernel, coefficients formed on the fly
            fast_assembly.elastic_into(space, members, G, LM, K)
        else:
            pat = pattern(space)
            K.put(members, pat, _term_blocks(space, pat, c, LM, shape, nurbs, w))
        loads, force = [None, None, None], np.zeros(3)
        if fb is not None:
            for a in range(3):
                loads[a] = load_form(space, fb[a] if nurbs is None else fb[a] / nurbs[0])
                force[a] = float(fb[a].sum())
        if th is not None:
            for a in range(3):
                terms = divergence_terms(c, th, a, shape)
                L = derivative_load_form(space, terms if nurbs is None else rational_load_terms(terms, *nurbs))
                loads[a] = L if loads[a] is None else loads[a] + L
        if w is not None:
            loads = [None if L is None else L * w for L in loads]
        return loads, force


def _term_blocks(space, pat, c, LM, shape, nurbs=None, w=None) -> dict:
    """The nine blocks' CSR data {(a, b): (P, nnz)} of patches on ``space`` (pattern ``pat``) from their terms
    (:func:`iga.assembly.forms.terms_data`: the form kernel for large groups, NumPy otherwise):
    each upper block from its parametric terms in one form (:func:`iga.elasticity.forms.block_terms`; the
    weights are in LM, so fac 1), a diagonal block as H + H^T of its six symmetric half terms, an off-diagonal
    one from all nine (one form, measured 1.8x faster than a symmetric and an antisymmetric part), the lower
    blocks as transposes.  ``nurbs`` (W, dW) and ``w``: the NURBS basis (:mod:`iga.discretisation.rational`)."""
    data = {}
    scale = None if w is None else nurbs_scale(pat, w.reshape(-1))
    for a in range(3):
        for b in range(a, 3):
            terms = block_terms(c, 1.0, LM[0], LM[1], a, b, shape, LM[2] if len(LM) > 2 else None)
            if nurbs is not None:
                terms = rational_form(terms, *nurbs)
            H = terms_data(space, terms, pat)  # compiled for large groups
            if scale is not None:
                H *= scale
            if a == b:
                data[(a, a)] = H + H[:, pat.transpose]
            else:
                data[(a, b)], data[(b, a)] = H, H[:, pat.transpose]  # the lower block: the transpose
    return data


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
