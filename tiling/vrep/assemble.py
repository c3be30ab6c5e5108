"""The kept tiles of every positive primitive of a V-model as one :class:`tiling.Microstructure`.

Each positive primitive is paved regularly (:func:`tiling.paving.regular_placements`: the placements only,
the interfaces are searched once for the whole model), classified
(:func:`tiling.vrep.classify`), and its inside and to-be-bridged tiles are
kept.  Anchoring faces are bridged (Hong and Elber 2021): to the trimming surface
(:mod:`tiling.vrep.bridges`, Sections 3.2-3.3) or, where the way out enters
another primitive's territory in a union, to that primitive's boundary tile
faces (:mod:`tiling.vrep.union`, Sections 3.4-3.6).  Patches keep their own
map (the primitive's; union bridges their own geometry), interfaces are found
in physical space, and the tags name the primitive (``"A"``: every free face
of A's kept patches), its map's sides (``"A:umin"`` .. ``"A:wmax"``: where
boundary conditions go), the anchoring faces (``"anchor"``, ``"anchor:A"``)
and the free faces of the bridges (``"bridge"``, ``"bridge:A"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import progress
from geometry.primitives import box
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.multipatch import face_points, tile_corners

from ..errors import TilingError
from ..microstructure import Microstructure, PlacedPatch
from ..paving import regular_placements
from ..tile import Tile
from .bridges import build_bridges, resolve_collisions
from .classify import Classification, classify
from .model import VModel
from .tubes import is_regular
from .union import boundary_faces, bridge_union, shared_faces, union_anchors
from geometry.grouping import ObjectIndex
from geometry.tolerances import COINCIDENT, ON_DOMAIN

__all__ = ["VResult", "vrep_microstructure"]


@dataclass
class VResult:
    """The V-model's micro-structure, the classification of every positive primitive, and timings (s)."""

    microstructure: Microstructure
    classifications: list
    timings: dict
    bridges: dict = None  # counts: anchoring faces, bridges, dropped, collisions, swapped, repelled, eliminated
    bridge_objects: list = None  # the kept :class:`tiling.vrep.bridges.Bridge` objects, in patch order
    unions: list = None  # :class:`tiling.vrep.union.UnionBridges` per matched pair of primitives

    def counts(self) -> dict:
        """Tiles per state, per primitive name."""
        return {c.primitive.name: c.counts() for c in self.classifications}


