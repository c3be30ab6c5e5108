"""Values and physical gradients of solution fields (one or several components per basis function) on
tensor grids of points, a patch's field as a spline, and their integrals by the problem's Gauss rule: shared by
the heat and the elastic solutions and by the VTU sampling."""

from __future__ import annotations

import numpy as np

from geometry import SplineFunction
from geometry.patches.chain import gradient_and_det, patches_geometry_derivs
from geometry.tolerances import SINGULAR
from geometry.grouping import ObjectIndex

from iga.errors import ProblemError
from iga.discretisation.faces import chunks

__all__ = ["grid_fields", "grid_contract", "integrate_fields", "GaussPoints", "GaussGeometry", "field_spline",
           "physical_gradient", "evaluation_matrix"]

#: bytes of Gauss-point geometry a problem keeps (:class:`GaussGeometry`); larger models evaluate it every pass
GAUSS_GEOMETRY_BYTES = 64 << 20


class GaussGeometry:
    """The geometry at a problem's Gauss points, per group of patches that share a space: the points x (P, n, 3),
    the derivatives [dx/dxi_k (P, n, 3)] * 3 and the channels {name: (P, n)} of
    :func:`geometry.patches.chain.patches_geometry_derivs`; kept (read-only) once :meth:`keep` was called and
    while the whole problem's fits in ``budget`` bytes, else evaluated at every pass.

    An output's value, its adjoint load and its sensitivity each pass over the Gauss points once per design
    step, and the deformation map's evaluation is the dearest part of a pass; a problem's geometry does not
    change, so the sensitivities (:mod:`iga.sensitivity`) and the optimiser's analyses ask to keep it and the
    passes after the first read it here (the circular demo sink's shape gradient: 1.45-1.66 forward analyses ->
    1.13-1.15).  An analysis that passes once (the energy identity of a solve) keeps nothing."""

    def __init__(self, budget: int = GAUSS_GEOMETRY_BYTES):
        self.budget, self.keeping, self._kept = int(budget), False, {}

    def keep(self, problem) -> None:
        """Keep the geometry from now on if all of ``problem``'s fits in the budget (x, three derivatives and
        the map's channels at every Gauss point)."""
        if self.keeping:
            return
        channels = {name for p in problem.model.patches for name in p.channels}
        size = sum(s.nq_total for s in problem.spaces) * (12 + len(channels)) * 8
        self.keeping = size <= self.budget

    def of(self, model, chunk, space) -> tuple:
        """(x, [dx/dxi_k] * 3, channels) at ``space``'s Gauss grid on the patches ``chunk`` of ``model``."""
        key = (tuple(int(i) for i in chunk), space.key())
        kept = self._kept.get(key)
        if kept is not None:
            return kept
        x, D, chans = patches_geometry_derivs([model.patches[i] for i in chunk], space.qaxes)
        if self.keeping:
            for a in (x, *D, *chans.values()):
                a.flags.writeable = False  # shared by every later pass
            self._kept[key] = (x, D, chans)
        return x, D, chans


