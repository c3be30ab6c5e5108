"""The boundary surface of a micro-structure, its watertightness, and its export (VTU / OBJ / STL / PLY).

Trivariate patches are sampled on conforming grids and welded into one
volume mesh (:func:`geometry.patches.sampling.sampled_mesh`: matching sample points
on every interface, both sides of open discontinuity planes, coinciding
points merged); its boundary is extracted by VTK.  Surface tiles are sampled
on their own grids and curve tiles as polylines, through the exact chain rule
``D(A T + b)``.  Everything is welded into one ``pyvista.PolyData`` of
triangles (and lines) in physical space.

:func:`watertightness` (:mod:`tiling.sealing.watertight`, re-exported here) reports the
open and non-manifold edges, the components and the Euler characteristic of
that surface, and the pinch lines of a tile's own geometry.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geometry import Interface, MultiPatch, compose_many
from geometry.faces import FACE_AXIS, FACE_NAMES, face_name, parse_slot_face
from geometry.errors import SplineError
from geometry.io.iges import write_iges as _write_iges
from geometry.patches.placed_points import IDENTITY, placements
from geometry.shapes.orientation import orient_outward
from geometry.io.files import atomic_write
from geometry.patches.sampling import piece_boxes, sample_axes, sampled_mesh, weld

from .errors import TilingError
from tiling.sealing.rims import conforming_axes
from tiling.members.trimmed import composed_trimmed
from tiling.sealing.watertight import mesh_watertightness, pinch_lines, pinched

if TYPE_CHECKING:  # annotations only: the Microstructure's own surface() calls into this module
    from .microstructure import Microstructure
from geometry.errors import show
from geometry.grouping import ObjectIndex
from geometry.numbers import is_integer, is_real

__all__ = ["surface", "watertightness", "pinch_lines", "mesh_watertightness", "write_surfaces", "write_mesh",
           "drawn_patches",
           "boundary_splines", "continuous_pieces", "slot_surfaces", "write_iges",
           "samples_for_tolerance"]

_FORMATS = {".vtu": "vtu", ".obj": "obj", ".stl": "stl", ".ply": "ply", ".vtp": "vtp"}


def _map(P, params):
    """A placed patch at its parameters (N, d), in physical space."""
    return _place(P, P.spline.evaluate(params)[:, :3])


def _place(P, x):
    """Tile-space points (N, 3) of a placed patch in physical space: placement, then the map D."""
    A = IDENTITY if P.placement is None else P.placement
    y = x @ A[:, :3].T + A[:, 3]
    if P.outer is None:  # already in physical space (e.g. swept struts)
        return y
    return P.outer.evaluate(np.clip(y, P.outer.domain[:, 0], P.outer.domain[:, 1]))[:, :3]


def _grid_tris(n1, n2, offset):
    i, j = np.meshgrid(np.arange(n1 - 1), np.arange(n2 - 1), indexing="ij")
    a = (i * n2 + j).ravel() + offset
    b, c, d = a + n2, a + n2 + 1, a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def surface(ms: Microstructure, samples: int = 4):
    """The boundary of ``ms`` as one welded ``pyvista.PolyData`` (triangles, lines for curve tiles).

    Cell data ``patch`` and ``level``.  ``samples``: subdivisions of every
    element per direction (>= 1).
    """
    import pyvista as pv

    if not is_integer(samples) or samples < 1:
        raise TilingError(f"samples must be a positive integer, got {show(samples)}")
    tri = [i for i, P in enumerate(ms.patches) if P.spline.dim == 3]
    parts_pts, parts_tri, parts_pid = [], [], []
    if tri:
        keep = {i: j for j, i in enumerate(tri)}
        itfs = [Interface(itf.kind, (keep[itf.a[0]], itf.a[1]), (keep[itf.b[0]], itf.b[1]), itf.swap, itf.flip,
                          itf.box, itf.R) for itf in ms.interfaces if itf.a[0] in keep and itf.b[0] in keep]
        vol = sampled_mesh(MultiPatch([ms.patches[i] for i in tri], itfs), samples)
        surf = vol.extract_surface(algorithm="dataset_surface").triangulate()
        parts_pts.append(np.asarray(surf.points))
        parts_tri.append(surf.faces.reshape(-1, 4)[:, 1:])
        parts_pid.append(np.asarray(tri)[surf.cell_data["patch"]])
    lines = []
    off = sum(len(p) for p in parts_pts)
    axes = conforming_axes(ms.patches, samples)
    for i, P in enumerate(ms.patches):
        s = P.spline
        if s.dim == 2:
            ax = axes[i]
            g = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 2)
            parts_pts.append(_map(P, g))
            t = _grid_tris(len(ax[0]), len(ax[1]), off)
            parts_tri.append(t)
            parts_pid.append(np.full(len(t), i))
            off += len(g)
        elif s.dim == 1:
            lo, hi = s.domain[0]
            lines.append((i, _map(P, np.linspace(lo, hi, 8 * samples * len(s.breakpoints(0)))[:, None])))
    for pts, t, pid in _trimmed_parts(ms, samples):
        parts_pts.append(pts)
        parts_tri.append(t + off)
        parts_pid.append(np.full(len(t), pid))
        off += len(pts)
    if not parts_pts and not lines:
        raise TilingError("the micro-structure has no patches to draw")
    pts = np.concatenate(parts_pts) if parts_pts else np.zeros((0, 3))
    tris = np.concatenate(parts_tri) if parts_tri else np.zeros((0, 3), int)
    pid = np.concatenate(parts_pid) if parts_pid else np.zeros(0, int)
    pts, tris, _, _ = weld(pts, tris, {})  # surface tiles meet each other (and volume faces) at their edges
    # a collapsed edge (the pole of a sphere, the apex of a cone) welds into triangles with a repeated vertex
    proper = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
    tris, pid = tris[proper], pid[proper]
    mesh = pv.PolyData(pts, np.column_stack([np.full(len(tris), 3), tris]).ravel()) if len(tris) else pv.PolyData()
    if len(tris):
        mesh.cell_data["patch"] = pid
        mesh.cell_data["level"] = np.array([P.level for P in drawn_patches(ms)], np.int32)[pid]
        # surface patches run in their own parameter directions, caps and volume faces in theirs, and a map with
        # det J < 0 turns everything inside out: one consistent, outward orientation per sheet
        mesh = orient_outward(mesh)
    for i, ln in lines:
        poly = pv.lines_from_points(ln)
        poly.cell_data["patch"] = np.full(poly.n_cells, i)
        poly.cell_data["level"] = np.full(poly.n_cells, ms.patches[i].level, np.int32)
        mesh = mesh.merge(poly) if mesh.n_points else poly
    return mesh


def drawn_patches(ms) -> list:
    """What the ``patch`` numbers of :func:`surface` stand for: the placed patches, then the placed surfaces of
    the trimmed members (:class:`tiling.members.trimmed.PlacedTrimmed`)."""
    return list(ms.patches) + [m.placed for m in getattr(ms, "trimmed", [])]


def _trimmed_parts(ms, samples: int):
    """(physical points, triangles, patch number) of every trimmed cap (drawn with its tile's patch) and
    every trimmed member (numbered after the patches, :func:`drawn_patches`)."""
    for pc in getattr(ms, "caps", []):
        pts, t = _cap_triangles(ms, pc, samples)
        owner = next((lp[0][0] for lp in pc.cap.segments if lp), 0)  # drawn with a tile patch it closes
        yield pts, t, pc.first + owner
    yield from _trimmed_triangles(ms, samples)


def _trimmed_triangles(ms, samples: int) -> list:
    """(physical points, triangles, patch number per triangle) of the trimmed members of every placed tile.

    A tile's members are tessellated once in tile coordinates (chord tolerance 0.08 / samples^2 of the unit
    cell: a quarter circle of radius 0.25 gets about ``samples`` chords, as a patch's element does), their
    shared trimming curves stitched (:func:`geometry.shapes.stitch.stitch_boundaries`: each side takes the other's
    samples, so they weld), and the tile's mesh is mapped per placement; member j of the micro-structure's
    ``trimmed`` is drawn as patch ``len(ms.patches) + j``."""
    from geometry.grouping import ObjectIndex
    from geometry.shapes.stitch import stitch_boundaries

    tol = 0.08 / samples ** 2
    same = ObjectIndex()
    meshes: dict = {}
    placed: dict = {}  # placed tile -> [(member index in its tile, member index in ms.trimmed)]
    for j, m in enumerate(getattr(ms, "trimmed", [])):
        placed.setdefault(m.placed.tile, []).append((-1 - m.placed.patch_in_tile, j))
    out = []
    for t, members in placed.items():
        tile = ms.tiles[t]
        key = same(tile)
        if key not in meshes:
            pts, tris, part = [], [], []
            for i, T in enumerate(tile.trimmed):
                try:
                    tess = T.tessellate(tol)
                except SplineError as exc:
                    raise TilingError(f"trimmed member {i} of tile {show(tile.name)}: {exc}") from None
                tris.append(tess.faces.reshape(-1, 4)[:, 1:] + sum(len(x) for x in pts))
                pts.append(np.asarray(tess.points))
                part.append(np.full(tess.n_points, i))
            P, T3, part = stitch_boundaries(np.concatenate(pts), np.concatenate(tris), np.concatenate(part),
                                            1.01 * tol)
            meshes[key] = (P, T3, part[T3[:, 0]])
        P, T3, owner = meshes[key]
        number = np.full(len(tile.trimmed), -1)
        for i, j in members:
            number[i] = len(ms.patches) + j
        keep = number[owner] >= 0  # (every member of a placed tile is placed)
        first = ms.trimmed[members[0][1]].placed
        out.append((_place(first, P), T3[keep], number[owner[keep]]))
    return out


def _edge_params(s, edge: str, samples: int) -> np.ndarray:
    """The parameters of a surface patch's samples along one of its edges, as in its grid in :func:`surface`."""
    ax = sample_axes(s.knots, samples)
    k, side = divmod(("umin", "umax", "vmin", "vmax").index(edge), 2)
    fixed = np.full(len(ax[1 - k]), s.domain[k, side])
    return np.stack([fixed, ax[1 - k]] if k == 0 else [ax[1 - k], fixed], 1)


def _cap_triangles(ms: Microstructure, pc, samples: int):
    """Physical points and triangles of a trimmed cap whose loop points are its tile's edge samples."""
    from geometry.shapes.triangulate import fill_rings

    k, _ = FACE_AXIS[pc.cap.side]
    rest = [j for j in range(3) if j != k]
    plane = pc.cap.trimmed.surface
    level = float(plane.control_points[..., k].flat[0])  # the wall, or a shell's inner plane
    rings = []  # per ring: the tile points, exactly the tile patches' own edge samples
    for loop, curve in zip(pc.cap.segments, pc.cap.trimmed.loops):
        if loop is None:  # a cell rectangle (shells): 2 * samples points per side, as its neighbours take it
            t = np.linspace(*curve.domain[0], 2 * samples * (len(curve.breakpoints(0)) - 1) + 1)[:-1]
            rings.append(plane.evaluate(curve.evaluate(t[:, None])[:, :2])[:, :3])
            continue
        pts = []
        for patch, edge, rev in loop:
            x = ms.patches[pc.first + patch].spline.evaluate(_edge_params(ms.patches[pc.first + patch].spline,
                                                                          edge, samples))[:, :3]
            pts.append((x[::-1] if rev else x)[:-1])  # the last point starts the next curve
        rings.append(np.concatenate(pts))
    ring_len = max(float(np.linalg.norm(np.diff(np.vstack([r, r[:1]]), axis=0), axis=1).max()) for r in rings)
    uv, tris = fill_rings([r[:, rest] for r in rings], ring_len)
    X = np.zeros((len(uv), 3))
    X[:, k], X[:, rest] = level, uv
    n_ring = sum(len(r) for r in rings)
    X[:n_ring] = np.concatenate(rings)  # the ring points exactly as the tile's patches give them
    return _place(pc.placed, X), tris


def samples_for_tolerance(ms: Microstructure, tolerance: float, max_samples: int = 64) -> int:
    """The fewest subdivisions per element (1, 2, 4, ...) for which every boundary face's triangles are within
    ``tolerance`` (model units) of the exact surface, measured at the centres of the sub-cells."""
    if not (is_real(tolerance) and np.isfinite(tolerance) and tolerance > 0):
        raise TilingError(f"tolerance must be a positive length (model units), got {show(tolerance)}")
    composed = ms.compose_all()
    faces = [composed[i].boundary(f) for i, f in ms.tags.get("boundary", []) if f in FACE_NAMES]
    faces += [c for c, P in zip(composed, ms.patches) if P.spline.dim == 2]
    s = 1
    while True:
        worst = 0.0
        for F in faces:
            ax = sample_axes(F.knots, s)
            mid = [0.5 * (a[:-1] + a[1:]) for a in ax]
            grid = F.evaluate(np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 2))[:, :3]
            grid = grid.reshape(len(ax[0]), len(ax[1]), 3)
            centre = F.evaluate(np.stack(np.meshgrid(*mid, indexing="ij"), -1).reshape(-1, 2))[:, :3]
            bilinear = 0.25 * (grid[:-1, :-1] + grid[1:, :-1] + grid[:-1, 1:] + grid[1:, 1:]).reshape(-1, 3)
            worst = max(worst, float(np.linalg.norm(centre - bilinear, axis=1).max()))
        if worst <= tolerance:
            return s
        if 2 * s > max_samples:
            raise TilingError(f"the boundary needs more than {max_samples} subdivisions per element for tolerance "
                              f"{show(tolerance)} (measured {worst:.3g} at {s}); raise the tolerance")
        s *= 2


