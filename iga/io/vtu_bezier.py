"""Exact VTU export: one rational Bezier hexahedron (VTK cell type 79) per element.

The geometry of every patch is its exact image ``D(A T + b)`` (the composed
spline, :func:`geometry.compose_many`), cut into Bezier elements on the union of
its breakpoints and those of the temperature space; the temperature is
expressed in the same basis so ParaView interpolates it exactly:

* polynomial geometry: both are elevated to the larger degree per direction;
* rational geometry (weights w, denominator W): VTK interpolates point data
  with the rational basis w_i B_i / W, so the temperature's control values are
  ``(T W)_i / w_i`` at degree p_T + p_geo (exact Bernstein product).

Point data: ``temperature`` (with a solution) and every channel of the tile
and the deformation map (exact, as composed); cell data: ``patch``, ``tile``,
``level`` and ``HigherOrderDegrees``; ``RationalWeights`` for NURBS geometry.
Points are not shared between cells.  The point order inside a cell is
VTK's own (``vtkBezierHexahedron.PointIndexFromIJK``).  Heat flux is not
written here: -K J^-T grad T is a rational function of the geometry's
derivatives with the Jacobian determinant in its denominator, which no Bezier
cell's control values represent; the linear-hexahedron export samples it.
"""

from __future__ import annotations


import numpy as np

from geometry import bernstein as bz, compose_many
from geometry.composition.products import common_refinement

from iga.errors import ProblemError
from geometry.grouping import ObjectIndex


def _exact_geometries(model) -> list:
    """Every patch's exact geometry as one BSpline: ``D(A T + b)``, composed in batches per tile patch."""
    same = ObjectIndex()  # patches share splines and maps: group by object
    out = [None] * len(model.patches)
    groups: dict = {}
    for i, patch in enumerate(model.patches):
        if patch.outer is None:
            s = patch.spline
            out[i] = s if patch.placement is None else s.affine(patch.placement[:, :3], patch.placement[:, 3])
        else:
            groups.setdefault((same(patch.spline), same(patch.outer)), []).append(i)
    for members in groups.values():
        first = model.patches[members[0]]
        placements = np.stack([model.patches[i].placement if model.patches[i].placement is not None
                               else np.hstack([np.eye(3), np.zeros((3, 1))]) for i in members])
        for i, g in zip(members, compose_many(first.outer, first.spline, placements)):
            out[i] = g
    return out


def _vtk_order(degrees) -> np.ndarray:
    """Permutation: VTK point index -> flat (C-order) index of the (p1+1, p2+1, p3+1) control net."""
    from vtkmodules.vtkCommonDataModel import vtkBezierHexahedron  # (not ``import vtk``: every module, 0.7 s)

    p = [int(v) for v in degrees]
    n = [v + 1 for v in p]
    order = np.empty(n[0] * n[1] * n[2], np.int64)
    for i in range(n[0]):
        for j in range(n[1]):
            for k in range(n[2]):
                order[vtkBezierHexahedron.PointIndexFromIJK(i, j, k, p)] = (i * n[1] + j) * n[2] + k
    return order


def _solution_field(solution):
    """(name, patch -> spline) of the field a solution carries: the temperature or the displacement."""
    if solution is None:
        return None, None
    if hasattr(solution, "displacement_spline"):
        return "displacement", solution.displacement_spline
    return "temperature", solution.temperature_spline


def _field_values(th, gh, pg, rational: bool):
    """(elevated homogeneous geometry, field control values (E, ..., c)) on common Bezier degrees."""
    pt = np.array(th.shape[1:4]) - 1
    if rational:  # the field's values carried with the rational basis w_i B_i / W: multiply by W, then divide
        W = np.moveaxis(gh[..., -1:], -1, 1)
        tw = np.concatenate([bz.multiply(np.moveaxis(th[..., c:c + 1], -1, 1), W, 3) for c in range(th.shape[-1])], 1)
        gh = np.moveaxis(bz.elevate(np.moveaxis(gh, -1, 1), list(pt), 3), 1, -1)
        return gh, np.moveaxis(tw, 1, -1) / gh[..., -1:]
    target = np.maximum(pg, pt)
    gh = np.moveaxis(bz.elevate(np.moveaxis(gh, -1, 1), list(target - pg), 3), 1, -1)
    return gh, np.moveaxis(bz.elevate(np.moveaxis(th, -1, 1), list(target - pt), 3), 1, -1)