def grid_fields(U: np.ndarray, tables, D, weights=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Values (P N, c), physical gradients (P N, c, 3) and det J (P N,) of coefficient blocks U (P, c) + shape.

    ``tables``: per direction (values, derivatives), each (points, n) of the 1-D basis at that direction's
    grid points; ``D``: the geometry's parameter derivatives at the P N grid points (C order per patch);
    ``weights``: the NURBS weights (shape) where the patches are analysed in the NURBS basis
    (:mod:`iga.discretisation.rational`): U then holds NURBS control values, the field sum w_i U_i N_i / W.
    """
    def on_grid(block):  # values (P N,) and parameter derivatives (P N, 3) of coefficient blocks (P,) + shape
        v = grid_contract(block, *(tables[d][0] for d in range(3)))
        dv = np.stack([grid_contract(block, *(tables[d][int(d == k)] for d in range(3))).reshape(-1)
                       for k in range(3)], -1)
        return v.reshape(-1), dv

    W = dW = None
    if weights is not None:
        W, dW = on_grid(np.broadcast_to(weights, (U.shape[0],) + weights.shape))
    vals, grads, det = [], [], None
    for a in range(U.shape[1]):
        v, dxi = on_grid(U[:, a] if weights is None else U[:, a] * weights)
        if W is not None:  # T = phi / W, dT = (dphi - T dW) / W
            v = v / W
            dxi = (dxi - v[:, None] * dW) / W[:, None]
        vals.append(v)
        g, det = gradient_and_det(D, dxi)
        grads.append(g)
    return np.stack(vals, 1), np.stack(grads, 1), det


def grid_contract(block: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """sum_abc block[p, a, b, c] A[i, a] B[j, b] C[k, c] -> (P, i, j, k): one direction at a time (sum
    factorisation by matrix products; no per-call contraction-path search, which dominates for small patches)."""
    P, na, nb, nc = block.shape
    t = np.matmul(block.reshape(P, na, nb, nc), C.T)  # (P, a, b, k)
    t = np.matmul(B, t)  # (P, a, j, k)
    t = np.matmul(A, t.reshape(P, na, -1))  # (P, i, j k)
    return t.reshape(P, A.shape[0], B.shape[0], C.shape[0])


def integrate_fields(prob, coefficients, components: int, fn, context: bool = False):
    """Sum over the model of int fn(x (N, 3), values (N, c), grads (N, c, 3)) dV by the problem's Gauss rule.

    ``coefficients(i)``: patch i's coefficient block (c,) + space shape; patches sharing a tile spline and
    a space are evaluated together.  ``fn`` returns (N,) (a float is returned) or (N, k) (k integrals from one
    pass, an array (k,)).  ``context``: ``fn`` takes a fourth argument, a :class:`GaussPoints` with the
    channels at the points and the patches and parameters they belong to (materials and thermal strains
    evaluated where the field is).
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    groups: dict = {}
    for i, s in enumerate(prob.spaces):
        groups.setdefault((s.key(), same(prob.model.patches[i].spline)), []).append(i)
    total = 0.0
    for members in groups.values():
        space = prob.spaces[members[0]]
        tables = [np.swapaxes(d.B[:, :, :-1], 1, 2) for d in space.dirs]  # (2, nq, n): values and derivatives
        w = np.einsum("i,j,k->ijk", *[d.qw for d in space.dirs]).ravel()
        params = np.stack(np.meshgrid(*space.qaxes, indexing="ij"), -1).reshape(-1, 3) if context else None
        for chunk in chunks(members, components * space.nq_total):
            x, D, chans = prob.gauss_geometry.of(prob.model, chunk, space)
            vals, grads, det = grid_fields(np.stack([coefficients(i) for i in chunk]), tables, D,
                                           _weights(prob, chunk[0]))
            if not np.all(np.isfinite(grads)):
                raise ProblemError(f"patches {chunk[0]}..{chunk[-1]}: the geometry Jacobian is singular at a Gauss "
                                   "point; the model is degenerate there")
            wv = np.broadcast_to(w, (len(chunk), len(w))).reshape(-1) * np.abs(det)
            args = (x.reshape(-1, 3), vals, grads)
            if context:
                args += (GaussPoints(x, {c: np.reshape(v, -1) for c, v in chans.items()}, chans, list(chunk),
                                     params),)
            total = total + np.tensordot(wv, np.asarray(fn(*args), float), axes=(0, 0))
    return float(total) if np.ndim(total) == 0 else np.asarray(total)


class GaussPoints:
    """Where an integrand of :func:`integrate_fields` is evaluated: ``x`` (P, n, 3) points of the patches
    ``patches`` (P of them), ``chans`` {name: (P n,)} flat channels, ``by_patch`` {name: (P, n)}, and
    ``params`` (n, 3) the Gauss points in every one of those patches' parameters."""

    def __init__(self, x, chans, by_patch, patches, params):
        self.x, self.chans, self.by_patch, self.patches, self.params = x, chans, by_patch, patches, params

    def per_patch(self, fn) -> np.ndarray:
        """``fn(patch, x (n, 3), params (n, 3), chans {name: (n,)}) -> (n,)`` of every patch, concatenated."""
        return np.concatenate([fn(pi, self.x[j], self.params, {c: v[j] for c, v in self.by_patch.items()})
                               for j, pi in enumerate(self.patches)])


def _weights(prob, pi):
    """The NURBS weights of patch ``pi``'s space where it is analysed in the NURBS basis, else None."""
    w = getattr(prob, "weights", None)
    return None if w is None else w[pi]


def physical_gradient(J: np.ndarray, dxi: np.ndarray, where: str, params=None) -> np.ndarray:
    """grad T = J^-T dT/dxi (N, 3); :class:`ProblemError` where the geometry Jacobian J (N, 3, 3) is singular."""
    det = np.linalg.det(J)
    scale = np.abs(J).max(axis=(1, 2)) ** 3
    bad = ~(np.abs(det) > 0.1 * SINGULAR * scale)
    if bad.any():
        i = int(np.argmax(bad))
        at = f" at parameters {np.round(params[i], 6).tolist()}" if params is not None else ""
        raise ProblemError(f"{where}: the geometry Jacobian is singular{at} (a degenerate point: collapsed edge or "
                           "fold), so the gradient and the heat flux are undefined there")
    return np.linalg.solve(np.transpose(J, (0, 2, 1)), dxi[:, :, None])[:, :, 0]


def field_spline(space, coef: np.ndarray, weights=None) -> SplineFunction:
    """A solution field on one patch as a spline over its parameters: ``coef`` (space.shape + (c,)) the
    coefficients; with the NURBS weights of :mod:`iga.discretisation.rational` (``weights``) the NURBS function of those
    weights, ``coef`` its control values."""
    return SplineFunction([d.degree for d in space.dirs], [d.knots for d in space.dirs], coef, weights=weights)


def evaluation_matrix(problem, where: np.ndarray, params: np.ndarray):
    """The sparse matrix E (N, ndof) with ``E @ u`` the field of coefficients u (ndof,) at N points: patch
    ``where`` (N,) and parameters ``params`` (N, 3) of each (:class:`iga.discretisation.locate.Locator`).  Each
    row holds the point's tensor-product basis values (the NURBS basis where the patch is analysed in it,
    :mod:`iga.discretisation.rational`), so a field's time series at fixed points is one product with its
    states."""
    import scipy.sparse as sp

    from geometry import knots as kn

    where, params = np.asarray(where, int), np.asarray(params, float)
    rows, cols, vals = [], [], []
    for pi in np.unique(where):
        sel = np.flatnonzero(where == pi)
        space = problem.spaces[int(pi)]
        idx, val = np.zeros((len(sel), 1), np.int64), np.ones((len(sel), 1))
        for d, dir_ in enumerate(space.dirs):  # the tensor product, one direction after the other (C order)
            spans, ders = kn.basis_functions(dir_.knots, dir_.degree, params[sel, d], 0)
            first = spans - dir_.degree
            local = first[:, None] + np.arange(dir_.degree + 1)
            idx = (idx[:, :, None] * space.shape[d] + local[:, None, :]).reshape(len(sel), -1)
            val = (val[:, :, None] * ders[:, 0, None, :]).reshape(len(sel), -1)
        w = problem.weights[int(pi)]
        if w is not None:  # R_i = w_i N_i / sum_j w_j N_j
            wv = w.reshape(-1)[idx] * val
            val = wv / wv.sum(axis=1, keepdims=True)
        rows.append(np.repeat(sel, idx.shape[1]))
        cols.append((idx + problem.offsets[int(pi)]).reshape(-1))
        vals.append(val.reshape(-1))
    n = len(where)
    if not rows:
        return sp.csr_matrix((n, problem.ndof))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, problem.ndof))