def vrep_microstructure(model: VModel, samples: int = 4, margin: float = 0.0, name: str = "vrep",
                        bridges: bool = True, beta: float = 0.5, d_maxdist: float | None = None, phi: float = 0.0,
                        alpha: float = np.pi / 4) -> VResult:
    """Classify and keep the tiles of every positive primitive of ``model``, and with ``bridges`` connect their
    anchoring faces: to the trimming surfaces by one-to-one bridging tiles (:mod:`tiling.vrep.bridges`; bend
    parameter ``beta`` in (0, 1)) whose collisions are resolved, and, where the surface is shared with another
    primitive of a union, to that primitive's boundary tile faces by matched one-to-one tubes and two-to-one
    bifurcation bridges (:mod:`tiling.vrep.union`; ``d_maxdist`` the longest match in model units, default four
    face widths; ``phi`` in [0, 1] blends the end directions from the tiles' cross derivatives to the face
    normals; ``alpha`` in (0, pi/2) the angle between the bifurcation base's bottom and sides)."""
    import time

    if not isinstance(model, VModel):
        raise TilingError(f"vrep_microstructure needs a V-model (primitives combined by |, -, &), got {show(model)}")
    if not (isinstance(samples, (int, np.integer)) and samples >= 2):
        raise TilingError(f"samples must be an integer >= 2 per direction, got {show(samples)}")
    if not (isinstance(margin, (int, float)) and np.isfinite(margin) and margin >= 0):
        raise TilingError(f"margin must be a length >= 0 (model units), got {show(margin)}")
    _check_union_parameters(d_maxdist, phi, alpha)
    names = [p.name for p in model.primitives()]
    if len(set(names)) != len(names):
        raise TilingError(f"primitive names must be distinct (they become tags), got {names}")
    t0 = time.perf_counter()
    model.check()
    timings = {"checks": time.perf_counter() - t0}
    placed, tiles, classes, tags = [], [], [], {}
    for prim in progress.bar(model.positive(), desc="V-model primitives", unit="primitive"):
        t0 = time.perf_counter()
        cls = classify(model, prim, samples, margin)
        t1 = time.perf_counter()
        classes.append(cls)
        if not len(cls.kept):  # nothing of this primitive stays (e.g. a lower priority inside an intersection)
            timings[f"classify {prim.name}"] = t1 - t0
            continue
        paved, paved_tiles = regular_placements(prim.D, prim.tile, prim.counts)[:2]
        timings[f"classify {prim.name}"], timings[f"pave {prim.name}"] = t1 - t0, time.perf_counter() - t1
        keep = set(cls.kept.tolist())
        anchors = {}
        for tile, face in cls.anchors:
            anchors.setdefault(tile, []).append(face)
        tile_map, first = {}, len(placed)
        for P in paved:
            if P.tile not in keep:
                continue
            if P.tile not in tile_map:
                tile_map[P.tile] = len(tiles)
                tiles.append(paved_tiles[P.tile])
            placed.append(PlacedPatch(P.spline, P.placement, P.outer, tile_map[P.tile], P.level, P.patch_in_tile))
        tags[prim.name] = (first, len(placed), _anchor_faces(placed[first:], first, cls, anchors, tile_map))
        if bridges and cls.anchors and not tags[prim.name][2]:
            raise TilingError(f"primitive {show(prim.name)}: its tile {show(prim.tile.name)} has no patch face on the "
                              f"cell walls, so its {len(cls.anchors)} anchoring faces have nothing to bridge from; use "
                              "a tile whose patches reach the cell faces, or bridges=False")
    report = {}
    made, union = [], []
    if bridges:
        t0 = time.perf_counter()
        by_name = {p.name: p for p in model.positive()}
        for cls in classes:
            prim = cls.primitive
            if prim.name not in tags or not tags[prim.name][2]:
                continue
            anchors = tags[prim.name][2]
            partners, rest = union_anchors(model, prim, placed, anchors, _reach(placed, anchors, margin))
            for pname, faces in partners.items():
                p = by_name[pname]
                a, b, _ = tags[pname] if pname in tags else (0, 0, None)
                shared = shared_faces(model, prim, placed, boundary_faces(p, placed, a, b))
                if shared:
                    union.append((prim, p, faces, shared))
                else:  # nothing of the other primitive to meet here: bridge to the surface (Section 3.2)
                    rest += faces
                    report["union anchors bridged to the surface"] = report.get(
                        "union anchors bridged to the surface", 0) + len(faces)
            got, rep = build_bridges(model, prim, cls, placed, rest, beta)
            got = _unfold(model, prim, cls, placed, got, beta)
            made += [(prim.name, b) for b in got]
            for key, v in rep.items():
                report[key] = report.get(key, 0) + v
        kept, counts = resolve_collisions([b for _, b in made])
        folded = [b for b in kept if not _valid(b)]  # a heat model takes regular patches only
        kept = [b for b in kept if all(b is not f for f in folded)]
        counts["eliminated (folded)"] = len(folded)
        report.update(counts)
        report["bridges"] = report["surface bridges"] = len(kept)
        same = ObjectIndex()
        alive = {same(b) for b in kept}
        made = [(n, b) for n, b in made if same(b) in alive]
        timings["bridges"] = time.perf_counter() - t0
    bridge_first = len(placed)
    bridge_tile = None
    for _, b in made:
        if bridge_tile is None:  # one tile entry stands for all bridges (each is its own spline, in map parameters)
            bridge_tile = len(tiles)
            tiles.append(Tile([box()], name="one-to-one bridge"))
        placed.append(PlacedPatch(b.spline, np.hstack([np.eye(3), np.zeros((3, 1))]), b.D, bridge_tile, 0, 0))
    owner = {bridge_first + j: pname for j, (pname, _) in enumerate(made)}
    unions = []
    if union:
        t0 = time.perf_counter()
        union_tile = len(tiles)
        tiles.append(Tile([box()], name="union bridge"))
        for q, p, faces, shared in union:
            ub = bridge_union(model, q, p, placed, faces, shared, union_tile, d_maxdist, beta, phi, alpha)
            owner.update({len(placed) + j: q.name for j in range(len(ub.patches))})
            placed += ub.patches
            unions.append(ub)
            for key, v in ub.counts.items():
                key = key if key.startswith("faces of") else f"union {key}"
                report[key] = report.get(key, 0) + v
        report["bridges"] = report.get("bridges", 0) + sum(len(u.patches) for u in unions)
        timings["union bridges"] = time.perf_counter() - t0
    if not placed:
        if _is_empty(model):
            raise TilingError(f"the V-model ({model.op} of {', '.join(_names(model))}) is empty: its Boolean "
                              "expression leaves no volume (no sample point of its primitives lies inside it), so "
                              "there is nothing to pave; check the expression (e.g. A - A)")
        raise TilingError("no tile of the V-model is inside it: every tile is outside or crosses a trimming "
                          "surface; use smaller tiles (higher counts)")
    t0 = time.perf_counter()
    out = Microstructure.build(model.positive()[0].D, placed, tiles, [], name=name)
    for tag in FACE_NAMES:
        out.tags[tag] = []  # the faces of one map's domain mean nothing across primitives
    out.tags["internal"] = list(out.tags["boundary"])  # so every free face is "elsewhere" (DESIGN, section 4)
    out.tags["anchor"] = []
    out.tags["bridge"] = [f for f in out.tags["boundary"] if f[0] >= bridge_first]
    for pname in tags:
        out.tags[f"bridge:{pname}"] = []
    for f in out.tags["bridge"]:
        out.tags[f"bridge:{owner[f[0]]}"].append(f)
    for pname, (a, b, anchor_faces) in tags.items():
        out.tags[pname] = [f for f in out.tags["boundary"] if a <= f[0] < b]
        out.tags[f"anchor:{pname}"] = list(anchor_faces)  # glued to their bridges when bridges are built
        out.tags["anchor"] += out.tags[f"anchor:{pname}"]
    _side_tags(out, model, tags)
    timings["build"] = time.perf_counter() - t0
    return VResult(out, classes, timings, report, [b for _, b in made], unions)


