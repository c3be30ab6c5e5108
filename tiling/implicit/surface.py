"""The zero set of a sampled implicit field as one welded triangle mesh, vertices exact (shared by the implicit builders).

The field is sampled on a grid in D's parameter domain (uniform: VTK's flying
edges on ``ImageData``; rectilinear: VTK's contour filter on a
``RectilinearGrid``) and contoured at 0 in parameter space.  Each vertex lies
on a grid edge; :func:`snap` moves it along that edge onto the exact zero set
of the field (bracketed Newton on the polynomial pieces of the field's
restriction to the edge, :class:`EdgeSplines`, where the builder gives them;
vectorised Illinois regula falsi on the field otherwise), then it is mapped
through D, so pieces that share grid points share vertices and the mesh is
one piece.
"""

from __future__ import annotations

import numpy as np

from geometry.numbers import TINY
from geometry import knots as kn

from tiling.errors import TilingError
from tiling.export import mesh_watertightness, write_mesh
from tiling.implicit.render import render_png
from geometry.tolerances import ON_DOMAIN

__all__ = ["zero_surface", "snap", "EdgeSplines", "SurfaceOutputs"]


class SurfaceOutputs:
    """What an implicit structure with a ``surface(resolution)`` method offers: report, picture, files."""

    def watertightness(self, resolution: int | None = None) -> dict:
        """Closedness, components, Euler characteristic of the surface (:func:`tiling.export.mesh_watertightness`)."""
        return mesh_watertightness(self.surface(resolution))

    def render_png(self, path, **options):
        """Offscreen picture of the surface (and spanning trees, where any) (:func:`tiling.implicit.render.render_png`)."""
        return render_png(self, path, **options)

    def write(self, path, resolution: int | None = None):
        """Write the surface to ``.stl``, ``.obj``, ``.ply``, ``.vtp`` or ``.vtu`` (atomic; by suffix)."""
        return write_mesh(path, self.surface(resolution))


def _uniform(axis) -> bool:
    d = np.diff(axis)
    return bool(np.allclose(d, d[0], rtol=1e-9, atol=0.0))


def zero_surface(axes, F, outer, field, *, close: bool = False, snap_vertices: bool = True, scale: float = 1.0,
                 point_data=None, stats: dict | None = None, lines=None):
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
        params, its = snap(params, axes, field, dom, 1e-12 * max(1.0, scale), values=F, lines=lines)
        if stats is not None:
            stats["snap_iterations"] = its
    params = np.clip(params, dom[:, 0], dom[:, 1])
    mapped = outer.evaluate(params, compiled=False)  # SciPy: one pass, no numba import (memory)
    out = pv.PolyData(mapped[:, :3], surf.faces)
    if _turns_inside_out(outer):  # the contour's facets face out of F > 0 in parameter space; D with det J < 0
        out = out.flip_faces()    # (one sign everywhere: D is regular) turns them inside out in space
    for i, c in enumerate(outer.channels):
        out.point_data[c] = mapped[:, 3 + i]
    for name, values in (point_data(params) if point_data is not None else {}).items():
        out.point_data[name] = values
    out.point_data["u"], out.point_data["v"], out.point_data["w"] = params.T
    return out


def _turns_inside_out(outer) -> bool:
    """Whether the map ``outer`` reverses orientation (det J < 0; its sign is one everywhere, as paving refuses
    a singular map), read at the centre of its domain."""
    J = outer.jacobian(outer.domain.mean(axis=1)[None, :])[0, :3, :3]
    return bool(np.linalg.det(J) < 0)


