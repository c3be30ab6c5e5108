"""Whether a micro-structure's boundary surface is closed, and where it is pinched by the tile's own geometry.

:func:`tiling.export.watertightness` reports, with VTK's feature-edge filter and
connectivity (:func:`mesh_watertightness`), the open edges (used by one triangle: a hole), the non-manifold
edges (used by more than two), the connected components and the Euler
characteristic of :func:`tiling.export.surface`.  A tile whose slots open
right from a free face (the skinned tile of Massarwi et al. 2018, Fig. 2) is
pinched along lines of that face by design: :func:`pinch_lines` finds and
names them, and the report separates the non-manifold edges on them from any
other (a defect).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from geometry.numbers import TINY
from geometry.faces import FACE_NAMES, face_name, parse_slot_face

if TYPE_CHECKING:
    from tiling.microstructure import Microstructure

__all__ = ["mesh_watertightness", "pinch_lines", "pinched"]


def pinched(mesh, ms: Microstructure, report: dict) -> dict:
    """The pinch part of a watertightness report of ``mesh`` (the surface of ``ms``): "pinch_lines"
    (:func:`pinch_lines`), "pinched_edges" (the non-manifold edges on them) and
    "unexplained_nonmanifold_edges" (the others: a defect), added to ``report`` (returned)."""
    lines = pinch_lines(ms)
    report["pinch_lines"] = lines
    report["pinched_edges"] = _on_lines(mesh, lines) if report["nonmanifold_edges"] else 0
    report["unexplained_nonmanifold_edges"] = report["nonmanifold_edges"] - report["pinched_edges"]
    return report


def pinch_lines(ms: Microstructure, n: int = 9) -> list[dict]:
    """The lines where a tile's two slot walls touch on the model's boundary (true geometry, not a defect).

    A partial discontinuity whose slot opens right from a free face of the
    patch (Massarwi et al. 2018, Fig. 2: the skinned tile's fins start at its
    base) has its two walls meet that face along a line: there four faces
    meet (both walls, the face on either side), so the boundary is closed but
    not a manifold along it.  For every free slot rectangle edge that lies on a
    free face of its patch, the two sides of the discontinuity are evaluated
    one-sidedly at ``n`` points along it; where they coincide the edge is a
    pinch line.  Returns [{"patch", "slot", "face", "points" (n, 3) in space}].
    """
    free = {f for f in ms.tags.get("boundary", []) if f[1] in FACE_NAMES}
    t = np.linspace(0.0, 1.0, n)
    out = []
    for (i, fid), rects in getattr(ms, "face_regions", {}).items():
        d, v, side = parse_slot_face(fid)
        if side > 0:  # one record per plane: the '-' side stands for both
            continue
        P = ms.patches[i]
        dom = P.spline.domain
        rest = [k for k in range(3) if k != d]
        for rect in rects:
            for m in (0, 1):
                for end in (0, 1):
                    at = rect[m][end]
                    face = face_name(rest[m], end)
                    if abs(at - dom[rest[m], end]) > 1e-12 * max(1.0, abs(at)) or (i, face) not in free:
                        continue
                    x = np.empty((n, 3))
                    x[:, d], x[:, rest[m]] = v, at
                    x[:, rest[1 - m]] = rect[1 - m][0] + t * (rect[1 - m][1] - rect[1 - m][0])
                    sides = [_one_sided(P, d, v, s_, x) for s_ in (-1, 1)]
                    size = max(float(np.ptp(sides[0], axis=0).max()), TINY)
                    if np.abs(sides[0] - sides[1]).max() <= 1e-9 * size:
                        out.append({"patch": int(i), "slot": fid[:-1], "face": face, "points": sides[0]})
    return out


def _one_sided(P, d: int, v: float, side: int, x: np.ndarray) -> np.ndarray:
    """Physical points of placed patch P at parameters x on the discontinuity plane (direction d, value v),
    evaluated on one side of it."""
    box = P.spline.domain.copy()
    box[d] = [box[d, 0], v] if side < 0 else [v, box[d, 1]]
    y = P.spline.extract(box).evaluate(x)[:, :3]
    if P.placement is not None:
        y = y @ P.placement[:, :3].T + P.placement[:, 3]
    if P.outer is not None:
        y = P.outer.evaluate(np.clip(y, P.outer.domain[:, 0], P.outer.domain[:, 1]))[:, :3]
    return y


def _on_lines(mesh, lines) -> int:
    """How many non-manifold edges of the triangles of ``mesh`` lie on the sampled ``lines``."""
    tris = mesh.extract_cells_by_type(5).extract_surface(algorithm="dataset_surface")
    nm = tris.extract_feature_edges(boundary_edges=False, non_manifold_edges=True, feature_edges=False,
                                    manifold_edges=False)
    if not nm.n_cells or not lines:
        return 0
    segs = nm.lines.reshape(-1, 3)[:, 1:]
    mid = 0.5 * (nm.points[segs[:, 0]] + nm.points[segs[:, 1]])
    dense = np.concatenate([_densify(ln["points"]) for ln in lines])
    spacing = max(float(np.linalg.norm(np.diff(_densify(ln["points"]), axis=0), axis=1).max()) for ln in lines)
    reach = np.linalg.norm(nm.points[segs[:, 0]] - nm.points[segs[:, 1]], axis=1)
    dist, _ = cKDTree(dense).query(mid)
    return int(np.sum(dist <= spacing + 0.05 * reach))


def _densify(points: np.ndarray, per: int = 16) -> np.ndarray:
    """The polyline ``points`` with ``per`` linear samples per segment."""
    t = np.linspace(0.0, 1.0, per, endpoint=False)[None, :, None]
    seg = points[:-1, None] + t * (points[1:, None] - points[:-1, None])
    return np.concatenate([seg.reshape(-1, 3), points[-1:]])


def mesh_watertightness(mesh) -> dict:
    """:func:`watertightness` of any welded ``pyvista.PolyData`` (its triangles)."""
    tris = mesh.extract_cells_by_type(5) if mesh.n_cells else mesh  # VTK_TRIANGLE
    tris = tris.extract_surface(algorithm="dataset_surface") if tris.n_cells else tris
    if not tris.n_cells:
        return {"closed": False, "manifold": True, "open_edges": 0, "nonmanifold_edges": 0, "components": 0,
                "euler_characteristic": 0, "triangles": 0}
    fe = tris.extract_feature_edges(boundary_edges=True, non_manifold_edges=False, feature_edges=False,
                                    manifold_edges=False)
    nm = tris.extract_feature_edges(boundary_edges=False, non_manifold_edges=True, feature_edges=False,
                                    manifold_edges=False)
    faces = tris.faces.reshape(-1, 4)[:, 1:]
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    V = len(np.unique(faces))
    components = int(tris.connectivity().cell_data["RegionId"].max()) + 1
    return {"closed": fe.n_cells == 0, "manifold": nm.n_cells == 0, "open_edges": int(fe.n_cells),
            "nonmanifold_edges": int(nm.n_cells), "components": components,
            "euler_characteristic": int(V - len(edges) + len(faces)), "triangles": int(len(faces))}
