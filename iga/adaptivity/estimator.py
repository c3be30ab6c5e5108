"""A posteriori error estimate of a steady heat solution: the residual estimator, per element and per patch.

For -div(K grad T) = f with the energy norm ||e||_E^2 = int grad e . K grad e dV, the estimate on a patch P is

    eta_P^2 = sum over its elements E of (h_E / pi)^2 / k_E ||f + div(K grad T_h)||^2_E          (element residual)
            + 1/4 sum over its faces F glued to a neighbour of (h_F / pi) / k_F ||[K grad T_h . n]||^2_F  (flux jump)
            + sum over its Neumann and Robin faces of (h_F / pi) / k_F ||q_n - (K grad T_h . n)||^2_F  (mismatch)

with ``h`` the local size: the smallest of the element's three edge lengths |dx/dxi_k| dxi_k / p_k, taken at each
Gauss point from the geometry Jacobian (on a face, those of the element it bounds, on the finer side of a glued
face; the smallest, so that a flat or long element is measured across its thin direction), each edge divided by
its direction's degree p_k (the h / p of hp finite elements, Melenk and Wohlmuth 2001: a patch whose degree is
raised is measured as it approximates; on splines of one degree a constant factor), and ``k`` the conductivity
(the mean of the tensor's diagonal).  On a face between two patches each side's residual is half the flux jump,
the mismatch of either side's flux with their average (Ainsworth and Oden 2000, Section 2.2), so each side counts
a quarter of the squared jump and the face half of it.  The residual estimator's reliability rests on
||v - Pv||_E <= C h |v|_1 for a projection P onto the spline space; for splines of every degree and smoothness the L2 projection on an element of size h gives it
with the explicit constant C = 1 / pi (Sande, Manni and Speleers 2019), so the sizes are scaled by 1 / pi and
no constant is fitted; the 1 / p factor follows hp finite elements, whose residual estimators are reliable with
h / p (Melenk and Wohlmuth 2001): ``total`` estimates the energy norm of the error up to a factor of order one
(measured by ``benchmarks/adaptive.py``, which prints the effectivity estimate / true error on every step, and by
the tests for h- and p-refinement).

Flux jumps count across every interface of the model (identity faces, branch faces, the faces between the
children of a split patch); inside a patch the basis is C^(p-1) across its knots where the geometry is smooth,
so the jumps there vanish, except across full-multiplicity knot planes (slots), which this estimate does not
visit, nor the Neumann and Robin mismatch on slot faces (their walls).  The element residual needs second
derivatives of the geometry, taken exactly through the chain rule of x = D(A T(xi) + b), and
div(k grad T) = k lap T + grad k . grad T the gradient of the conductivity: exact for a channel of the tile or
the deformation map (a graded material), zero for a number; a callable conductivity or a tensor must be constant
on each patch (within 1e-9 relative), else it is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations_with_replacement

import numpy as np

from geometry import knots as kn
from geometry.faces import FACE_AXIS
from geometry.grouping import ObjectIndex

from geometry.patches.chain import patches_geometry_derivs

from iga.discretisation.fields import grid_fields
from iga.errors import ProblemError
from iga.heat.conditions import face_values
from iga.heat.solution import flux_vector

__all__ = ["ErrorEstimate", "estimate_error"]

_ONE_PER_PATCH = 1e-9  # relative spread of a conductivity treated as constant on a patch
_AFFINE = 1e-12  # control points off an affine function of the Greville points by less than this (relative): affine
_PAIRS = list(combinations_with_replacement(range(3), 2))  # the six second derivatives (i <= j)
_VOIGT = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]  # the conductivity tensor's components, in order
_CHUNK = 1 << 17  # Gauss points per batch of patches


@dataclass(frozen=True)
class ErrorEstimate:
    """The residual estimate of a heat solution (squares, (J/s)^2 / (W/K) = W: energy-norm units squared).

    ``patch`` (P,) eta_P^2 of every patch (the sum of the three parts); ``residual``, ``jump`` and ``boundary``
    (P,) its element-residual, flux-jump and Neumann/Robin parts; ``elements``: per patch the element
    residuals (E_u, E_v, E_w); ``energy`` the energy of the solution int grad T . K grad T dV (W K);
    ``total`` the estimate sqrt(sum eta_P^2) of the energy norm of the error, ``relative`` it over sqrt(energy).
    """

    patch: np.ndarray
    residual: np.ndarray
    jump: np.ndarray
    boundary: np.ndarray
    elements: list
    energy: float

    @property
    def total(self) -> float:
        """The estimate of the energy norm of the error, sqrt(W K)."""
        return float(np.sqrt(self.patch.sum()))

    @property
    def relative(self) -> float:
        """:attr:`total` over the energy norm of the solution (inf for a zero solution)."""
        return self.total / np.sqrt(self.energy) if self.energy > 0 else float("inf")


def estimate_error(solution) -> ErrorEstimate:
    """The residual estimate (see the module notes) of a steady :class:`iga.Solution`."""
    prob = solution.problem
    if getattr(solution, "physics", None) != "heat" or not getattr(solution, "steady", False):
        raise ProblemError("the error estimate is for steady heat solutions (iga.HeatProblem(...).solve())")
    if prob.conductivity.of_temperature is not None or any(c.kind == "radiation" for c in prob.conditions):
        raise ProblemError("the error estimate is for linear heat problems: drop the temperature-dependent "
                           "conductivity or the radiation")
    if any(w is not None for w in prob.weights):
        raise ProblemError("the error estimate needs polynomial analysis bases; a patch analysed in the NURBS basis "
                           "of its own weights is not supported")
    residual, elements, energy = _residuals(solution)
    jump = _jumps(solution)
    boundary = _boundary(solution)
    return ErrorEstimate(residual + jump + boundary, residual, jump, boundary, elements, energy)


# ------------------------------------------------------------------ element residual
def _tables(space):
    """Per direction the dense basis tables (values, first, second derivatives), each (nq, n)."""
    return [[m.toarray() for m in kn.basis_matrices(d.knots, d.degree, d.qpts, 2)] for d in space.dirs]


def _per_dof(d) -> float:
    """The factor 1 / p of a direction of degree p on the element lengths: the h / p of hp finite elements, so
    that raising a patch's degree is measured (module notes)."""
    return 1.0 / d.degree