def write_surfaces(path, ms: Microstructure, samples: int = 4) -> Path:
    """Write the boundary surface to ``.vtu``, ``.vtp``, ``.obj``, ``.stl`` or ``.ply`` (by suffix), atomically."""
    return write_mesh(path, surface(ms, samples))


def write_mesh(path, mesh) -> Path:
    """Write a surface ``mesh`` to ``.vtu``, ``.vtp``, ``.obj``, ``.stl`` or ``.ply`` (by suffix), atomically."""
    path = Path(path)
    if path.suffix.lower() not in _FORMATS:
        raise TilingError(f"cannot export {path.name}: use a {', '.join(_FORMATS)} file name")
    if path.suffix.lower() in (".stl", ".obj", ".ply"):
        mesh = mesh.extract_cells_by_type(5).extract_surface(algorithm="dataset_surface")  # triangles only
        if not mesh.n_cells:
            raise TilingError(f"nothing to export to {path.name}: the model has no surfaces (curves need .vtu)")
    elif path.suffix.lower() == ".vtu":
        mesh = mesh.cast_to_unstructured_grid()
    suffix = path.suffix.lower()
    return atomic_write(path, lambda tmp: _save(mesh, tmp, suffix), suffix, TilingError)


def _save(mesh, tmp, suffix):
    # pyvista picks the writer by the file's suffix: write to a name with the right one, then move it
    target = str(tmp) + suffix
    mesh.save(target, binary=True)
    os.replace(target, tmp)


