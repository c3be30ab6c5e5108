"""The kept tiles of every positive primitive of a V-model as one :class:`tiling.Microstructure`.

Each positive primitive is paved regularly (:func:`tiling.paving.regular_placements`: the placements only,
the interfaces are searched once for the whole model), classified
(:func:`tiling.vrep.classify`), and its inside and to-be-bridged tiles are
kept.  Patches keep their own map (the primitive's), interfaces are found in
physical space, and the tags name the primitive (``"A"``: every free face of
A's kept patches) and the anchoring faces (``"anchor"``, ``"anchor:A"``: the
patch faces lying on an anchoring face of a to-be-bridged tile), where
bridging tiles will start (Hong and Elber 2021, Section 3.2; not built yet).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import progress
from geometry.primitives import box
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES

from ..errors import TilingError
from ..microstructure import Microstructure, PlacedPatch
from ..paving import regular_placements
from ..tile import Tile
from .bridges import build_bridges, resolve_collisions
from .classify import Classification, classify
from .model import VModel

__all__ = ["VResult", "vrep_microstructure"]


@dataclass
class VResult:
    """The V-model's micro-structure, the classification of every positive primitive, and timings (s)."""

    microstructure: Microstructure
    classifications: list
    timings: dict
    bridges: dict = None  # counts: anchoring faces, bridges, dropped, collisions, swapped, repelled, eliminated
    bridge_objects: list = None  # the kept :class:`tiling.vrep.bridges.Bridge` objects, in patch order

    def counts(self) -> dict:
        """Tiles per state, per primitive name."""
        return {c.primitive.name: c.counts() for c in self.classifications}


def vrep_microstructure(model: VModel, samples: int = 4, margin: float = 0.0, name: str = "vrep",
                        bridges: bool = True, beta: float = 0.5) -> VResult:
    """Classify and keep the tiles of every positive primitive of ``model``, and with ``bridges`` connect their
    anchoring faces to the trimming surfaces by one-to-one bridging tiles (:mod:`tiling.vrep.bridges`; bend
    parameter ``beta`` in (0, 1)) whose collisions are resolved."""
    import time

    if not isinstance(model, VModel):
        raise TilingError(f"vrep_microstructure needs a V-model (primitives combined by |, -, &), got {show(model)}")
    if not (isinstance(samples, (int, np.integer)) and samples >= 2):
        raise TilingError(f"samples must be an integer >= 2 per direction, got {show(samples)}")
    if not (isinstance(margin, (int, float)) and np.isfinite(margin) and margin >= 0):
        raise TilingError(f"margin must be a length >= 0 (model units), got {show(margin)}")
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
    made = []
    if bridges:
        t0 = time.perf_counter()
        for cls in classes:
            prim = cls.primitive
            if prim.name not in tags or not tags[prim.name][2]:
                continue
            got, rep = build_bridges(model, prim, cls, placed, tags[prim.name][2], beta)
            made += [(prim.name, b) for b in got]
            for key, v in rep.items():
                report[key] = report.get(key, 0) + v
        kept, counts = resolve_collisions([b for _, b in made])
        report.update(counts)
        report["bridges"] = len(kept)
        alive = {id(b) for b in kept}
        made = [(n, b) for n, b in made if id(b) in alive]
        timings["bridges"] = time.perf_counter() - t0
    bridge_first = len(placed)
    bridge_tile = None
    for _, b in made:
        if bridge_tile is None:  # one tile entry stands for all bridges (each is its own spline, in map parameters)
            bridge_tile = len(tiles)
            tiles.append(Tile([box()], name="one-to-one bridge"))
        placed.append(PlacedPatch(b.spline, np.hstack([np.eye(3), np.zeros((3, 1))]), b.D, bridge_tile, 0, 0))
    if not placed:
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
    owner = {bridge_first + j: pname for j, (pname, _) in enumerate(made)}
    for f in out.tags["bridge"]:
        out.tags[f"bridge:{owner[f[0]]}"].append(f)
    for pname, (a, b, anchor_faces) in tags.items():
        out.tags[pname] = [f for f in out.tags["boundary"] if a <= f[0] < b]
        out.tags[f"anchor:{pname}"] = list(anchor_faces)  # glued to their bridges when bridges are built
        out.tags["anchor"] += out.tags[f"anchor:{pname}"]
    timings["build"] = time.perf_counter() - t0
    return VResult(out, classes, timings, report, [b for _, b in made])


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
        tol = 1e-9 * max(float(np.ptp(box, axis=1).max()), 1e-300) + 1e-12
        for cell_face in faces:
            k, s = FACE_AXIS[cell_face]
            out += [(offset + j, f) for f, pts in sides.items() if np.abs(pts[:, k] - box[k, s]).max() < tol]
    return out