def _spacing(space):
    """Per direction the local size, in parameters, of the element of each Gauss point (nq,) (:func:`_per_dof`)."""
    return [np.repeat(np.diff(d.breaks) * _per_dof(d), d.g) for d in space.dirs]


def _derivatives(spline, points):
    """Values (N, m), first (N, m, 3) and second derivatives (N, m, 3, 3) of every component of a trivariate
    spline at parameter points (N, 3)."""
    D = spline.derivatives(points, 2)
    e = np.eye(3, dtype=int)
    J = np.stack([D[tuple(e[i])] for i in range(3)], axis=-1)
    H = np.empty(J.shape + (3,))
    for i, j in _PAIRS:
        H[:, :, i, j] = H[:, :, j, i] = D[tuple(e[i] + e[j])]
    return D[(0, 0, 0)], J, H


def _geometry(patches, T, axes):
    """Geometry of placed patches sharing the tile spline T on the grid ``axes``, by the chain rule of
    x = D(A T + b): x (P, N, 3), J (P, N, 3, 3) [x_a, xi_i], H (P, N, 3, 3, 3) [x_a, xi_i, xi_j], and the channels'
    values {name: (P, N)} and parameter gradients {name: (P, N, 3)} (the map's over the tile's); the patches of
    one map are evaluated in it at once."""
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    vT, JT, HT = _derivatives(T, grid)
    N = len(grid)
    A = np.stack([np.eye(3) if q.placement is None else q.placement[:, :3] for q in patches])
    b = np.stack([np.zeros(3) if q.placement is None else q.placement[:, 3] for q in patches])
    y = np.einsum("pab,nb->pna", A, vT[:, :3]) + b[:, None, :]
    Jy = np.einsum("pab,nbi->pnai", A, JT[:, :3])
    Hy = np.einsum("pab,nbij->pnaij", A, HT[:, :3])
    x, J, H = y.copy(), Jy.copy(), Hy.copy()
    P = len(patches)
    values = {c: np.broadcast_to(vT[:, 3 + i], (P, N)) for i, c in enumerate(T.channels)}
    grads = {c: np.broadcast_to(JT[:, 3 + i], (P, N, 3)) for i, c in enumerate(T.channels)}
    same = ObjectIndex()
    groups: dict = {}
    for i, q in enumerate(patches):
        if q.outer is not None:
            groups.setdefault(same(q.outer), []).append(i)
    for idx in groups.values():
        D = patches[idx[0]].outer
        dom = D.domain
        n = len(idx)
        Jyi = Jy[idx]
        yy = np.clip(y[idx].reshape(-1, 3), dom[:, 0], dom[:, 1])
        affine = _affine(D)
        if affine is not None:  # x = M y + c (a box map): no second derivatives of D, first ones constant
            M, c = affine
            x[idx] = yy.reshape(n, N, 3) @ M.T + c
            J[idx] = np.einsum("ac,pnci->pnai", M, Jyi)
            H[idx] = np.einsum("ac,pncij->pnaij", M, Hy[idx])
            if not D.channels:
                continue
            vD, JD = D.value_and_jacobian(yy)
            JD = JD.reshape(n, N, -1, 3)
        else:
            vD, JD, HD = _derivatives(D, yy)
            JD, HD = JD.reshape(n, N, -1, 3), HD.reshape(n, N, -1, 3, 3)
            x[idx] = vD[:, :3].reshape(n, N, 3)
            J[idx] = np.einsum("pnac,pnci->pnai", JD[:, :, :3], Jyi)
            H[idx] = (np.einsum("pnacd,pnci,pndj->pnaij", HD[:, :, :3], Jyi, Jyi, optimize=True)
                      + np.einsum("pnac,pncij->pnaij", JD[:, :, :3], Hy[idx], optimize=True))
        for i, c in enumerate(D.channels):
            values.setdefault(c, np.zeros((P, N)))
            grads.setdefault(c, np.zeros((P, N, 3)))
            values[c] = np.array(values[c])
            grads[c] = np.array(grads[c])
            values[c][idx] = vD[:, 3 + i].reshape(n, N)
            grads[c][idx] = np.einsum("pnc,pnci->pni", JD[:, :, 3 + i], Jyi)
    return x, J, H, values, grads


