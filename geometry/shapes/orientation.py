"""Consistent, outward orientation of the surfaces the toolkit returns and writes.

A surface assembled from pieces (surface patches in their own parameter
directions, trimmed caps, marching-cubes facets mapped through a map with
det J < 0) can list a shared edge in the same direction on both sides, and a
closed sheet can face inwards.  :func:`orient_outward` makes every connected
sheet consistent (VTK's ``vtkPolyDataNormals`` consistency pass) and then
turns each sheet so that its normals point out of the solid it bounds:

* a closed sheet (every edge used twice) that lies inside an odd number of
  other closed sheets bounds a cavity and gets a negative signed volume, any
  other closed sheet a positive one;
* an open sheet (a tube with open ends, a printed skin) gets a positive signed
  volume about its own centroid when that volume is clearly non-zero, and
  keeps its orientation when it is flat.

The sign decisions use a stated margin (:data:`FLAT`), so they do not rest on
the last bits of a sum.  :func:`orientation_check` measures what the tests
assert: directed edges used twice, and the signed volume.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.errors import SplineError

__all__ = ["orient_outward", "orientation_check", "OrientationCheck", "FLAT"]

FLAT = 1e-6
"""A sheet whose signed volume about its centroid is below ``FLAT`` times the cube of its bounding-box
diagonal counts as flat: its orientation is kept as built."""


@dataclass(frozen=True)
class OrientationCheck:
    """What makes a surface's orientation right or wrong.

    ``repeated_edges``: directed edges listed by two faces (0 when every sheet
    is consistently oriented); ``signed_volume``: the enclosed volume from the
    divergence theorem (model units cubed; positive for outward normals of a
    closed surface); ``sheets``: connected pieces.
    """

    repeated_edges: int
    signed_volume: float
    sheets: int


def _polys(mesh):
    """(offsets (n + 1,), connectivity) of the polygons of a ``pyvista.PolyData``."""
    cells = mesh.GetPolys()
    from vtk.util.numpy_support import vtk_to_numpy

    return (vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64),
            vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64))


def _fan(offsets, conn):
    """Triangles (T, 3) of a fan of every polygon and the polygon each belongs to (T,)."""
    sizes = np.diff(offsets)
    cell = np.repeat(np.arange(len(sizes)), np.maximum(sizes - 2, 0))
    k = np.arange(len(cell)) - np.repeat(np.cumsum(np.maximum(sizes - 2, 0)) - np.maximum(sizes - 2, 0),
                                         np.maximum(sizes - 2, 0))
    first = offsets[:-1][cell]
    return np.stack([conn[first], conn[first + k + 1], conn[first + k + 2]], 1), cell


def _edges(offsets, conn):
    """Directed edges (E, 2) of every polygon, each polygon's closing edge included."""
    sizes = np.diff(offsets)
    nxt = np.arange(len(conn)) + 1
    last = offsets[1:] - 1
    nxt[last[sizes > 0]] = offsets[:-1][sizes > 0]
    return np.stack([conn, conn[nxt]], 1)


def orientation_check(mesh) -> OrientationCheck:
    """Directed-edge and signed-volume facts of the polygons of ``mesh`` (a ``pyvista.PolyData``)."""
    from scipy.sparse.csgraph import connected_components

    offsets, conn = _polys(mesh)
    if len(offsets) < 2:
        return OrientationCheck(0, 0.0, 0)
    e = _edges(offsets, conn)
    _, uses = np.unique(e[:, 0] * np.int64(mesh.n_points) + e[:, 1], return_counts=True)
    tris, _ = _fan(offsets, conn)
    p = np.asarray(mesh.points, float)
    vol = float(np.einsum("ij,ij->i", p[tris[:, 0]], np.cross(p[tris[:, 1]], p[tris[:, 2]])).sum() / 6.0)
    n, _ = connected_components(_vertex_graph(e, mesh.n_points), directed=False)
    used = np.unique(conn)
    isolated = mesh.n_points - len(used)
    return OrientationCheck(int(np.sum(uses > 1)), vol, int(n - isolated))


def _vertex_graph(edges, n_points):
    from scipy.sparse import coo_matrix

    return coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_points, n_points))