def _anchor_faces(placed, offset: int, cls: Classification, anchors: dict, tile_map: dict) -> list:
    """(patch, face) of the kept patches lying on an anchoring cell face of their tile."""
    by_tile = {tile_map[t]: (cls.cells[t], faces) for t, faces in anchors.items()}
    out = []
    for j, P in enumerate(placed):
        if P.tile not in by_tile:
            continue
        box, faces = by_tile[P.tile]
        net = P.spline.points @ P.placement[:, :3].T + P.placement[:, 3]  # the control net in the map's domain
        sides = {f: np.take(net, -1 if FACE_AXIS[f][1] else 0, axis=FACE_AXIS[f][0]).reshape(-1, 3)
                 for f in FACE_NAMES}
        tol = COINCIDENT * max(float(np.ptp(box, axis=1).max()), 1e-300) + ON_DOMAIN
        for cell_face in faces:
            k, s = FACE_AXIS[cell_face]
            out += [(offset + j, f) for f, pts in sides.items() if np.abs(pts[:, k] - box[k, s]).max() < tol]
    return out


def _check_union_parameters(d_maxdist, phi, alpha) -> None:
    if d_maxdist is not None and not (isinstance(d_maxdist, (int, float)) and np.isfinite(d_maxdist) and d_maxdist > 0):
        raise TilingError(f"d_maxdist must be a positive length (model units) or None, got {show(d_maxdist)}")
    if not (isinstance(phi, (int, float)) and 0.0 <= phi <= 1.0):
        raise TilingError(f"phi blends the cross derivative (0) with the face normal (1): give a number in [0, 1], "
                          f"got {show(phi)}")
    if not (isinstance(alpha, (int, float)) and 0 < alpha < np.pi / 2):
        raise TilingError(f"alpha, the bifurcation base's side angle, must lie in (0, pi/2) radians, got "
                          f"{show(alpha)}")