def _affine(D):
    """(M (3, 3), c (3,)) when the polynomial map D is affine, x = M y + c (its control points an affine function
    of its Greville points, to round-off of its size), else None."""
    if D.is_rational:
        return None
    P = D.control_points[..., :3].reshape(-1, 3)
    G = np.stack(np.meshgrid(*(kn.greville(U, p) for U, p in zip(D.knots, D.degrees)), indexing="ij"),
                 axis=-1).reshape(-1, 3)
    A = np.c_[G, np.ones(len(G))]
    X = np.linalg.lstsq(A, P, rcond=None)[0]
    size = max(float(np.ptp(P, axis=0).max()), 1.0)
    if np.abs(A @ X - P).max() > _AFFINE * size:
        return None
    return X[:3].T, X[3]


def _field_derivatives(U, tables):
    """Parameter gradient (P, N, 3) and Hessian (P, N, 3, 3) of fields with coefficient blocks U (P, n1, n2, n3)."""
    P = U.shape[0]

    def contract(orders):
        B = [tables[d][orders[d]] for d in range(3)]
        return np.einsum("pabc,ia,jb,kc->pijk", U, *B, optimize=True).reshape(P, -1)

    e = np.eye(3, dtype=int)
    g = np.stack([contract(e[i]) for i in range(3)], axis=-1)
    H = np.empty(g.shape + (3,))
    for i, j in _PAIRS:
        H[..., i, j] = H[..., j, i] = contract(e[i] + e[j])
    return g, H