def orient_outward(mesh):
    """``mesh`` (a ``pyvista.PolyData`` of polygons only: merge lines and vertices afterwards) with every sheet
    consistent and outward.

    Cells keep their order, points and data; only the order of the vertices of
    some polygons is reversed.  See the module docstring for the rule.  The nesting test runs once per closed
    sheet that contains another sheet's bounding box (a handful on the toolkit's surfaces).
    """
    import pyvista as pv
    from scipy.sparse.csgraph import connected_components

    offsets, conn = _polys(mesh)
    if len(offsets) < 2:
        return mesh
    if mesh.n_lines or mesh.n_verts:
        raise SplineError("orient_outward takes polygons only; merge lines and vertices afterwards")
    consistent = mesh.compute_normals(cell_normals=True, point_normals=False, split_vertices=False,
                                      consistent_normals=True, auto_orient_normals=False,
                                      non_manifold_traversal=True)
    offsets, conn = _polys(consistent)
    points = np.asarray(consistent.points, float)
    edges = _edges(offsets, conn)
    _, label = connected_components(_vertex_graph(edges, len(points)), directed=False)
    tris, owner = _fan(offsets, conn)
    sheet_of_cell = label[conn[offsets[:-1]]]
    sheets = np.unique(sheet_of_cell)
    sheet_of_tri = sheet_of_cell[owner]

    # closed sheets: every undirected edge used exactly twice
    und = np.sort(edges, axis=1)
    key, uses = np.unique(und[:, 0] * np.int64(len(points)) + und[:, 1], return_counts=True)
    open_edge_sheet = label[key[uses != 2] // len(points)]
    closed = np.ones(label.max() + 1, bool)
    closed[open_edge_sheet] = False

    lo = np.full((label.max() + 1, 3), np.inf)
    hi = np.full((label.max() + 1, 3), -np.inf)
    np.minimum.at(lo, label[conn], points[conn])
    np.maximum.at(hi, label[conn], points[conn])
    centre = 0.5 * (lo + hi)
    q = points[tris] - centre[sheet_of_tri][:, None, :]
    vol = np.bincount(sheet_of_tri, np.einsum("ij,ij->i", q[:, 0], np.cross(q[:, 1], q[:, 2])) / 6.0,
                      minlength=label.max() + 1)
    diag = np.linalg.norm(hi - lo, axis=1)
    decided = np.abs(vol) > FLAT * np.where(np.isfinite(diag), diag, 0.0) ** 3

    depth = _nesting_depth(points, offsets, conn, label, sheets[closed[sheets]], lo, hi)
    want = np.where(depth % 2 == 1, -1.0, 1.0)
    flip_sheet = decided & (np.sign(vol) != want)
    flip_cell = flip_sheet[sheet_of_cell]
    if not flip_cell.any():
        out = consistent
    else:
        sizes = np.diff(offsets)
        cell = np.repeat(np.arange(len(sizes)), sizes)
        idx = np.arange(len(conn))
        src = np.where(flip_cell[cell], offsets[1:][cell] - 1 - idx + offsets[:-1][cell], idx)
        new = conn[src]
        faces = np.insert(new, offsets[:-1], sizes)
        out = pv.PolyData(points, faces)
        for name in consistent.point_data.keys():
            out.point_data[name] = consistent.point_data[name]
        for name in consistent.cell_data.keys():
            out.cell_data[name] = consistent.cell_data[name]
    for arrays in (out.cell_data, out.point_data):
        if "Normals" in arrays and "Normals" not in (mesh.cell_data if arrays is out.cell_data else mesh.point_data):
            del arrays["Normals"]
    return out


def _nesting_depth(points, offsets, conn, label, closed_sheets, lo, hi):
    """For every sheet, how many closed sheets enclose it (tested at one of its vertices)."""
    import pyvista as pv

    depth = np.zeros(label.max() + 1, int)
    if len(closed_sheets) < 1:
        return depth
    first_vertex = np.full(label.max() + 1, -1)
    first_vertex[label[conn[::-1]]] = conn[::-1]  # one vertex of every sheet
    candidates = np.flatnonzero(first_vertex >= 0)
    cell_sheet = label[conn[offsets[:-1]]]
    for s in closed_sheets:
        inside_box = np.all((lo[candidates] >= lo[s]) & (hi[candidates] <= hi[s]), axis=1) & (candidates != s)
        others = candidates[inside_box]
        if not len(others):
            continue
        sub = _sheet_polydata(points, offsets, conn, cell_sheet == s)
        probe = pv.PolyData(points[first_vertex[others]])
        # ray casting (vtkSelectEnclosedPoints): independent of the sheet's own orientation
        enclosed = np.asarray(probe.select_interior_points(sub, method="cell_locator", check_surface=False)
                              ["selected_points"], bool)
        depth[others[enclosed]] += 1
    return depth


def _sheet_polydata(points, offsets, conn, keep):
    """The polygons ``keep`` (bool per polygon) as their own ``pyvista.PolyData`` (all points kept)."""
    import pyvista as pv

    sizes = np.diff(offsets)
    sel_sizes = sizes[keep]
    sel_conn = conn[np.repeat(keep, sizes)]
    starts = np.concatenate([[0], np.cumsum(sel_sizes)[:-1]])
    return pv.PolyData(points, np.insert(sel_conn, starts, sel_sizes))