def snap(params, axes, f, dom, tol, iterations: int = 60, values=None, lines=None):
    """Move contour vertices (N, 3) along their grid edges onto f = 0; returns (params, iterations).

    ``values``: f on the grid of ``axes`` when known (the sampled field): the
    edges' end values are then read, not evaluated.  ``lines``: (a, b, axis)
    -> :class:`EdgeSplines`: the iterations evaluate the field restricted to
    each edge (a univariate spline) instead of ``f``.

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

    def at(ix, pts):  # f at grid points: read from the samples, or evaluated
        if values is not None:
            return values[tuple(np.clip(ix[:, k], 0, values.shape[k] - 1) for k in range(3))]
        return f(np.clip(pts, dom[:, 0], dom[:, 1]))

    near = np.flatnonzero(at_sample[rows])
    if len(near):
        _edges_at_samples(near, idx, ax, lower, axes, dom, at)
    i = np.arange(len(rows))
    ia = idx.copy()  # the edge's ends: grid indices ...
    ia[i, ax] = np.clip(lower, 0, np.array([len(a) for a in axes])[ax] - 2)  # ... the sample below along the edge
    ib = ia.copy()
    ib[i, ax] += 1
    a = np.stack([axes[k][ia[:, k]] for k in range(3)], 1)
    b = np.stack([axes[k][ib[:, k]] for k in range(3)], 1)
    keep = np.all((a >= dom[:, 0] - ON_DOMAIN) & (b <= dom[:, 1] + ON_DOMAIN), axis=1)
    rows, ax, a, b, ia, ib = rows[keep], ax[keep], a[keep], b[keep], ia[keep], ib[keep]
    fa, fb = at(ia, a), at(ib, b)
    ok = fa * fb < 0  # a sign change on the edge (else keep VTK's vertex)
    rows, a, b, fa, fb, ax = rows[ok], a[ok], b[ok], fa[ok], fb[ok], ax[ok]
    if lines is not None:
        c, its = _bracketed_newton(a, b, fa, fb, ax, lines(a, b, ax), tol, iterations)
    else:
        c, its = _illinois(a, b, fa, fb, ax, lambda j, pts: f(pts), tol, iterations)
    out = params.copy()
    out[rows] = c
    return out, its


def _edges_at_samples(near, idx, ax, lower, axes, dom, at) -> None:
    """For the vertices ``near`` that sit at a grid sample: of their up to six edges, the one with a sign
    change whose (linear) root is nearest; ``ax`` and ``lower`` are updated in place."""
    g = np.stack([axes[k][idx[near, k]] for k in range(3)], 1)
    fg = at(idx[near], g)
    best, pick = np.full(len(near), np.inf), np.zeros((len(near), 2), int)
    for k in range(3):
        for sgn in (-1, 1):
            j = idx[near, k] + sgn
            valid = (j >= 0) & (j < len(axes[k]))
            h = g.copy()
            h[:, k] = axes[k][np.clip(j, 0, len(axes[k]) - 1)]
            valid &= (h[:, k] >= dom[k, 0] - ON_DOMAIN) & (h[:, k] <= dom[k, 1] + ON_DOMAIN)
            hi = idx[near].copy()
            hi[:, k] = np.clip(j, 0, len(axes[k]) - 1)
            fh = at(hi, h)
            score = np.where(valid & (fg * fh < 0), np.abs(fg) / (np.abs(fg - fh) + TINY), np.inf)
            better = score < best
            best[better], pick[better] = score[better], (k, sgn)
    found = np.isfinite(best)
    ax[near] = np.where(found, pick[:, 0], ax[near])
    lower[near] = idx[near, ax[near]] - (found & (pick[:, 1] < 0))


def _illinois(a, b, fa, fb, ax, f_edge, tol, iterations):
    """Roots of f on the edges [a, b] (along axis ``ax``, f of opposite signs at the ends) by the Illinois
    variant of regula falsi, all edges at once; returns (roots (N, 3), iterations used)."""
    c = a.copy()
    side = np.zeros(len(a), int)  # which end the last step replaced: +1 a, -1 b
    act = np.arange(len(a))  # edges not converged yet
    its = 0
    while len(act) and its < iterations:
        its += 1
        j, axj = act, ax[act]
        s = fa[j] / (fa[j] - fb[j])  # the secant's root on the edge
        c[j, axj] = a[j, axj] + s * (b[j, axj] - a[j, axj])
        fc = f_edge(j, c[j])
        done = np.abs(fc) < tol
        left = fc * fa[j] > 0  # the root lies between c and b: c replaces a
        fb[j[left & (side[j] == 1)]] *= 0.5  # Illinois: an end kept twice has its value halved
        fa[j[~left & (side[j] == -1)]] *= 0.5
        a[j[left]], fa[j[left]] = c[j[left]], fc[left]
        b[j[~left]], fb[j[~left]] = c[j[~left]], fc[~left]
        side[j] = np.where(left, 1, -1)
        act = j[~done]
    return c, its


def _bracketed_newton(a, b, fa, fb, ax, E, tol, iterations):
    """Roots of the edge splines E (:class:`EdgeSplines`) on the edges [a, b] (along axis ``ax``, f of opposite
    signs at the ends), all edges at once: each bracket first narrowed to the polynomial piece of its edge
    that holds a sign change (:meth:`EdgeSplines.bracket`), then Newton steps from the secant point, kept
    inside the shrinking bracket (a bisection where a step would leave it), the piece evaluated by de
    Casteljau's algorithm; returns (roots (N, 3), iterations used).  On the Fig. 16 ducks 9-10 rounds in
    all where the Illinois iteration (:func:`_illinois`) took 12, and far fewer edges open after the first
    rounds, so the open edges' data are kept compact (gathered once a round)."""
    i = np.arange(len(a))
    piece, lo, hi, flo, fhi = E.bracket(a[i, ax], b[i, ax], fa, fb)
    origin, width, bern = E.origin[i, piece], E.width[i, piece], E.bern[i, piece]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = flo / (flo - fhi)
    x = np.where(np.isfinite(s), lo + s * (hi - lo), lo)  # lo == hi: a root at a knot, found by bracket
    act, its, xa = i, 0, x
    while len(act) and its < iterations:
        its += 1
        fx, dfx = _de_casteljau(bern, (xa - origin) / width)
        dfx = dfx / width
        done = np.abs(fx) < tol
        left = fx * flo > 0  # the root lies between x and hi: x replaces lo
        lo, flo, hi = np.where(left, xa, lo), np.where(left, fx, flo), np.where(left, hi, xa)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = xa - fx / dfx
        inside = np.isfinite(step) & (step > lo) & (step < hi)
        x[act] = xa  # every open edge's current iterate (the converged ones keep theirs)
        keep = ~done
        act, xa = act[keep], np.where(inside, step, 0.5 * (lo + hi))[keep]
        lo, hi, flo, origin, width, bern = lo[keep], hi[keep], flo[keep], origin[keep], width[keep], bern[keep]
    x[act] = xa
    out = a.copy()
    out[i, ax] = x
    return out, its