def _refuse_varying(values: np.ndarray, where: str) -> None:
    """A conductivity whose gradient is not known (a callable, a tensor) must be constant on each patch."""
    v = np.asarray(values, float).reshape(len(values), -1)
    spread = np.abs(v - v[:1]).max()
    if spread > _ONE_PER_PATCH * np.abs(v).max():
        raise ProblemError(f"the error estimate needs the gradient of the conductivity; on {where} the conductivity "
                           f"(a callable or a tensor) varies by {spread:.3g} W/(m K): give a graded conductivity as a "
                           "channel of the tile or the map (its gradient is exact), or refine uniformly")


def _conductivity(prob, x, chans, where):
    """(K6 (N, 6) tensor components, k (N,) mean of the diagonal, channel name whose gradient enters or None)."""
    cond = prob.conductivity
    v = np.asarray(cond.values(x, chans, where), float)
    if v.ndim == 1:
        channel = cond.scalar.spec if cond.scalar is not None and cond.scalar.kind == "channel" else None
        if channel is None and cond.constant is None:
            _refuse_varying(v, where)
        K6 = np.zeros((len(v), 6))
        K6[:, :3] = v[:, None]
        return K6, v, channel
    if cond.constant is None:
        _refuse_varying(v, where)
    return v, v[:, :3].mean(axis=1), None