def boundary_splines(ms: Microstructure) -> list:
    """The exact, closed boundary of ``ms`` as continuous splines in physical space.

    Every free side of a trivariate patch, every slot face (the free
    rectangles of a discontinuity plane, each side from its own one-sided
    sub-patch), every surface patch, every curve patch, the trimmed caps and
    the tiles' trimmed members (``TrimmedSurface``, loops carried unaltered).
    A surface with a full-multiplicity (C^-1) knot is
    two surfaces that happen to share a knot vector; readers such as
    OpenCASCADE take it as one continuous surface and misread it, so such
    surfaces are split at those knots into pieces that are each continuous.
    Faces of trivariates are oriented outwards (``S_s x S_t`` along the outward
    normal), so the pieces bound the solid consistently.
    The faces are cut from the tile patches in tile space and composed into
    the map as surfaces (exact, and cheaper than composing whole trivariates),
    in one batch per tile patch, face and map.
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    jobs: dict = {}  # (tile spline, map, face key) -> [patch indices]; face key: a face name or (slot id, rect)
    for i, f in ms.tags.get("boundary", []):
        if f in FACE_NAMES:
            jobs.setdefault((same(ms.patches[i].spline), same(ms.patches[i].outer), f), []).append(i)
    for (i, fid), rects in getattr(ms, "face_regions", {}).items():
        for rect in rects:
            jobs.setdefault((same(ms.patches[i].spline), same(ms.patches[i].outer), (fid, tuple(map(tuple, rect)))),
                            []).append(i)
    out = []
    for (_, _, key), members in jobs.items():
        tile = ms.patches[members[0]].spline
        face = tile.boundary(key) if isinstance(key, str) else slot_surfaces(tile, key[0], [key[1]])[0]
        name = key if isinstance(key, str) else _slot_side_face(key[0])
        hand = _handedness(ms, members)
        for sign in (1, -1):  # outward normals: reverse the face where S_s x S_t points inwards
            group = [i for i, h in zip(members, hand) if h * _OUTWARD[name] == sign]
            for piece in (continuous_pieces(face) if group else []):
                out += _placed_surfaces(ms, group, piece if sign > 0 else piece.reverse(0))
    for i, P in enumerate(ms.patches):
        if P.spline.dim in (1, 2):
            out += [c for piece in continuous_pieces(P.spline) for c in _placed_surfaces(ms, [i], piece)]
    return out + [pc.composed() for pc in getattr(ms, "caps", [])] + composed_trimmed(getattr(ms, "trimmed", []))


#: sign of S_s x S_t against the outward normal for each face of a right-handed trivariate (boundary(face)
#: takes the two remaining directions in order: umin's (v, w) give x_v x x_w, along +u, so inwards)
_OUTWARD = {"umin": -1, "umax": 1, "vmin": 1, "vmax": -1, "wmin": -1, "wmax": 1}


def _slot_side_face(fid: str) -> str:
    """The face of the one-sided sub-patch that a slot face is: ``u=0.5-`` is the umax face of u <= 0.5."""
    d, _, side = parse_slot_face(fid)
    return face_name(d, 1 if side < 0 else 0)


def _handedness(ms, members) -> np.ndarray:
    """Sign of the physical Jacobian determinant of each placed patch (at its tile patch's centre)."""
    P0 = ms.patches[members[0]]
    c = P0.spline.domain.mean(axis=1)[None]
    JT = P0.spline.jacobian(c)[0, :3, :]
    A = placements(ms.patches, members)
    sign = np.sign(np.linalg.det(JT)) * np.sign(np.linalg.det(A[:, :, :3]))
    if P0.outer is not None:
        y = np.einsum("pij,j->pi", A[:, :, :3], P0.spline.evaluate(c)[0, :3]) + A[:, :, 3]
        dom = P0.outer.domain
        sign = sign * np.sign(np.linalg.det(P0.outer.jacobian(np.clip(y, dom[:, 0], dom[:, 1]))[:, :3, :]))
    return sign.astype(int)


def _placed_surfaces(ms, members, piece) -> list:
    """A tile-space curve or surface ``piece`` of the patches ``members``, placed and composed into their map."""
    first = ms.patches[members[0]]
    A = placements(ms.patches, members)
    if first.outer is None:
        return [piece.affine(a[:, :3], a[:, 3]) for a in A]
    return compose_many(first.outer, piece, A)


def continuous_pieces(spline) -> list:
    """``spline`` cut at its full-multiplicity (discontinuity) knots: exact sub-splines, each continuous."""
    boxes = piece_boxes(spline)
    if len(boxes) == 1:
        return [spline]
    return [spline.extract(box) for box in boxes]


def slot_surfaces(patch, fid: str, rects) -> list:
    """The free rectangles ``rects`` of the slot face ``fid`` of a (composed) trivariate, as exact surfaces.

    Each side of a discontinuity plane is evaluated on its own one-sided
    sub-patch, so the two walls of a slot are two surfaces.
    """
    d, v, side = parse_slot_face(fid)
    rest = [k for k in range(3) if k != d]
    out = []
    for (a1, b1), (a2, b2) in rects:
        box = patch.domain.copy()
        box[d] = (box[d, 0], v) if side < 0 else (v, box[d, 1])
        box[rest[0]], box[rest[1]] = (a1, b1), (a2, b2)
        out.append(patch.extract(box).boundary(_slot_side_face(fid)))
    return out


def write_iges(path, ms: Microstructure, units: str = "m") -> Path:
    """Write the exact boundary surfaces of ``ms`` (:func:`boundary_splines`) to IGES (entities 128, 126)."""
    splines = boundary_splines(ms)
    if not splines:
        raise TilingError(f"{ms.name or 'the micro-structure'} has no boundary surfaces to export")
    try:
        return _write_iges(path, splines, units=units, name=ms.name)
    except SplineError as exc:
        raise TilingError(str(exc)) from None



def watertightness(ms: Microstructure, samples: int = 4) -> dict:
    """Closedness of the boundary surface of ``ms`` (triangles only; :mod:`tiling.sealing.watertight`).

    Returns {"closed": no open edge, "manifold": no non-manifold edge,
    "open_edges", "nonmanifold_edges", "components", "euler_characteristic",
    "triangles"}, and the tile's own pinches: "pinch_lines" (:func:`pinch_lines`),
    "pinched_edges" (the non-manifold edges on them) and "unexplained_nonmanifold_edges"
    (the others: a defect).  A closed surface of one component has no holes; a
    non-manifold edge is a line where more than two faces meet.
    """
    mesh = surface(ms, samples)
    return pinched(mesh, ms, mesh_watertightness(mesh))
