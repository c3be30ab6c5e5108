"""The zero set of a sampled implicit field as one welded triangle mesh, vertices exact (shared by the implicit builders).

The field is sampled on a grid in D's parameter domain (uniform: VTK's flying
edges on ``ImageData``; rectilinear: VTK's contour filter on a
``RectilinearGrid``) and contoured at 0 in parameter space.  Each vertex lies
on a grid edge; :func:`snap` moves it along that edge onto the exact zero set
of the field (vectorised Illinois regula falsi), then it is mapped through D,
so pieces that share grid points share vertices and the mesh is one piece.
"""

from __future__ import annotations

import numpy as np

from .errors import TilingError

__all__ = ["zero_surface", "snap"]


def _uniform(axis) -> bool:
    d = np.diff(axis)
    return bool(np.allclose(d, d[0], rtol=1e-9, atol=0.0))


def zero_surface(axes, F, outer, field, *, close: bool = False, snap_vertices: bool = True, scale: float = 1.0,
                 point_data=None, stats: dict | None = None):
    """Contour F (shape of the axes) at 0, snap, map through ``outer``: a ``pyvista.PolyData``.

    ``field``: exact values (N,) at parameter points (N, 3); ``scale``: the
    field's magnitude (the snapping tolerance is 1e-12 of it); ``close``: a
    strongly negative layer outside the grid, so the surface follows D's
    boundary where F > 0; ``point_data``: optional callable params -> {name: (N,)}.
    Point data: D's channels, ``point_data``'s, and the parameters u, v, w.
    """
    import pyvista as pv

    axes = [np.asarray(a, float) for a in axes]
    if close:
        F = np.pad(F, 1, constant_values=-1e6 * max(1.0, float(np.abs(F).max())))
        axes = [np.concatenate([[a[0] - (a[1] - a[0])], a, [a[-1] + (a[-1] - a[-2])]]) for a in axes]
    if all(_uniform(a) for a in axes):
        grid = pv.ImageData(dimensions=F.shape, spacing=[a[1] - a[0] for a in axes], origin=[a[0] for a in axes])
        grid.point_data["f"] = F.ravel(order="F")
        surf = grid.contour([0.0], scalars="f", method="flying_edges")
    else:
        grid = pv.RectilinearGrid(*axes)
        grid.point_data["f"] = F.ravel(order="F")
        surf = grid.contour([0.0], scalars="f")
    if surf.n_points == 0:
        raise TilingError("the implicit structure has an empty zero set; raise alpha or connectivity, or use a "
                          "canonical tile whose field changes sign")
    dom = outer.domain
    params = np.asarray(surf.points, dtype=float)
    if snap_vertices:
        params, its = snap(params, axes, field, dom, 1e-12 * max(1.0, scale))
        if stats is not None:
            stats["snap_iterations"] = its
    params = np.clip(params, dom[:, 0], dom[:, 1])
    mapped = outer.evaluate(params, compiled=False)  # SciPy: one pass, no numba import (memory)
    out = pv.PolyData(mapped[:, :3], surf.faces)
    for i, c in enumerate(outer.channels):
        out.point_data[c] = mapped[:, 3 + i]
    for name, values in (point_data(params) if point_data is not None else {}).items():
        out.point_data[name] = values
    out.point_data["u"], out.point_data["v"], out.point_data["w"] = params.T
    return out


def snap(params, axes, f, dom, tol, iterations: int = 60):
    """Move contour vertices (N, 3) along their grid edges onto f = 0; returns (params, iterations).

    A vertex lies on a grid edge: two coordinates on grid lines, the third
    between two samples of opposite sign.  A vertex at a sample (VTK writes
    float32, so one within 1e-4 of a step) takes, of its up to six edges, the
    one with a sign change whose root is nearest.  Vertices on edges leaving
    D's domain (the closing layer) keep VTK's position.
    """
    n = len(params)
    t = np.stack([np.interp(params[:, k], axes[k], np.arange(len(axes[k]))) for k in range(3)], 1)  # index coords
    off = np.abs(t - np.round(t))
    ax = np.argmax(off, axis=1)  # the edge's direction: the coordinate off the grid lines
    at_sample = off.max(axis=1) < 1e-4
    off[np.arange(n), ax] = 0.0
    rows = np.flatnonzero(off.max(axis=1) < 1e-4)  # the other two on grid lines
    ax = ax[rows]
    idx = np.round(t[rows]).astype(int)
    lower = np.floor(t[rows, ax]).astype(int)
    near = np.flatnonzero(at_sample[rows])
    if len(near):
        g = np.stack([axes[k][idx[near, k]] for k in range(3)], 1)
        fg = f(np.clip(g, dom[:, 0], dom[:, 1]))
        best, pick = np.full(len(near), np.inf), np.zeros((len(near), 2), int)
        for k in range(3):
            for sgn in (-1, 1):
                j = idx[near, k] + sgn
                valid = (j >= 0) & (j < len(axes[k]))
                h = g.copy()
                h[:, k] = axes[k][np.clip(j, 0, len(axes[k]) - 1)]
                valid &= (h[:, k] >= dom[k, 0] - 1e-12) & (h[:, k] <= dom[k, 1] + 1e-12)
                fh = f(np.clip(h, dom[:, 0], dom[:, 1]))
                score = np.where(valid & (fg * fh < 0), np.abs(fg) / (np.abs(fg - fh) + 1e-300), np.inf)
                better = score < best
                best[better], pick[better] = score[better], (k, sgn)
        found = np.isfinite(best)
        ax[near] = np.where(found, pick[:, 0], ax[near])
        lower[near] = idx[near, ax[near]] - (found & (pick[:, 1] < 0))
    i = np.arange(len(rows))
    a = np.stack([axes[k][idx[:, k]] for k in range(3)], 1)  # the edge's ends: grid coordinates ...
    b = a.copy()
    for k in range(3):  # ... and the samples below and above along the edge
        m = ax == k
        lo = np.clip(lower[m], 0, len(axes[k]) - 2)
        a[i[m], k], b[i[m], k] = axes[k][lo], axes[k][lo + 1]
    keep = np.all((a >= dom[:, 0] - 1e-12) & (b <= dom[:, 1] + 1e-12), axis=1)
    rows, ax, a, b = rows[keep], ax[keep], a[keep], b[keep]
    fa, fb = f(a), f(b)
    ok = fa * fb < 0  # a sign change on the edge (else keep VTK's vertex)
    rows, a, b, fa, fb, ax = rows[ok], a[ok], b[ok], fa[ok], fb[ok], ax[ok]
    c = a.copy()
    side = np.zeros(len(rows), int)  # which end the last step replaced: +1 a, -1 b
    act = np.arange(len(rows))  # edges not converged yet
    its = 0
    while len(act) and its < iterations:
        its += 1
        j, axj = act, ax[act]
        s = fa[j] / (fa[j] - fb[j])  # the secant's root on the edge
        c[j, axj] = a[j, axj] + s * (b[j, axj] - a[j, axj])
        fc = f(c[j])
        done = np.abs(fc) < tol
        left = fc * fa[j] > 0  # the root lies between c and b: c replaces a
        fb[j[left & (side[j] == 1)]] *= 0.5  # Illinois: an end kept twice has its value halved
        fa[j[~left & (side[j] == -1)]] *= 0.5
        a[j[left]], fa[j[left]] = c[j[left]], fc[left]
        b[j[~left]], fb[j[~left]] = c[j[~left]], fc[~left]
        side[j] = np.where(left, 1, -1)
        act = j[~done]
    out = params.copy()
    out[rows] = c
    return out, its
