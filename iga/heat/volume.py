"""Volume assembly of the diffusion form and the source load: one dispatcher, two paths.

Patches are grouped by (analysis space, tile spline): a group shares every
quadrature table, and its geometry comes from one tile evaluation (plus one
deformation-map evaluation per batch).  Each group is assembled

* by the compiled kernels of :mod:`iga.assembly.compiled` (numba) when it has at
  least :data:`iga.assembly.compiled.MIN_POINTS` Gauss points: geometry, metric
  and stiffness slab by slab, straight into the final CSR (patches in the NURBS basis: the ten fields of
  :data:`iga.assembly.terms.RATIONAL_DIFFUSION` per slab, the entries scaled by w_i w_j once complete);
* otherwise by the NumPy sum factorisation of :mod:`iga.assembly.tensor`.

Both evaluate the same coefficient fields (:func:`iga.heat.forms.diffusion` or its
compiled twin) and agree to rounding.  The Jacobian determinant is checked on
every slab and across slabs (a sign change anywhere is a fold).  Every entry
is written once into the final block-diagonal CSR (a one-component
:class:`iga.assembly.vector_csr.VectorCSR`): the compiled kernels write values and
columns in place, the NumPy path copies each batch in.
"""

from __future__ import annotations

import numpy as np

from iga.assembly import compiled as fast_assembly
from iga.assembly.forms import form_data
from iga.assembly.tensor import banded_form, banded_to_csr_data, load_form, pattern, stiffness_data
from iga.assembly.terms import DIFFUSION, MASS, RATIONAL_DIFFUSION
from iga.heat.coefficients import TENSOR_PAIRS
from iga.discretisation.faces import chunks
from iga.heat.forms import diffusion
from iga.discretisation.rational import (nurbs_scale, own_rational, rational_diffusion_fields, rational_form,
                                         rational_load, stiffness_half_terms, weight_coefficients, weight_fields,
                                         weight_grid)
from geometry import progress
from geometry.patches.chain import gradient_and_det, patches_geometry_derivs_slabs

from iga.discretisation.jacobians import checked_det
from iga.assembly.vector_csr import VectorCSR, pattern_nnz
from geometry.grouping import ObjectIndex

__all__ = ["VolumeAssembler"]

# Gauss points per slab (at least one element): the NumPy path keeps cache-sized temporaries; the compiled
# kernels take 2^16 (the chain rule through placement and map holds about 600 bytes a point while a slab is
# formed: 2^18 points made a 150 MiB transient per batch, a fixed cost on every MPI rank, and the refined
# demo sink assembled in 2.4-2.5 s against 1.6-1.7 s at 2^16; lattices the same either way); the fused
# geometry-metric pass takes small ones, whose fields (64 bytes a point) are still in cache when the
# stiffness kernel reads them: 1-2 element layers, 20-35% faster than 2^20 points from 24^3 to 98^3
# elements (docs/performance.md)
_NUMPY_SLAB_POINTS = 1 << 14
_COMPILED_SLAB_POINTS = 1 << 16
_FUSED_SLAB_POINTS = 1 << 15