def _de_casteljau(bern, tau):
    """Polynomials in Bernstein form ``bern`` (n, p + 1) at ``tau`` (n,) in [0, 1]: values and derivatives
    d/dtau (n,) (the derivative from the last level's two points)."""
    b, t = bern, tau[:, None]
    slope = None
    for r in range(bern.shape[1] - 1, 0, -1):
        if r == 1:
            slope = (bern.shape[1] - 1) * (b[:, 1] - b[:, 0])
        b = b[:, :-1] + t * (b[:, 1:] - b[:, :-1])
    return b[:, 0], (np.zeros(len(tau)) if slope is None else slope)


class EdgeSplines:
    """Scalar trivariates restricted to grid edges: each edge's restriction as its polynomial pieces, one per
    knot span it crosses, in Bernstein form.

    For n edges of at most m pieces: ``bern`` (n, m, p + 1) the Bernstein
    coefficients of each piece over its whole knot span, which starts at
    ``origin`` (n, m) and is ``width`` (n, m) long; ``breaks`` (n, m - 1) the
    knots inside each edge, where its pieces meet (+inf pads rows with fewer
    pieces).  A piece is its spline's Bezier extraction on the span
    (:func:`geometry.knots.extraction_operators`) contracted with the basis
    values of the two other directions: exact, and evaluating it is de
    Casteljau's algorithm over all edges at once, far cheaper than
    evaluating the trivariate again at every step.
    """

    def __init__(self, bern, origin, width, breaks):
        self.bern, self.origin, self.width, self.breaks = bern, origin, width, breaks
        self.p = bern.shape[2] - 1

    @classmethod
    def of(cls, spline, a, b, axis) -> "EdgeSplines":
        """The restrictions of the scalar ``spline`` to the edges from a (n, 3) to b along ``axis`` (n,)."""
        return cls.of_cells([spline], np.zeros(len(a), int), a, b, axis)

    @classmethod
    def of_cells(cls, splines, cell, a, b, axis) -> "EdgeSplines":
        """The restrictions of the scalar ``splines[cell[e]]`` to the edges e from a (n, 3) to b along ``axis``.

        Splines with the same degrees, coefficient shape and knots up to an
        affine map of each direction (the cells of a structure) are restricted
        together, in their unit cube: one gather per direction and kind
        instead of one per cell; the pieces' spans are mapped back.
        """
        kinds = {}
        for i in np.unique(cell):
            sp = splines[i]
            if len(set(sp.degrees)) != 1:
                raise TilingError(f"edge restrictions need equal degrees in all directions, got {sp.degrees}")
            kinds.setdefault((sp.degrees, sp.coefficients.shape), []).append(i)
        groups = []
        for same in kinds.values():  # then by the knots in the unit cube, all of a kind's splines at once
            K = np.array([np.concatenate(splines[i].knots) for i in same])
            bounds = np.cumsum([0] + [len(U) for U in splines[same[0]].knots])
            unit = np.concatenate([(K[:, u:v] - K[:, u:u + 1]) / (K[:, v - 1:v] - K[:, u:u + 1])
                                   for u, v in zip(bounds[:-1], bounds[1:])], axis=1)
            index = {}
            for i, row in zip(same, np.round(unit, 12)):
                index.setdefault(row.tobytes(), []).append(i)
            groups += index.values()
        parts = []
        slot = np.full(len(splines), -1)
        for members in groups:
            ref = splines[members[0]]
            unit = [(U - U[0]) / (U[-1] - U[0]) for U in ref.knots]
            G = np.stack([splines[i].coefficients[..., 0] for i in members])
            slot[members] = np.arange(len(members))
            ends = np.array([[[U[0], U[-1]] for U in splines[i].knots] for i in members])  # (m, 3, 2)
            mine = np.flatnonzero(np.isin(cell, members))
            ci = slot[cell[mine]]
            lo, size = ends[ci, :, 0], ends[ci, :, 1] - ends[ci, :, 0]
            an, bn = (a[mine] - lo) / size, (b[mine] - lo) / size
            chunk = 16384  # edges per gather: (edges, p + 1, p + 1, p + 1) coefficients, about 8 MB
            for k in range(3):
                along = np.flatnonzero(axis[mine] == k)
                for rows in np.array_split(along, max(1, -(-len(along) // chunk))):
                    if len(rows):
                        parts.append((mine[rows],) + cls._pieces(unit, ref.degrees, G, ci[rows], an[rows], bn[rows],
                                                                 k, lo[rows, k], size[rows, k]))
        return cls._stack(parts, len(a))

    @staticmethod
    def _pieces(knots, degrees, G, ci, a, b, k, lo, size):
        """The pieces of edges along direction k from a to b (unit coordinates) of the splines G[ci] (knots,
        degrees, unit cube), mapped back by ``lo + size * u``: (bern, origin, width, breaks), rows padded."""
        o = [j for j in range(3) if j != k]
        p, Uk = degrees[k], knots[k]
        vals = np.unique(Uk)  # the span ends
        ne = len(vals) - 1
        ext, first = kn.extraction_operators(Uk, p)
        ea = np.clip(np.searchsorted(vals, a[:, k], side="right") - 1, 0, ne - 1)
        eb = np.clip(np.searchsorted(vals, b[:, k], side="left") - 1, ea, ne - 1)  # an end on a knot: the left span
        m = eb - ea + 1
        n, M = len(ci), int(m.max())
        r = np.repeat(np.arange(n), m)  # one row per (edge, span crossed)
        j = np.arange(len(r)) - np.repeat(np.cumsum(m) - m, m)
        e = ea[r] + j
        (s1, v1), (s2, v2) = [kn.basis_functions(knots[d], degrees[d], a[:, d]) for d in o]
        q1, q2 = degrees[o[0]] + 1, degrees[o[1]] + 1
        # the splines' Bernstein coefficients along k, span by span: (C, ne, n_o1, n_o2, p + 1)
        Gk = np.moveaxis(G, k + 1, 1)
        bez = np.einsum("eij,cejab->ceabi", ext, Gk[:, first[:, None] + np.arange(p + 1)])
        # each piece's (p + 1, q1, q2) block is one window of them: gathered from a windowed view by one index
        # per axis, the four adjacent (a flat take through (rows, p + 1, q1, q2) index arrays measured 5x
        # slower, a slice between the indices 2x)
        view = np.lib.stride_tricks.sliding_window_view(bez, (q1, q2), axis=(2, 3))
        sub = view[ci[r], e, s1[r] - q1 + 1, s2[r] - q2 + 1].reshape(len(r), p + 1, q1 * q2)
        weights = (v1[:, 0, :, None] * v2[:, 0, None, :]).reshape(n, q1 * q2)
        bern = np.zeros((n, M, p + 1))
        bern[r, j] = np.einsum("nik,nk->ni", sub, weights[r])
        span = np.minimum(ea[:, None] + np.arange(M), ne - 1)
        origin = lo[:, None] + size[:, None] * vals[span]
        width = size[:, None] * (vals[span + 1] - vals[span])
        inner = np.arange(M - 1) < (m - 1)[:, None]
        breaks = np.where(inner, lo[:, None] + size[:, None] * vals[np.minimum(span[:, 1:], ne)], np.inf)
        return bern, origin, width, breaks

    @classmethod
    def _stack(cls, parts, n) -> "EdgeSplines":
        """One set from parts (rows (index array), bern, origin, width, breaks) covering n edges."""
        M = max(part[1].shape[1] for part in parts)
        p = parts[0][1].shape[2] - 1
        bern, origin = np.zeros((n, M, p + 1)), np.zeros((n, M))
        width, breaks = np.ones((n, M)), np.full((n, M - 1), np.inf)
        for rows, bb, oo, ww, kk in parts:
            if bb.shape[2] != p + 1:
                raise TilingError("edge restrictions need one degree for all edges")
            m = bb.shape[1]
            bern[rows, :m], origin[rows, :m], width[rows, :m], breaks[rows, :m - 1] = bb, oo, ww, kk
        return cls(bern, origin, width, breaks)

    def bracket(self, lo, hi, flo, fhi):
        """Each edge's bracket [lo, hi] (n,) with f of opposite signs ``flo``, ``fhi`` at its ends narrowed to
        one piece: the first piece with a sign change (f at the knots inside is read off the pieces' last
        Bernstein coefficients; a knot where f is 0 becomes a bracket of width 0 at its piece's right end).
        Returns (piece, lo, hi, flo, fhi), each (n,)."""
        n, m = self.breaks.shape
        if m == 0:
            return np.zeros(n, int), lo, hi, flo, fhi
        live = np.isfinite(self.breaks)
        pts = np.concatenate([lo[:, None], np.where(live, self.breaks, hi[:, None]), hi[:, None]], axis=1)
        val = np.concatenate([flo[:, None], np.where(live, self.bern[:, :-1, -1], fhi[:, None]), fhi[:, None]],
                             axis=1)
        q = np.argmax(val[:, :-1] * val[:, 1:] <= 0, axis=1)  # a sign change, or a zero at its right end
        at = np.arange(n)
        zero = val[at, q + 1] == 0
        return (q, np.where(zero, pts[at, q + 1], pts[at, q]), pts[at, q + 1],
                np.where(zero, 0.0, val[at, q]), val[at, q + 1])

    def __call__(self, rows, t, derivative: bool = False):
        """Values of edges ``rows`` at their coordinates ``t`` (de Casteljau on the piece holding t); with
        ``derivative``, the pair (values, derivatives along the edge)."""
        j = (self.breaks[rows] <= t[:, None]).sum(axis=1)
        w = self.width[rows, j]
        f, df = _de_casteljau(self.bern[rows, j], (t - self.origin[rows, j]) / w)
        return (f, df / w) if derivative else f
