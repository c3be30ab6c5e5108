"""Exact geometry of a patch at parameter points: x = D(A T(xi) + b), J = J_D A J_T.

The chain rule is exact and avoids forming the high-degree composed spline
(DESIGN.md, performance note).  Channels are returned by name: tile channels
from ``T``, deformation-map channels from ``D`` at the mapped point.
"""

from __future__ import annotations

import numpy as np

from geometry.compiled import _fast
from geometry import knots as kn
from geometry.cache import BoundedCache
from geometry.errors import SplineError
from geometry.grouping import ObjectIndex


def _dehomogenise(spline, H, dH):
    if not spline.is_rational:
        return H, dH
    w = H[:, -1:]
    x = H[:, :-1] / w
    return x, [(dh[:, :-1] - x * dh[:, -1:]) / w for dh in dH]


#: (values, first derivatives) basis matrices per (knots, degree, axis): the placed copies of one tile patch
#: and the composed patches of one tile share knot vectors, so a model's grids need few distinct ones.  Axes of
#: at most _CACHED_AXIS points only (Gauss points of a patch): at most about 10 MB at degree 12
_BASES = BoundedCache(256)
_CACHED_AXIS = 128


def _bases(U, p, ax):
    if len(ax) > _CACHED_AXIS:
        return tuple(kn.basis_matrices(U, p, ax, 1))

    def make():
        mats = tuple(kn.basis_matrices(U, p, ax, 1))
        for m in mats:  # shared between calls: read-only
            for a in (m.data, m.indices, m.indptr):
                a.setflags(write=False)
        return mats

    return _BASES.get((np.asarray(U, float).tobytes(), int(p), np.asarray(ax, float).tobytes()), make)


def _prepare(spline, axes, order):
    """Basis matrices per direction and the contraction prefixes shared by value and derivatives."""
    d = spline.dim
    B = []
    for k, ax in enumerate(axes):
        U, p = spline.knots[k], spline.degrees[k]
        B.append(_bases(U, p, np.clip(ax, U[0], U[-1])))
    outputs = [tuple(0 for _ in range(d))] + [tuple(int(i == k) for i in range(d)) for k in range(d)]
    keys = [tuple(o[k] for k in order) for o in outputs]
    return B, keys


def _contract_prefixes(hom, B, order, keys, depth):
    """Partial contractions of ``hom`` along order[:depth] for every prefix in ``keys``.

    A prefix is freed as soon as its last extension is computed, so at most
    one level and the next are alive.
    """
    level = {(): hom}
    for j in range(depth):
        k = order[j]
        need = sorted({key[: j + 1] for key in keys})
        nxt = {}
        for pre in need:
            nxt[pre] = kn.apply_along(level[pre[:-1]], k, B[k][pre[-1]])
            if not any(q[:-1] == pre[:-1] for q in need if q > pre):
                del level[pre[:-1]]
        level = nxt
    return level


#: grid points from which :func:`grid_values_derivs` uses the compiled kernel (when numba is installed);
#: from :data:`COMPILED_PROBLEM_GRID_POINTS` when the caller's problem uses the compiled assembly anyway
COMPILED_GRID_POINTS = 25_000
COMPILED_PROBLEM_GRID_POINTS = 2_000


def grid_values_derivs(spline, axes, compiled: bool = False):
    """Values (N, m) and first derivatives [(N, m)] * d on a tensor grid (C order; rational handled).

    Sum factorisation with shared partial contractions: directions are
    contracted in order of growth (a face's single-point direction first), and
    the value and every derivative share their common prefixes.  3-D grids of
    at least :data:`COMPILED_GRID_POINTS` points (large faces) run in the
    compiled kernel of :mod:`geometry.compiled._fast` when numba is installed
    (NumPy's contractions copy every partial result); with ``compiled`` (the
    problem assembles with the compiled kernels) from
    :data:`COMPILED_PROBLEM_GRID_POINTS`.  Small analyses never import numba.
    """
    d = spline.dim
    hom = spline.homogeneous
    m = hom.shape[-1]
    n = int(np.prod([len(a) for a in axes]))
    if d == 3 and n >= (COMPILED_PROBLEM_GRID_POINTS if compiled else COMPILED_GRID_POINTS):
        if _fast.AVAILABLE:
            # the kernel contracts direction 2 first, over every coefficient row: on a face v = const
            # (one point in direction 1) that would make a full (n0, n1, nq2) partial result, so v and w
            # swap places; with a single v point the points keep their C order
            order = (0, 2, 1) if len(axes[1]) == 1 < len(axes[2]) else (0, 1, 2)
            out = _fast.grid_derivs(hom.transpose(*order, 3), slice(0, len(axes[0])),
                                    _fast.grid_tables(spline, axes, order))
            dH = [None] * 3
            for j, k in enumerate(order):
                dH[k] = out[1 + j]
            return _dehomogenise(spline, out[0], dH)
    # ties: last direction first, so that direction 0 comes last and the result is C-contiguous
    order = sorted(range(d), key=lambda k: (len(axes[k]) / hom.shape[k], -k))
    B, keys = _prepare(spline, axes, order)
    done = _contract_prefixes(hom, B, order, keys, d)
    H, *dH = [done[key].reshape(-1, m) for key in keys]
    return _dehomogenise(spline, H, dH)