class VolumeAssembler:
    """Stiffness (CSR) and source load of all patches of a model on their spaces."""

    def __init__(self, model, spaces, offsets):
        same = ObjectIndex()  # patches share splines and maps: group by object
        self.model, self.spaces, self.offsets = model, spaces, offsets
        self.ndof = int(offsets[-1])
        self.groups: dict = {}
        for i, s in enumerate(spaces):
            self.groups.setdefault((s.key(), same(model.patches[i].spline)), []).append(i)
        self.nnz = np.zeros(len(spaces), np.int64)  # each patch's pattern size, one count per group
        #: per patch, the NURBS weight function's coefficients in its analysis space where the patch is analysed
        #: in the NURBS basis (:mod:`iga.discretisation.rational`), else None; one array per group
        self.weights = [None] * len(spaces)
        for g in self.groups.values():
            self.nnz[g] = pattern_nnz(spaces[g[0]])
            if own_rational(model.patches[g[0]]):
                w = weight_coefficients(model.patches[g[0]].spline, spaces[g[0]])
                if w is not None:
                    w.setflags(write=False)
                for i in g:
                    self.weights[i] = w

    @property
    def compiled(self) -> bool:
        """Whether some group is large enough for the compiled kernels (then large faces use them too)."""
        return any(self._compiled(g) for g in self.groups.values())

    def share(self, patches=None) -> tuple[np.ndarray, list]:
        """(a mask over the patches, the groups cut to them, empty ones left out) for ``patches``: a set of patch
        indices (one MPI rank's share; the others' rows stay empty) or None for all."""
        n = len(self.spaces)
        chosen = np.ones(n, bool) if patches is None else np.isin(np.arange(n), np.fromiter(patches, np.int64))
        return chosen, [g for g in ([i for i in g if chosen[i]] for g in self.groups.values()) if g]

    def _compiled(self, members) -> bool:
        """Whether patches ``members`` (one group) assemble in the compiled kernels: large enough for the form
        (:data:`DIFFUSION`, or :data:`RATIONAL_DIFFUSION` in the NURBS basis)."""
        form = DIFFUSION if self.weights[members[0]] is None else RATIONAL_DIFFUSION
        return fast_assembly.applies(self.spaces[members[0]], len(members), terms=form.fields)

    def assemble(self, conductivity, source, patches=None):
        """(K, f, source_total): the stiffness of ``conductivity`` (a :class:`iga.heat.coefficients.Conductivity`)
        and the load of ``source`` (a :class:`iga.heat.coefficients.ScalarField`); ``source_total`` is int f dV (W).

        ``patches``: assemble only these patch indices (a set; the other patches' rows stay empty), default all.
        """
        f = np.zeros(self.ndof)
        source_total = 0.0
        chosen, groups = self.share(patches)
        K = VectorCSR(self.offsets, self.nnz * chosen, components=1)  # each entry written once, where it belongs
        K.skip(np.flatnonzero(~chosen))
        work = [members for group in groups
                for members in chunks(group, _weight(self.spaces[group[0]], len(group), self._compiled(group)))]
        for members in progress.bar(work, desc="assembly", unit="batch"):
            pat, data, loads, total = self._group(members, self.spaces[members[0]], conductivity, source, K)
            source_total += total
            if data is not None:
                K.put(members, pat, {(0, 0): data})
            if loads is not None:
                f[_rows(self.offsets, members)] += loads.reshape(-1)
        return K.matrix(), f, source_total

    def _group(self, members, space, conductivity, source, into):
        """Pattern, data (P, nnz) or None (the compiled kernel wrote it ``into`` the global CSR), loads (P,) +
        shape or None, and int f dV of patches sharing a space and spline."""
        P, N = len(members), space.nq_total
        total = 0.0
        if self._compiled(members):
            if self.weights[members[0]] is not None:
                return self._compiled_nurbs(members, space, conductivity, source)
            # each slab goes straight into the global CSR and loads
            acc = fast_assembly.FormAccumulator(space, P, into=(into, members))
            for planes, Cs, Ls in self._slabs(members, space, conductivity, source, compiled=True):
                total += float(Ls.sum())
                acc.add(planes, Cs, Ls if np.any(Ls) else None)
            pat, data = acc.result()
            return pat, data, acc.load, total
        shape = (P,) + space.qshape
        rest = N // space.dirs[0].nq
        C, L = np.empty((6, P, N)), np.empty((P, N))
        for planes, Cs, Ls in self._slabs(members, space, conductivity, source, compiled=False):
            C[:, :, planes.start * rest : planes.stop * rest] = Cs
            L[:, planes.start * rest : planes.stop * rest] = Ls
        pat = pattern(space)
        total = float(L.sum())
        fields = {rs: C[j].reshape(shape) for j, rs in enumerate(TENSOR_PAIRS)}
        if self.weights[members[0]] is None:
            data = stiffness_data(space, fields, pat)
        else:  # the NURBS basis N / W (iga.discretisation.rational)
            W, dW = weight_fields(self.model.patches[members[0]].spline, space, P)
            data = banded_to_csr_data(space, banded_form(space, rational_form(stiffness_half_terms(fields), W, dW)),
                                      pat)
            data += data[:, pat.transpose]
            w = self.weights[members[0]].reshape(-1)
            data *= nurbs_scale(pat, w)  # the basis N / W to R = w N / W: both sides scaled by w
            L = rational_load(L.reshape(shape), W)
            loads = load_form(space, L.reshape(shape)) * self.weights[members[0]] if np.any(L) else None
            return pat, data, loads, total
        del C
        return pat, data, (load_form(space, L.reshape(shape)) if np.any(L) else None), total

    def _compiled_nurbs(self, members, space, conductivity, source):
        """:meth:`_group` of patches analysed in the NURBS basis, by the compiled kernel: the ten fields of
        :data:`RATIONAL_DIFFUSION` and the load density L / W per slab, then the entries scaled by w_i w_j and
        the loads by w_i (:mod:`iga.discretisation.rational`)."""
        W, dW = weight_grid(self.model.patches[members[0]].spline, space.qaxes)
        W, dW = W.reshape(space.qshape), [d.reshape(space.qshape) for d in dW]
        acc = fast_assembly.FormAccumulator(space, len(members), RATIONAL_DIFFUSION)
        total = 0.0
        for planes, Cs, Ls in self._slabs(members, space, conductivity, source, compiled=True):
            total += float(Ls.sum())
            Wp, dWp = W[planes].reshape(-1), [d[planes].reshape(-1) for d in dW]
            acc.add(planes, rational_diffusion_fields(Cs, Wp, dWp), Ls / Wp if np.any(Ls) else None)
        pat, data = acc.result()
        w = self.weights[members[0]]
        data *= nurbs_scale(pat, w.reshape(-1))
        return pat, data, (acc.load * w if acc.load is not None else None), total

    def _slabs(self, members, space, conductivity, source, compiled=False):
        """Coefficient fields on the Gauss grid of patches ``members`` (same tile spline and space), by slabs.

        Yields ``(planes, C, L)``: ``planes`` a slice of whole elements' Gauss
        planes along the first axis, C (6, P, n) the stiffness coefficient
        fields (:func:`iga.heat.forms.diffusion`) and L (P, n) the source density on
        those planes (n points per patch, C order).  The full-grid geometry
        never exists.  ``compiled``: the arithmetic runs in the numba kernels,
        geometry and metric fused for patches without placement or map and with
        constant conductivity and source (:func:`iga.assembly.compiled.metric_slabs`).
        """
        patches = [self.model.patches[i] for i in members]
        P = len(members)
        where = f"patch {members[0]}" if P == 1 else f"patches {members[0]}..{members[-1]}"
        lo, hi = np.inf, -np.inf  # det range over all slabs: a sign change between slabs is a fold too
        kc, fc = conductivity.constant, source.constant
        if (compiled and kc is not None and fc is not None
                and all(p.placement is None and p.outer is None for p in patches)):
            # x = spline(xi), k and f constant: geometry and metric in one compiled pass (the patches of the
            # group are the same spline, so one evaluation serves them all)
            for planes, C, L, det in fast_assembly.metric_slabs(patches[0].spline, space, _FUSED_SLAB_POINTS, kc, fc):
                a, b = checked_det(det, where)
                lo, hi = min(lo, a), max(hi, b)
                n = len(L)
                yield planes, np.broadcast_to(C[:, None], (6, P, n)), np.broadcast_to(L, (P, n))
            checked_det(np.array([lo, hi]), where)
            return
        for planes, xs, D, flat, wv in _geometry_slabs(patches, space, compiled):
            kval = conductivity.values(xs, flat, where)
            fval = source.values(xs, flat, where)
            if compiled:
                C, L, det = fast_assembly.metric_fields(D, kval, fval, wv)
            else:
                C, L, det = diffusion(D, kval, fval, wv)
            a, b = checked_det(det, where)
            lo, hi = min(lo, a), max(hi, b)
            yield planes, C.reshape(6, P, -1), L.reshape(P, -1)
        checked_det(np.array([lo, hi]), where)

    def mass(self, coefficient, patches=None):
        """M (CSR, ndof x ndof): int c N_i N_j dV, the zero-order (mass) form, for ``coefficient`` c (a
        :class:`iga.heat.coefficients.ScalarField`; the volumetric heat capacity rho c in J/(m^3 K) makes M
        the heat capacity matrix in J/K per unit of the coefficients).  ``patches`` as in :meth:`assemble`.

        One term of the form vocabulary (:data:`iga.assembly.terms.MASS` through
        :func:`iga.assembly.forms.form_data`, compiled for large groups): the coefficient field c |det J| w on
        the Gauss grid, no derivative on either side; in the NURBS basis
        (:mod:`iga.discretisation.rational`) the field is divided by the weight function squared and the
        entries scaled by w_i w_j."""
        chosen, groups = self.share(patches)
        M = VectorCSR(self.offsets, self.nnz * chosen, components=1)
        M.skip(np.flatnonzero(~chosen))
        for group in groups:
            for members in chunks(group, _weight(self.spaces[group[0]], len(group), False)):
                space = self.spaces[members[0]]
                F = self._weighted_field(members, space, coefficient)
                rational = self.weights[members[0]] is not None
                if rational:
                    W, _ = weight_fields(self.model.patches[members[0]].spline, space, len(members))
                    F /= W ** 2
                pat = pattern(space)
                data = form_data(space, F[None], MASS, pat)
                if rational:
                    data *= nurbs_scale(pat, self.weights[members[0]].reshape(-1))
                M.put(members, pat, {(0, 0): data})
        return M.matrix()

    def load(self, source, patches=None) -> tuple[np.ndarray, float]:
        """(f, total): the load vector f_i = int s N_i dV (ndof,) of the volumetric ``source`` s (a
        :class:`iga.heat.coefficients.ScalarField`, W/m^3 for heat) and its integral int s dV (W), without the
        stiffness; for a source that changes while the stiffness does not (a transient source).  ``patches`` as
        in :meth:`assemble`; the same Gauss rule and NURBS basis as :meth:`assemble`'s load."""
        f = np.zeros(self.ndof)
        total = 0.0
        for group in self.share(patches)[1]:
            for members in chunks(group, _weight(self.spaces[group[0]], len(group), False)):
                space = self.spaces[members[0]]
                L = self._weighted_field(members, space, source)
                total += float(L.sum())
                if self.weights[members[0]] is not None:  # the NURBS basis: N / W, scaled by the weights
                    W, _ = weight_fields(self.model.patches[members[0]].spline, space, len(members))
                    loads = load_form(space, rational_load(L, W)) * self.weights[members[0]]
                else:
                    loads = load_form(space, L)
                f[_rows(self.offsets, members)] += loads.reshape(-1)
        return f, total

    def _weighted_field(self, members, space, coefficient) -> np.ndarray:
        """c |det J| w on the Gauss grid of patches ``members``: (P,) + qshape."""
        patches = [self.model.patches[i] for i in members]
        where = f"patch {members[0]}" if len(members) == 1 else f"patches {members[0]}..{members[-1]}"
        F = np.empty((len(members), space.nq_total))
        rest = space.nq_total // space.dirs[0].nq
        lo, hi = np.inf, -np.inf
        for planes, xs, D, flat, wv in _geometry_slabs(patches, space, False):
            _, det = gradient_and_det(D, None)
            a, b = checked_det(det, where)
            lo, hi = min(lo, a), max(hi, b)
            c = np.broadcast_to(coefficient.values(xs, flat, where), det.shape)
            F[:, planes.start * rest: planes.stop * rest] = (c * np.abs(det) * wv).reshape(len(members), -1)
        checked_det(np.array([lo, hi]), where)
        return F.reshape((len(members),) + space.qshape)


