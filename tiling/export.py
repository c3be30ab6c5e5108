"""Surface export of micro-structures (VTU / OBJ / STL) and a watertightness report.

Surfaces are sampled exactly through the chain rule ``D(A T + b)`` (no need
to form the composed splines).  The boundary of every trivariate patch is
taken face by face after splitting the patch at its full-multiplicity
(discontinuity) knots, so the gaps of partial discontinuities are surfaces
too; faces glued by an interface are left out.  Surface and curve tiles are
exported as they are (curves as polylines, VTU only).
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
from itertools import product

from geometry.io import atomic_write
from geometry.faces import FACE_AXIS, FACE_NAMES

from .errors import TilingError
from .microstructure import Microstructure


def _map(P, params, spline=None):
    spline = P.spline if spline is None else spline
    y = spline.evaluate(params)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]
    return P.outer.evaluate(np.clip(y, P.outer.domain[:, 0], P.outer.domain[:, 1]))[:, :3]


def _pieces(U, p):
    """Sub-intervals of a knot vector between full-multiplicity (discontinuity) knots."""
    vals, mults = np.unique(U, return_counts=True)
    cuts = np.r_[vals[0], vals[1:-1][mults[1:-1] >= p + 1], vals[-1]]
    return np.stack([cuts[:-1], cuts[1:]], axis=1)


def _grid_tris(n1, n2, offset):
    i, j = np.meshgrid(np.arange(n1 - 1), np.arange(n2 - 1), indexing="ij")
    a = (i * n2 + j).ravel() + offset
    b, c, d = a + n2, a + n2 + 1, a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _trivariate_pieces(i, P, glued, t):
    """Boundary pieces of one trivariate: (points (n, n, 3) grids, corner keys) per element of every face.

    The patch is split at its discontinuity knots (one-sided evaluation on
    each side); outer faces glued by an interface are skipped.
    """
    s = P.spline
    out = []
    for box in product(*[_pieces(U, p) for U, p in zip(s.knots, s.degrees)]):
        box = np.array(box)
        sub = s.extract(box) if not np.allclose(box, s.domain) else s
        for f in FACE_NAMES:
            k, side = FACE_AXIS[f]
            if box[k, side] == s.domain[k, side] and (i, f) in glued:
                continue
            rest = [d for d in range(3) if d != k]
            b1, b2 = sub.breakpoints(rest[0]), sub.breakpoints(rest[1])
            for e1 in range(len(b1) - 1):
                for e2 in range(len(b2) - 1):
                    G = np.empty((len(t), len(t), 3))
                    G[..., k] = box[k, side]
                    G[..., rest[0]] = (b1[e1] + t * (b1[e1 + 1] - b1[e1]))[:, None]
                    G[..., rest[1]] = (b2[e2] + t * (b2[e2 + 1] - b2[e2]))[None, :]
                    out.append(_map(P, G.reshape(-1, 3), sub))
    return out


def boundary_mesh(ms: Microstructure, samples: int = 6, tol: float = 1e-8):
    """Triangulated free boundary: (points (N, 3), triangles (M, 3), patch id per triangle, curve polylines).

    Face pieces that coincide exactly with another piece (both sides of a
    discontinuity where they are still one material, or faces meeting without
    an interface record) are interior and left out.
    """
    glued = {itf.a for itf in ms.interfaces} | {itf.b for itf in ms.interfaces}
    t = np.linspace(0.0, 1.0, samples + 1)
    grids, owner, lines = [], [], []
    for i, P in enumerate(ms.patches):
        s = P.spline
        if s.dim == 1:
            lo, hi = s.domain[0]
            lines.append(_map(P, np.linspace(lo, hi, 8 * samples + 1)[:, None]))
        elif s.dim == 2:
            d = s.domain
            g = np.stack(np.meshgrid(d[0, 0] + t * (d[0, 1] - d[0, 0]), d[1, 0] + t * (d[1, 1] - d[1, 0]),
                                     indexing="ij"), -1)
            grids.append(_map(P, g.reshape(-1, 2)))
            owner.append(i)
        else:
            pieces = _trivariate_pieces(i, P, glued, t)
            grids += pieces
            owner += [i] * len(pieces)
    if not grids:
        return np.zeros((0, 3)), np.zeros((0, 3), int), np.zeros(0, int), lines
    # drop pieces that coincide with another piece (same sampled points as a set)
    scale = max(1.0, max(float(np.abs(g).max()) for g in grids))
    keys = [tuple(sorted(map(tuple, np.round(g[[0, len(t) - 1, -len(t), -1, len(g) // 2]] / (tol * scale)).astype(np.int64))))
            for g in grids]
    seen: dict = {}
    for j, kk in enumerate(keys):
        seen.setdefault(kk, []).append(j)
    keep = [j for j, kk in enumerate(keys) if len(seen[kk]) == 1]
    pts, tris, pid = [], [], []
    off = 0
    for j in keep:
        pts.append(grids[j])
        tris.append(_grid_tris(len(t), len(t), off))
        pid.append(np.full(len(tris[-1]), owner[j]))
        off += len(grids[j])
    return np.concatenate(pts), np.concatenate(tris), np.concatenate(pid), lines


def write_surfaces(path, ms: Microstructure, samples: int = 6) -> Path:
    """Write the free boundary surfaces to ``.vtu``, ``.obj`` or ``.stl`` (by suffix), atomically."""
    path = Path(path)
    fmt = {".vtu": "vtu", ".obj": "obj", ".stl": "stl"}.get(path.suffix.lower())
    if fmt is None:
        raise TilingError(f"cannot export {path.name}: use a .vtu, .obj or .stl file name")
    P, T, pid, lines = boundary_mesh(ms, samples)
    cells = [("triangle", T)] if len(T) else []
    cell_data = {}
    if fmt == "vtu":
        cell_data = {"patch": [pid]} if len(T) else {"patch": []}
        lp = []
        for ln in lines:
            base = len(P) + sum(len(x) for x in lp)
            lp.append(ln)
            cells.append(("line", np.stack([np.arange(len(ln) - 1), np.arange(1, len(ln))], 1) + base))
            cell_data["patch"].append(np.full(len(ln) - 1, -1))
        if lp:
            P = np.concatenate([P] + lp)
    if not cells:
        raise TilingError(f"nothing to export to {path.name}: the model has no surfaces" + (" (curves need .vtu)" if lines else ""))
    mesh = meshio.Mesh(P, cells, cell_data=cell_data)
    return atomic_write(path, lambda tmp: meshio.write(tmp, mesh, file_format=fmt), path.suffix, TilingError)


def watertightness(ms: Microstructure, samples: int = 6, tol: float = 1e-8) -> dict:
    """Weld the sampled free boundary and count edges used by one triangle (open) or more than two.

    Sampling-based (the exact statement is that interface faces coincide, which
    the Microstructure verifies): an unmatched triangle edge counts as closed
    when it runs along another unmatched edge within 1% of its length (the
    chordal deviation of a T-junction between finely and coarsely sampled
    curved faces).  Returns {"closed": bool, "open_edges": int, "nonmanifold_edges": int, "triangles": int}.
    A closed model (every free boundary meets another exactly) reports no open edges.
    """
    P, T, _, _ = boundary_mesh(ms, samples, tol)
    if not len(T):
        return {"closed": False, "open_edges": 0, "nonmanifold_edges": 0, "triangles": 0}
    scale = max(1.0, float(np.abs(P).max()))
    key = np.round(P / (tol * scale)).astype(np.int64)
    _, weld = np.unique(key, axis=0, return_inverse=True)
    T = weld.ravel()[T]
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])]  # drop collapsed triangles
    E = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(E, axis=0, return_counts=True)
    nonman = int(np.sum(counts > 2))
    single = uniq[counts == 1]
    # an unmatched edge still closes the surface when it runs along another unmatched edge
    # (a T-junction between a coarse and a finely sampled face, e.g. a parent fin top and its child)
    Pw = np.zeros((weld.max() + 1, 3))
    Pw[weld.ravel()] = P
    a, b = Pw[single[:, 0]], Pw[single[:, 1]]
    mid = 0.5 * (a + b)
    open_e = 0
    if len(single):
        from scipy.spatial import cKDTree

        L = np.linalg.norm(b - a, axis=1)
        tree = cKDTree(mid)
        for e, cand in enumerate(tree.query_ball_point(mid, r=L.max())):
            cand = np.array([c for c in cand if c != e])
            if not len(cand):
                open_e += 1
                continue
            d = b[cand] - a[cand]
            s = np.clip(np.einsum("ij,ij->i", mid[e] - a[cand], d) / np.einsum("ij,ij->i", d, d), 0, 1)
            dist = np.linalg.norm(a[cand] + s[:, None] * d - mid[e], axis=1)
            if dist.min() > max(tol * scale, 1e-2 * L[e]):  # chordal deviation of curved faces
                open_e += 1
    return {"closed": open_e == 0 and nonman == 0, "open_edges": int(open_e), "nonmanifold_edges": nonman,
            "triangles": int(len(T))}


def render_png(ms: Microstructure, path, samples: int = 6, color_by: str = "level", window=(1000, 800),
               camera: str = "iso") -> Path:
    """Offscreen pyvista render of the free boundary, coloured by ``level``, ``tile`` or ``patch``."""
    import pyvista as pv

    try:  # offscreen (EGL) rendering works without X; silence VTK's note about the missing X server
        pv.vtk_verbosity("off")
    except AttributeError:  # older pyvista
        pass
    P, T, pid, lines = boundary_mesh(ms, samples)
    if not len(T) and not lines:
        raise TilingError("nothing to render: the model has no surfaces or curves")
    attr = {"level": [p.level for p in ms.patches], "tile": [p.tile for p in ms.patches],
            "patch": list(range(len(ms.patches)))}
    if color_by not in attr:
        raise TilingError(f"color_by must be one of {sorted(attr)}, got {color_by!r}")
    pl = pv.Plotter(off_screen=True, window_size=list(window))
    if len(T):
        mesh = pv.PolyData(P, np.column_stack([np.full(len(T), 3), T]).ravel())
        mesh.cell_data[color_by] = np.asarray(attr[color_by])[pid]
        several = len(np.unique(mesh.cell_data[color_by])) > 1
        pl.add_mesh(mesh, scalars=color_by, cmap="viridis", show_edges=False, smooth_shading=True,
                    show_scalar_bar=several, scalar_bar_args={"title": color_by})
    for ln in lines:
        pl.add_mesh(pv.lines_from_points(ln).tube(radius=0.01 * float(np.ptp(ln, axis=0).max())), color="darkred")
    pl.camera_position = camera
    pl.set_background("white")
    try:
        return atomic_write(Path(path), lambda tmp: pl.screenshot(tmp), ".png", TilingError)
    finally:
        pl.close()