def grid_values_derivs_slabs(spline, axes, points_per_slab: int = 1 << 15, rows_multiple: int = 1,
                             compiled: bool = False):
    """:func:`grid_values_derivs` in slabs of the first axis: yields (rows slice of axis 0, x, [dx]).

    Directions 1..d-1 are contracted once; the last contraction (direction 0)
    runs per slab, so the full-grid values and derivatives never exist at once.
    A slab has about ``points_per_slab`` points and a multiple of
    ``rows_multiple`` rows (the Gauss points of whole elements).
    ``compiled`` (3-D only, numba): each slab is evaluated from the
    coefficients by the kernel of :mod:`geometry.compiled._fast` instead, with no
    full-grid partial contractions at all.
    """
    d = spline.dim
    hom = spline.homogeneous
    m = hom.shape[-1]
    rest = int(np.prod([len(a) for a in axes[1:]]))
    rows = rows_multiple * max(1, points_per_slab // max(rest * rows_multiple, 1))
    n0 = len(axes[0])
    if compiled and d == 3:
        tables = _fast.grid_tables(spline, axes)
        for a in range(0, n0, rows):
            sl = slice(a, min(a + rows, n0))
            out = _fast.grid_derivs(hom, sl, tables)
            yield (sl, *_dehomogenise(spline, out[0], list(out[1:])))
        return
    order = list(range(d - 1, -1, -1))  # direction 0 last: slabs of it are contiguous in C order
    B, keys = _prepare(spline, axes, order)
    level = _contract_prefixes(hom, B, order, keys, d - 1)
    level = {k: np.ascontiguousarray(v) for k, v in level.items()}  # each slab reads them as (n_0, rest)
    for a in range(0, n0, rows):
        sl = slice(a, min(a + rows, n0))
        out = [kn.apply_along(level[key[:-1]], 0, B[0][key[-1]][sl]).reshape(-1, m) for key in keys]
        yield (sl, *_dehomogenise(spline, out[0], out[1:]))


def _outer_map(patches, xT, DT, compiled: bool = False):
    """Placements and deformation map applied to shared tile values (N, m) and derivatives [(N, m)] * 3.

    ``patches`` share the tile spline that produced ``xT``.  Returns x (P, N, 3),
    the physical derivatives [(P, N, 3)] * 3 (chain rule) and all channels
    {name: (P, N)}: the tile's (broadcast) and the map's; one evaluation of each
    deformation map serves all its patches.  ``compiled``: the caller runs
    compiled kernels anyway, so the map is evaluated in the compiled kernel
    however few the points (a V-model's face batches: a few hundred each).
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    P, N = len(patches), len(xT)
    chans = {c: np.broadcast_to(xT[:, 3 + i], (P, N)) for i, c in enumerate(patches[0].spline.channels)}
    if all(p.placement is None for p in patches):
        y = np.broadcast_to(xT[:, :3], (P, N, 3))
        Dy = [np.broadcast_to(dk[:, :3], (P, N, 3)) for dk in DT]
    else:
        A = np.stack([p.placement[:, :3] if p.placement is not None else np.eye(3) for p in patches])
        b = np.stack([p.placement[:, 3] if p.placement is not None else np.zeros(3) for p in patches])
        AT = np.ascontiguousarray(np.transpose(A, (0, 2, 1)))
        y = np.matmul(xT[:, :3], AT) + b[:, None, :]  # (P, N, 3): BLAS, not einsum
        Dy = [np.matmul(dk[:, :3], AT) for dk in DT]
    groups: dict = {}
    for i, p in enumerate(patches):
        groups.setdefault(same(p.outer), []).append(i)
    if len(groups) == 1 and patches[0].outer is None:
        return y, Dy, chans
    x = np.empty_like(y)
    Dx = [np.empty_like(d) for d in Dy]
    mapped: dict = {}  # the map's channels (they take precedence over equally named tile channels)
    for members in groups.values():
        D = patches[members[0]].outer
        if D is None:
            raise SplineError("patches that share a tile must all have a deformation map or none")
        dom = D.domain
        rows = slice(None) if len(members) == P else members  # one map for all: views, not copies
        yy = np.clip(y[rows].reshape(-1, 3), dom[:, 0], dom[:, 1])  # inside the domain: no second check
        vals, dD = D.value_and_derivatives(yy, checked=True, compiled=True if compiled else None, columns=3)
        x[rows] = vals[:, :3].reshape(len(members), N, 3)
        for k in range(len(Dy)):
            # dx/dxi_k = sum_j dD/dy_j (dy_j/dxi_k): three scaled columns, no (N, 3, 3) Jacobian formed
            dy = Dy[k][rows].reshape(-1, 3)
            Dx[k][rows] = (dD[0] * dy[:, 0:1] + dD[1] * dy[:, 1:2] + dD[2] * dy[:, 2:3]).reshape(len(members), N, 3)
        for i, c in enumerate(D.channels):
            mapped.setdefault(c, np.empty((P, N)))[rows] = vals[:, 3 + i].reshape(len(members), N)
    chans.update(mapped)
    return x, Dx, chans


def patches_geometry_derivs(patches, axes, compiled: bool = False, compiled_maps: bool = False):
    """Geometry of patches sharing one tile spline on one parameter grid.

    Returns x (P, N, 3), [dx/dxi_k (P, N, 3)] * 3 and channels {name: (P, N)}
    (tile channels broadcast, map channels per patch); the tile is evaluated
    once.  ``compiled``: see :func:`grid_values_derivs` (it implies ``compiled_maps``); ``compiled_maps``: the
    deformation maps are evaluated in the compiled kernel however few the points (a caller whose other, larger
    evaluations load it anyway: a sampled model's groups).
    """
    return _outer_map(patches, *grid_values_derivs(patches[0].spline, axes, compiled),
                      compiled=compiled or compiled_maps)


def patches_geometry_derivs_slabs(patches, axes, points_per_slab: int = 1 << 15, rows_multiple: int = 1,
                                  compiled: bool = False):
    """:func:`patches_geometry_derivs` in slabs of the first parameter axis.

    Yields (rows: slice of axis 0, x (P, n, 3), [dx/dxi_k (P, n, 3)] * 3,
    channels {name: (P, n)}); the slab's points are the flat grid points
    ``rows.start * rest : rows.stop * rest`` (rest = points per row).
    ``rows_multiple``, ``compiled``: see :func:`grid_values_derivs_slabs`.
    """
    per_patch = max(1, points_per_slab // len(patches))
    for rows, xT, DT in grid_values_derivs_slabs(patches[0].spline, axes, per_patch, rows_multiple, compiled):
        yield (rows, *_outer_map(patches, xT, DT, compiled))


def patch_geometry_derivs(patch, axes):
    """Geometry on a tensor grid of patch parameters: x (N, 3), [dx/dxi_k (N, 3)] * 3, channels."""
    x, Dx, chans = patches_geometry_derivs([patch], axes)
    return x[0], [d[0] for d in Dx], {c: v[0] for c, v in chans.items()}


def patch_geometry_grid(patch, axes):
    """Geometry on a tensor grid: x (N, 3), J (N, 3, 3), channels {name: (N,)}; N in C order."""
    x, Dx, chans = patch_geometry_derivs(patch, axes)
    return x, np.stack(Dx, axis=-1), chans


def patch_geometry_points(patch, params):
    """Geometry at scattered parameter points (N, 3): (x, J (N, 3, 3), channels)."""
    params = np.asarray(params, float)
    vals = patch.spline.evaluate(params)
    JT = patch.spline.jacobian(params)
    x, Dx, chans = _outer_map([patch], vals, [JT[:, :, k] for k in range(3)])
    return x[0], np.stack([d[0] for d in Dx], axis=-1), {c: v[0] for c, v in chans.items()}


def gradient_and_det(D, dxi):
    """Physical gradients and Jacobian determinants from parameter derivatives, without solving.

    D: [dx/du, dx/dv, dx/dw], each (M, 3) (any leading shape, flattened);
    dxi (M, 3) the derivatives dT/du, dT/dv, dT/dw of a field, or None for
    the determinants only.  With the rows
    c_1 = x_v x x_w, c_2 = x_w x x_u, c_3 = x_u x x_v of det J * J^-1,
    grad T = J^-T dT/dxi = sum_r c_r dT/dxi_r / det J.  Returns (grad (M, 3),
    det (M,)); where det J = 0 the gradient is not finite (the caller decides).
    """
    Du, Dv, Dw = (np.moveaxis(np.reshape(d, (-1, 3)), 1, 0) for d in D)  # (3, M) component-major
    c1, c2, c3 = _cross0(Dv, Dw), _cross0(Dw, Du), _cross0(Du, Dv)
    det = Du[0] * c1[0] + Du[1] * c1[1] + Du[2] * c1[2]
    if dxi is None:
        return None, det
    g = np.moveaxis(np.asarray(dxi).reshape(-1, 3), 1, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        grad = (c1 * g[0] + c2 * g[1] + c3 * g[2]) / det
    return np.ascontiguousarray(grad.T), det


def _cross0(a, b):
    """Cross product of (3, M) arrays along the first axis, written out (np.cross is slow on many vectors)."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