def _residuals(solution):
    """Element residuals per patch (P,), per element, and the solution's energy int grad T . K grad T dV."""
    prob = solution.problem
    model, spaces, offsets = prob.model, prob.spaces, prob.offsets
    n = len(model.patches)
    out, elements, energy = np.zeros(n), [None] * n, 0.0
    same = ObjectIndex()
    groups: dict = {}
    for pi, patch in enumerate(model.patches):
        groups.setdefault((same(patch.spline), spaces[pi].key()), []).append(pi)
    for members in groups.values():
        space = spaces[members[0]]
        tables, dxi = _tables(space), _spacing(space)
        axes = [d.qpts for d in space.dirs]
        w = np.einsum("i,j,k->ijk", *(d.qw for d in space.dirs)).ravel()
        cell = np.stack(np.meshgrid(*dxi, indexing="ij"), axis=-1).reshape(-1, 3)  # element lengths in xi
        per = max(1, _CHUNK // len(w))
        for c0 in range(0, len(members), per):
            chunk = members[c0 : c0 + per]
            x, J, H, chans, dchans = _geometry([model.patches[i] for i in chunk], model.patches[chunk[0]].spline, axes)
            U = np.stack([solution.u[offsets[i] : offsets[i + 1]].reshape(space.shape) for i in chunk])
            g, Hu = _field_derivatives(U, tables)
            det = np.linalg.det(J)
            G = np.linalg.inv(J)  # [xi_i, x_a]
            grad = np.einsum("pnia,pni->pna", G, g)  # physical gradient
            # d2u/dxi_i dxi_j = J^T Hx J + sum_a (grad u)_a d2x_a/dxi_i dxi_j
            M = Hu - np.einsum("pna,pnaij->pnij", grad, H)
            Hx = np.einsum("pnia,pnij,pnjb->pnab", G, M, G)
            for j, pi in enumerate(chunk):
                where = f"patch {pi}"
                ch = {c: v[j] for c, v in chans.items()}
                K6, k, channel = _conductivity(prob, x[j], ch, where)
                div = sum((1.0 if a == b else 2.0) * K6[:, m] * Hx[j, :, a, b] for m, (a, b) in enumerate(_VOIGT))
                if channel is not None:  # grad k . grad T, grad k = J^-T dk/dxi
                    div = div + np.einsum("nia,ni,na->n", G[j], dchans[channel][j], grad[j])
                r = prob.source.values(x[j], ch, where) + div
                h = (np.linalg.norm(J[j], axis=1) * cell).min(axis=1)
                dV = np.abs(det[j]) * w
                contrib = (h / np.pi) ** 2 * r**2 / k * dV
                out[pi] = contrib.sum()
                energy -= float(np.sum(np.einsum("na,na->n", flux_vector(K6, grad[j]), grad[j]) * dV))
                elements[pi] = _per_element(contrib, space)
    return out, elements, energy


def _per_element(contrib: np.ndarray, space) -> np.ndarray:
    """Gauss-point contributions (N,) summed per element -> (E_u, E_v, E_w)."""
    shape = []
    for d in space.dirs:
        shape += [d.E, d.g]
    return contrib.reshape(shape).sum(axis=(1, 3, 5))


# ------------------------------------------------------------------ faces
def _face_axes(space, domain, face):
    """The Gauss grid of a standard face as three parameter axes (the face's own direction a single value)."""
    k, side = FACE_AXIS[face]
    axes = [d.qpts for d in space.dirs]
    axes[k] = np.array([domain[k, side]])
    return axes


def _element_lengths(space, axes):
    """Per direction the parameter length of the element holding each axis point (a face's end value: the
    boundary element), as a grid (N, 3) in C order."""
    lengths = []
    for d, ax in zip(space.dirs, axes):
        e = np.clip(np.searchsorted(d.breaks, ax, side="right") - 1, 0, d.E - 1)
        lengths.append(np.diff(d.breaks)[e] * _per_dof(d))
    return np.stack(np.meshgrid(*lengths, indexing="ij"), axis=-1).reshape(-1, 3)


def _flux_on_grid(solution, members, axes, normals):
    """K grad T . n (P, N), T (P, N), the conductivity (mean of the diagonal, (P, N)) and the local element size
    (P, N) of patches ``members`` (one tile spline and space) on the grid ``axes``, with unit normals (P, N, 3)."""
    prob = solution.problem
    space = prob.spaces[members[0]]
    tabs = [[m.toarray() for m in kn.basis_matrices(d.knots, d.degree, np.clip(ax, d.knots[0], d.knots[-1]), 1)]
            for d, ax in zip(space.dirs, axes)]
    U = np.stack([solution.u[prob.offsets[i] : prob.offsets[i + 1]].reshape((1,) + space.shape) for i in members])
    P = len(members)
    x, D, chans = patches_geometry_derivs([prob.model.patches[i] for i in members], axes)
    val, grad, _ = grid_fields(U, tabs, D)
    val, grad = val[:, 0].reshape(P, -1), grad[:, 0]
    K6, k, _ = _conductivity(prob, x.reshape(-1, 3), {c: np.asarray(v).reshape(-1) for c, v in chans.items()},
                             f"patches {members[0]}..{members[-1]}")
    q = -np.einsum("ni,ni->n", flux_vector(K6, grad), normals.reshape(-1, 3))
    h = (np.stack([np.linalg.norm(np.asarray(d), axis=-1) for d in D], axis=-1) * _element_lengths(space, axes)).min(-1)
    return q.reshape(P, -1), val, k.reshape(P, -1), h.reshape(P, -1)


def _batched(solution, requests):
    """Evaluate :func:`_flux_on_grid` for many requests (patch, axes, normals (N, 3)) -> [(q, T, k, h), each (N,)],
    grouped by tile spline, space and grid."""
    prob = solution.problem
    same = ObjectIndex()
    groups: dict = {}
    for r, (pi, axes, _) in enumerate(requests):
        key = (same(prob.model.patches[pi].spline), prob.spaces[pi].key(), tuple(a.tobytes() for a in axes))
        groups.setdefault(key, []).append(r)
    out = [None] * len(requests)
    for rs in groups.values():
        members = [requests[r][0] for r in rs]
        q, T, k, h = _flux_on_grid(solution, members, requests[rs[0]][1], np.stack([requests[r][2] for r in rs]))
        for j, r in enumerate(rs):
            out[r] = (q[j], T[j], k[j], h[j])
    return out


def _jumps(solution) -> np.ndarray:
    """Flux jumps over every interface between standard faces: a quarter of h_F / pi ||jump||^2 / k to each side's
    patch (P,) (the module notes)."""
    prob = solution.problem
    model = prob.model
    out = np.zeros(len(model.patches))
    itfs = [itf for itf in model.interfaces if itf.a[1] in FACE_AXIS and itf.b[1] in FACE_AXIS]  # slots: notes
    if not itfs:
        return out
    fds = prob.faces_data([itf.b for itf in itfs])
    requests, meta = [], []
    for itf, fd in zip(itfs, fds):
        (pa, _), (pb, fb) = itf.a, itf.b
        axes_b = _face_axes(prob.spaces[pb], model.patches[pb].spline.domain, fb)
        axes_a, transposed = _map_axes(axes_b, fb, itf, model.patches[pa].spline.domain,
                                       model.patches[pb].spline.domain)
        shape_b = tuple(len(axes_b[d]) for d in range(3) if d != FACE_AXIS[fb][0])
        n_a = fd.normal
        if transposed:  # a's grid runs over b's points transposed: hand a its normals in its own order
            n_a = fd.normal.reshape(shape_b + (3,)).transpose(1, 0, 2).reshape(-1, 3)
        requests += [(pb, axes_b, fd.normal), (pa, axes_a, n_a)]
        meta.append((pa, pb, fd, shape_b, transposed))
    results = _batched(solution, requests)
    for j, (pa, pb, fd, shape_b, transposed) in enumerate(meta):
        (qb, _, kb, h), (qa, _, ka, _) = results[2 * j], results[2 * j + 1]
        if transposed:
            qa, ka = (v.reshape(shape_b[::-1]).T.ravel() for v in (qa, ka))
        k = 0.5 * (ka + kb)
        term = float(np.sum(h / np.pi * (qa - qb) ** 2 / k * fd.dAw))
        out[pa] += 0.25 * term
        out[pb] += 0.25 * term
    return out


def _map_axes(axes_b, fb, itf, domain_a, domain_b):
    """Face a's parameter axes at the points of face b's Gauss grid ``axes_b`` across ``itf`` (b's normalised face
    coordinates flipped per ``flip``, swapped into a's frame, placed on a's face or, for a branch, on its box),
    and whether a's grid is b's transposed (``swap``)."""
    kb, _ = FACE_AXIS[fb]
    rb = [d for d in range(3) if d != kb]
    ka, side = FACE_AXIS[itf.a[1]]
    ra = [d for d in range(3) if d != ka]
    t = [(np.asarray(axes_b[d]) - domain_b[d, 0]) / (domain_b[d, 1] - domain_b[d, 0]) for d in rb]
    t = [1 - tj if f else tj for tj, f in zip(t, itf.flip)]
    if itf.swap:
        t = t[::-1]
    axes = [None, None, None]
    axes[ka] = np.array([domain_a[ka, side]])
    for j, d in enumerate(ra):
        lo, hi = itf.box[j] if itf.kind == "branch" else domain_a[d]
        axes[d] = lo + t[j] * (hi - lo)
    return axes, bool(itf.swap)


def _boundary(solution) -> np.ndarray:
    """Neumann and Robin mismatches per patch (P,)."""
    prob = solution.problem
    model = prob.model
    out = np.zeros(len(model.patches))
    by_kind = prob.faces_by_kind()
    items = [(key, kind, c) for kind in ("neumann", "robin") for key, c in by_kind[kind].items() if key[1] in FACE_AXIS]
    if not items:
        return out
    fds = prob.faces_data([key for key, _, _ in items])
    requests = [(pi, _face_axes(prob.spaces[pi], model.patches[pi].spline.domain, face), fd.normal)
                for ((pi, face), _, _), fd in zip(items, fds)]
    for ((pi, _), kind, cond), fd, (qn, T, k, h) in zip(items, fds, _batched(solution, requests)):
        value = face_values(cond.value, [fd], cond.tag)[0]
        if kind == "neumann":  # K grad T . n = q (inward flux)
            r = value - qn
        else:  # -K grad T . n = h (T - T_ambient)
            r = -qn - face_values(cond.h, [fd], cond.tag)[0] * (T - value)
        out[pi] += float(np.sum(h / np.pi * r**2 / k * fd.dAw))
    return out