def _reach(placed, anchors, margin: float) -> float:
    """How far (model units) a union anchor may look for the other side: three face widths plus the margin."""
    pts = face_points(placed, anchors[:1], np.array([[0.0, 0.0], [1.0, 1.0]]))[0]
    width = float(np.linalg.norm(pts[1] - pts[0]))
    return 6.0 * width + margin


def _side_tags(out, model, tags) -> None:
    """``"<primitive>:<side>"``: the free faces of a primitive's patches on a side (umin .. wmax) of its map's
    domain (e.g. where a heat problem puts its boundary conditions)."""
    free = set(out.tags["boundary"])
    for prim in model.positive():
        if prim.name not in tags:
            continue
        a, b, _ = tags[prim.name]
        pidx, fc = tile_corners(out.patches[a:b])
        dom = prim.D.domain
        tol = COINCIDENT * float(np.abs(dom).max() + 1.0)
        for fi, side in enumerate(FACE_NAMES):
            k, s = FACE_AXIS[side]
            on = np.all(np.abs(fc[:, fi, :, k] - dom[k, s]) < tol, axis=-1)
            out.tags[f"{prim.name}:{side}"] = [(a + int(pidx[t]), side) for t in np.flatnonzero(on)
                                               if (a + int(pidx[t]), side) in free]


def _valid(b) -> bool:
    """A bridge to a surface the analysis can take: its net inside its map's domain (else its image would be
    clipped there) and its Jacobian of one sign."""
    dom = b.D.domain
    pts = b.spline.points.reshape(-1, 3)
    tol = COINCIDENT * float(np.ptp(dom, axis=1).max())
    inside = np.all(pts >= dom[:, 0] - tol) and np.all(pts <= dom[:, 1] + tol)
    return bool(inside) and is_regular(b.spline)


_BENDS = (0.3, 0.7, 0.15, 0.85)  # bend parameters tried for a bridge that folds


def _unfold(model, prim, cls, placed, bridges: list, beta: float) -> list:
    """Rebuild the bridges that fold or leave their map's domain with other bend parameters (the first valid one
    is kept; the others stay, and are eliminated after the collisions)."""
    bad = {(b.patch, b.face): i for i, b in enumerate(bridges) if not _valid(b)}
    out = list(bridges)
    for bend in _BENDS:
        if not bad or bend == beta:
            continue
        again, _ = build_bridges(model, prim, cls, placed, list(bad), bend)
        for b in again:
            key = (b.patch, b.face)
            if key in bad and _valid(b):
                out[bad.pop(key)] = b
    return out


def _is_empty(model, n: int = 9) -> bool:
    """Whether no point of an n^3 parameter grid of any positive primitive lies inside the V-model."""
    for prim in model.positive():
        D = prim.D
        axes = [np.linspace(lo, hi, n + 2)[1:-1] for lo, hi in D.domain]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        if np.any(model.contains(D.evaluate(grid)[:, :3])):
            return False
    return True


def _names(model) -> list[str]:
    """The names of the primitives of a V-model tree, left to right."""
    return [c.name for c in model.children if not hasattr(c, "children")] + [
        n for c in model.children if hasattr(c, "children") for n in _names(c)]