def _nurbs_field_values(th, gh, pg):
    """(elevated homogeneous geometry, field control values) of a NURBS field with the geometry's own weight
    function: its numerator T W (``th[..., :-1]``, degree p_T) and the geometry (degree p_g) elevated to their
    common degrees; VTK's rational basis w_i B_i / W then carries control values numerator_i / w_i."""
    pt = np.array(th.shape[1:4]) - 1
    target = np.maximum(pg, pt)
    gh = np.moveaxis(bz.elevate(np.moveaxis(gh, -1, 1), list(target - pg), 3), 1, -1)
    num = np.moveaxis(bz.elevate(np.moveaxis(th[..., :-1], -1, 1), list(target - pt), 3), 1, -1)
    return gh, num / gh[..., -1:]


def bezier_cells(solution, model):
    """Per-patch Bezier cells: list of dicts with points, weights, degrees, point fields and ids."""
    out = []
    name, field_of = _solution_field(solution)
    for pi, (patch, G) in enumerate(zip(model.patches, _exact_geometries(model))):
        T = field_of(pi) if field_of is not None else None
        breaks = [np.union1d(G.breakpoints(k), T.breakpoints(k) if T is not None else []) for k in range(3)]
        G = common_refinement(G, breaks)
        gh, _ = G.bezier_patches(homogeneous=True)  # (e1, e2, e3, q1+1, q2+1, q3+1, m+1)
        ne = gh.shape[:3]
        gh = gh.reshape((-1,) + gh.shape[3:])
        pg = np.array(gh.shape[1:4]) - 1
        fields = {}
        if T is not None:
            # a NURBS field (the geometry's own weights, iga.discretisation.rational) as its homogeneous numerator; else
            # polynomial, one or three components
            th, _ = common_refinement(T, breaks).bezier_patches(homogeneous=T.is_rational)
            th = th.reshape((-1,) + th.shape[3:])
            gh, tvals = _nurbs_field_values(th, gh, pg) if T.is_rational else _field_values(th, gh, pg, G.is_rational)
            fields[name] = tvals[..., 0] if tvals.shape[-1] == 1 else tvals
        if G.is_rational:
            w = gh[..., -1]
            cart = gh[..., :-1] / w[..., None]
        else:
            w, cart = None, gh
        for i, c in enumerate(G.channels):
            fields[c] = cart[..., 3 + i]
        out.append({"patch": pi, "tile": patch.tile, "level": patch.level, "points": cart[..., :3],
                    "weights": w, "fields": fields, "n_elements": int(np.prod(ne))})
    return out


def bezier_grid(solution, model):
    """The exact Bezier-hexahedron grid (a ``pyvista.UnstructuredGrid``, see the module notes)."""
    import pyvista as pv

    cells = bezier_cells(solution, model)
    pts, conn, types, degs, wts, ids = [], [], [], [], [], {"patch": [], "tile": [], "level": []}
    fields: dict = {}
    names = sorted({k for c in cells for k in c["fields"]})
    rational = any(c["weights"] is not None for c in cells)
    offset = 0
    for c in cells:
        P = c["points"]  # (E, q1+1, q2+1, q3+1, 3)
        E = P.shape[0]
        q = np.array(P.shape[1:4]) - 1
        order = _vtk_order(q)
        npc = len(order)
        flat = P.reshape(E, npc, 3)[:, order]
        pts.append(flat.reshape(-1, 3))
        idx = offset + np.arange(E * npc).reshape(E, npc)
        conn.append(np.hstack([np.full((E, 1), npc), idx]).ravel())
        types.append(np.full(E, 79, np.uint8))  # VTK_BEZIER_HEXAHEDRON
        degs.append(np.tile(q, (E, 1)))
        w = c["weights"] if c["weights"] is not None else np.ones(P.shape[:4])
        wts.append(w.reshape(E, npc)[:, order].ravel())
        for name in names:
            v = c["fields"].get(name)
            v = np.full(P.shape[:4], np.nan) if v is None else v
            flat_v = v.reshape(E, npc, -1)[:, order]
            fields.setdefault(name, []).append(flat_v.reshape(-1) if flat_v.shape[-1] == 1 else flat_v.reshape(-1, 3))
        for key in ids:
            ids[key].append(np.full(E, c[key], np.int32))
        offset += E * npc
    grid = pv.UnstructuredGrid(np.concatenate(conn), np.concatenate(types), np.concatenate(pts))
    for name, v in fields.items():
        grid.point_data[name] = np.concatenate(v)
    for key, v in ids.items():
        grid.cell_data[key] = np.concatenate(v)
    grid.cell_data["HigherOrderDegrees"] = np.concatenate(degs).astype(np.float64)
    grid.GetCellData().SetHigherOrderDegrees(grid.GetCellData().GetArray("HigherOrderDegrees"))
    if rational:
        grid.point_data["RationalWeights"] = np.concatenate(wts)
        grid.GetPointData().SetRationalWeights(grid.GetPointData().GetArray("RationalWeights"))
    if not grid.n_cells:
        raise ProblemError("the model has no trivariate patches to write")
    return grid