def _geometry_slabs(patches, space, compiled: bool):
    """The geometry of ``patches`` (one tile spline, one space) on their Gauss grid, by slabs of whole elements:
    yields (planes (slice of axis 0), x (P n, 3), [dx/du, dx/dv, dx/dw] each (P, n, 3), channels {name: (P n,)},
    quadrature weights (P n,))."""
    w_rest = np.multiply.outer(space.dirs[1].qw, space.dirs[2].qw).ravel()  # weights of one plane
    slabs = patches_geometry_derivs_slabs(patches, space.qaxes,
                                          _COMPILED_SLAB_POINTS if compiled else _NUMPY_SLAB_POINTS,
                                          rows_multiple=space.dirs[0].g, compiled=compiled)
    for planes, x, D, chans in slabs:
        n = x.shape[1]
        w = np.multiply.outer(space.dirs[0].qw[planes], w_rest).ravel()
        yield (planes, x.reshape(-1, 3), D, {ch: np.reshape(v, -1) for ch, v in chans.items()},
               np.broadcast_to(w, (len(patches), n)).reshape(-1))



def _rows(offsets: np.ndarray, members) -> np.ndarray:
    """The global DOFs of ``members`` (patches of one space), patch after patch."""
    members = np.asarray(members)
    size = int(offsets[members[0] + 1] - offsets[members[0]])
    return (np.asarray(offsets)[members][:, None] + np.arange(size)).reshape(-1)


#: banded entries that weigh as much as one Gauss point in a batch (:func:`_weight`)
BANDED_PER_POINT = 16


def _weight(space, n_patches: int, compiled: bool) -> int:
    """A patch's weight in Gauss points for batching (:func:`iga.discretisation.faces.chunks`) a group of ``n_patches``: its
    points; on the NumPy path, its banded operator's entries / :data:`BANDED_PER_POINT` where those are more
    (patches of one element, whose banded work per point is largest: 4,096 such patches in one batch took
    372 MB of transient memory).  The compiled path keeps whole batches of points (its memory is the ring)."""
    if compiled:
        return int(space.nq_total)
    band = int(np.prod([2 * d.degree + 1 for d in space.dirs]))
    return max(int(space.nq_total), space.ndof * band // BANDED_PER_POINT)
