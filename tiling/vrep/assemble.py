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

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from geometry import progress
from geometry.primitives import box
from geometry.errors import show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.patches.multipatch import face_points, tile_corners

from ..errors import TilingError
from ..microstructure import Microstructure, PlacedPatch
from ..paving import regular_placements
from ..tile import Tile
from .bridges import build_bridges, resolve_collisions
from .classify import Classification, classify
from .model import VModel
from .report import BridgeReport
from .spatial import crosses_knot_lines, in_space
from .tubes import are_regular, bridge_patch
from .union import boundary_faces, bridge_union, shared_faces, union_anchors
from geometry.grouping import ObjectIndex
from geometry.tolerances import COINCIDENT, ON_DOMAIN
from geometry.numbers import TINY, is_integer, is_real

__all__ = ["VResult", "vrep_microstructure"]


@dataclass
class VResult:
    """The V-model's micro-structure, the classification of every positive primitive, and timings (s)."""

    microstructure: Microstructure
    classifications: list
    timings: dict
    bridges: BridgeReport = None  # what the bridging did (typed counts)
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
    _check_arguments(model, samples, margin, d_maxdist, phi, alpha, beta)
    t0 = time.perf_counter()
    model.check()
    timings = {"checks": time.perf_counter() - t0}
    kept = _keep_tiles(model, samples, margin, bridges, timings)
    report = BridgeReport()
    made, union = _surface_bridges(model, kept, margin, beta, report, timings) if bridges else ([], [])
    bridge_first = len(kept.placed)
    owner = _place_surface_bridges(kept, made)
    unions = _union_bridges(model, kept, union, owner, (d_maxdist, beta, phi, alpha), report, timings)
    if not kept.placed:
        _refuse_empty(model)
    t0 = time.perf_counter()
    out = _build(model, kept, bridge_first, owner, name)
    timings["build"] = time.perf_counter() - t0
    left = report.unbridged()
    if left:  # said where it happens, not only recorded in res.bridges (and in a pipeline's summary.json)
        warnings.warn(f"V-model {name!r}: {sum(left.values())} anchoring faces have no bridge ("
                      + "; ".join(f"{n}: {why}" for why, n in left.items()) + "); their tiles end at free faces "
                      "there (raise the primitives' counts, or margin, for room to bridge)", UnbridgedWarning,
                      stacklevel=2)
    return VResult(out, kept.classes, timings, report, [b for _, b in made], unions)


class UnbridgedWarning(UserWarning):
    """Some anchoring faces of a V-model were left without a bridge (counts and reasons in the message and in
    ``VResult.bridges.unbridged()``)."""


@dataclass
class _Kept:
    """The kept tiles of every positive primitive: placed patches, tile list, classifications, and per
    primitive name (first patch, end, anchoring (patch, face) list)."""

    placed: list = field(default_factory=list)
    tiles: list = field(default_factory=list)
    classes: list = field(default_factory=list)
    spans: dict = field(default_factory=dict)


def _check_arguments(model, samples, margin, d_maxdist, phi, alpha, beta) -> None:
    if not isinstance(model, VModel):
        raise TilingError(f"vrep_microstructure needs a V-model (primitives combined by |, -, &), got {show(model)}")
    if not (is_integer(samples) and samples >= 2):
        raise TilingError(f"samples must be an integer >= 2 per direction, got {show(samples)}")
    if not (is_real(margin) and np.isfinite(margin) and margin >= 0):
        raise TilingError(f"margin must be a length >= 0 (model units), got {show(margin)}")
    _check_union_parameters(d_maxdist, phi, alpha)
    if not (is_real(beta) and np.isfinite(beta) and 0 < beta < 1):
        raise TilingError(f"the bend parameter beta must be in (0, 1), got {show(beta)} (checked with or without "
                          "bridges, so that a later run with bridges does not fail)")
    names = [p.name for p in model.primitives()]
    if len(set(names)) != len(names):
        raise TilingError(f"primitive names must be distinct (they become tags), got {names}")


def _keep_tiles(model, samples, margin, bridges: bool, timings: dict) -> _Kept:
    """Classify and pave every positive primitive, keeping its inside and to-be-bridged tiles."""
    kept = _Kept()
    for prim in progress.bar(model.positive(), desc="V-model primitives", unit="primitive"):
        t0 = time.perf_counter()
        cls = classify(model, prim, samples, margin)
        t1 = time.perf_counter()
        kept.classes.append(cls)
        timings[f"classify {prim.name}"] = t1 - t0
        if not len(cls.kept):  # nothing of this primitive stays (e.g. a lower priority inside an intersection)
            continue
        paving = regular_placements(prim.D, prim.tile, prim.counts)
        paved, paved_tiles = paving.placed, paving.tiles
        timings[f"pave {prim.name}"] = time.perf_counter() - t1
        keep = set(cls.kept.tolist())
        anchors = {}
        for tile, face in cls.anchors:
            anchors.setdefault(tile, []).append(face)
        tile_map, first = {}, len(kept.placed)
        for P in paved:
            if P.tile not in keep:
                continue
            if P.tile not in tile_map:
                tile_map[P.tile] = len(kept.tiles)
                kept.tiles.append(paved_tiles[P.tile])
            kept.placed.append(PlacedPatch(P.spline, P.placement, P.outer, tile_map[P.tile], P.level,
                                           P.patch_in_tile))
        faces = _anchor_faces(kept.placed[first:], first, cls, anchors, tile_map)
        kept.spans[prim.name] = (first, len(kept.placed), faces)
        if bridges and cls.anchors and not faces:
            raise TilingError(f"primitive {show(prim.name)}: its tile {show(prim.tile.name)} has no patch face on the "
                              f"cell walls, so its {len(cls.anchors)} anchoring faces have nothing to bridge from; use "
                              "a tile whose patches reach the cell faces, or bridges=False")
    return kept


def _surface_bridges(model, kept: _Kept, margin, beta, report: BridgeReport, timings: dict):
    """Bridges to the trimming surfaces (after collisions and folds), and the union pairs to bridge:
    ([(primitive name, Bridge)], [(q, p, q's union anchors, p's shared faces)])."""
    t0 = time.perf_counter()
    by_name = {p.name: p for p in model.positive()}
    made, union = [], []
    for cls in kept.classes:
        prim = cls.primitive
        if prim.name not in kept.spans or not kept.spans[prim.name][2]:
            continue
        anchors = kept.spans[prim.name][2]
        partners, rest = union_anchors(model, prim, kept.placed, anchors, _reach(kept.placed, anchors, margin))
        for pname, faces in partners.items():
            a, b, _ = kept.spans.get(pname, (0, 0, None))
            shared = shared_faces(model, prim, kept.placed, boundary_faces(by_name[pname], kept.placed, a, b))
            if shared:
                union.append((prim, by_name[pname], faces, shared))
            else:  # nothing of the other primitive to meet here: bridge to the surface (Section 3.2)
                rest += faces
                report.union_anchors_to_surface += len(faces)
        got, counts = build_bridges(model, prim, cls, kept.placed, rest, beta)
        made += [(prim.name, b) for b in _unfold(model, prim, cls, kept.placed, got, beta)]
        report.add_surface(counts)
    survivors, report.collisions = resolve_collisions([b for _, b in made])
    valid = [b for b, ok in zip(survivors, _valid(survivors)) if ok]  # a heat model takes regular patches only
    valid = [b for b, ok in zip(valid, _exact(valid, kept.placed)) if ok]
    report.folded = len(survivors) - len(valid)
    report.surface_bridges = len(valid)
    same = ObjectIndex()
    alive = {same(b) for b in valid}
    timings["bridges"] = time.perf_counter() - t0
    return [(n, b) for n, b in made if same(b) in alive], union


def _exact(bridges: list, placed) -> list[bool]:
    """Per bridge: whether the model composes it exactly.  A bridge whose map's knot lines cut it is rebuilt in
    space (:mod:`tiling.vrep.spatial`) with the first bend whose geometry is regular (the one it was built with,
    then the others a folded bridge tries); False (given up as folded) where every one folds.  Where the
    rebuild declines (a rational tile face) the bridge stays in map parameters, analysed through the map.  The
    geometries of one bend are proven regular together."""
    out = [True] * len(bridges)
    todo = [i for i, b in enumerate(bridges) if crosses_knot_lines(b)]
    for k in range(1 + len(_BENDS)):
        built = [(i, in_space(bridges[i], placed, ((bridges[i].beta,) + _BENDS)[k])) for i in todo]
        built = [(i, made) for i, made in built if made is not None]
        for (i, made), ok in zip(built, are_regular([g for _, (g, _) in built])):
            if ok:
                bridges[i].geometry, bridges[i].space = made
        todo = [i for i, made in built if bridges[i].geometry is not made[0]]
    for i in todo:
        out[i] = False
    return out


def _place_surface_bridges(kept: _Kept, made: list) -> dict:
    """Append the surface bridges as patches (one tile entry stands for all: each is its own spline, in map
    parameters, or its own geometry in space); returns {patch index: owning primitive name}."""
    if made:
        bridge_tile = len(kept.tiles)
        kept.tiles.append(Tile([box()], name="one-to-one bridge"))
    owner = {}
    for pname, b in made:
        owner[len(kept.placed)] = pname
        if b.geometry is not None:
            kept.placed.append(bridge_patch(b.geometry, b.space, bridge_tile))
        else:
            kept.placed.append(PlacedPatch(b.spline, np.hstack([np.eye(3), np.zeros((3, 1))]), b.D, bridge_tile, 0,
                                           0))
    return owner


def _union_bridges(model, kept: _Kept, union: list, owner: dict, params, report: BridgeReport,
                   timings: dict) -> list:
    """Bridge every union pair (:func:`tiling.vrep.union.bridge_union`) and append the patches."""
    if not union:
        return []
    t0 = time.perf_counter()
    d_maxdist, beta, phi, alpha = params
    union_tile = len(kept.tiles)
    kept.tiles.append(Tile([box()], name="union bridge"))
    unions = []
    for q, p, faces, shared in union:
        ub = bridge_union(model, q, p, kept.placed, faces, shared, union_tile, d_maxdist, beta, phi, alpha)
        owner.update({len(kept.placed) + j: q.name for j in range(len(ub.patches))})
        kept.placed += ub.patches
        unions.append(ub)
        report.add_union(ub.counts, len(ub.patches))
    timings["union bridges"] = time.perf_counter() - t0
    return unions


def _refuse_empty(model) -> None:
    if _is_empty(model):
        raise TilingError(f"the V-model ({model.op} of {', '.join(_names(model))}) is empty: its Boolean "
                          "expression leaves no volume (no sample point of its primitives lies inside it), so "
                          "there is nothing to pave; check the expression (e.g. A - A)")
    raise TilingError("no tile of the V-model is inside it: every tile is outside or crosses a trimming "
                      "surface; use smaller tiles (higher counts)")


def _build(model, kept: _Kept, bridge_first: int, owner: dict, name: str) -> Microstructure:
    """The micro-structure of the kept patches and bridges, with the V-model's tags (module notes)."""
    out = Microstructure.build(model.positive()[0].D, kept.placed, kept.tiles, [], name=name)
    for tag in FACE_NAMES:
        out.tags[tag] = []  # the faces of one map's domain mean nothing across primitives
    out.tags["internal"] = list(out.tags["boundary"])  # so every free face is "elsewhere" (DESIGN, section 4)
    out.tags["anchor"] = []
    out.tags["bridge"] = [f for f in out.tags["boundary"] if f[0] >= bridge_first]
    for pname in kept.spans:
        out.tags[f"bridge:{pname}"] = []
    for f in out.tags["bridge"]:
        out.tags[f"bridge:{owner[f[0]]}"].append(f)
    for pname, (a, b, anchor_faces) in kept.spans.items():
        out.tags[pname] = [f for f in out.tags["boundary"] if a <= f[0] < b]
        out.tags[f"anchor:{pname}"] = list(anchor_faces)  # glued to their bridges when bridges are built
        out.tags["anchor"] += out.tags[f"anchor:{pname}"]
    _side_tags(out, model, kept.spans)
    return out


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
        tol = COINCIDENT * max(float(np.ptp(box, axis=1).max()), TINY) + ON_DOMAIN
        for cell_face in faces:
            k, s = FACE_AXIS[cell_face]
            out += [(offset + j, f) for f, pts in sides.items() if np.abs(pts[:, k] - box[k, s]).max() < tol]
    return out


def _check_union_parameters(d_maxdist, phi, alpha) -> None:
    if d_maxdist is not None and not (is_real(d_maxdist) and np.isfinite(d_maxdist) and d_maxdist > 0):
        raise TilingError(f"d_maxdist must be a positive length (model units) or None, got {show(d_maxdist)}")
    if not (is_real(phi) and 0.0 <= phi <= 1.0):
        raise TilingError(f"phi blends the cross derivative (0) with the face normal (1): give a number in [0, 1], "
                          f"got {show(phi)}")
    if not (is_real(alpha) and 0 < alpha < np.pi / 2):
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


def _valid(bridges: list) -> list[bool]:
    """Per bridge: one the analysis can take (a bridge to a surface): its net inside its map's domain (else its
    image would be clipped there) and its Jacobian of one sign.  The regularity proofs run together
    (:func:`tiling.vrep.tubes.are_regular`), and each answer is kept on the bridge with the spline it is about
    (``Bridge.regular``): the survivors of the collisions are asked again, and only those that moved (a new
    spline) are proven again."""
    out = [None] * len(bridges)
    ask = []
    for i, b in enumerate(bridges):
        if b.regular is not None and b.regular[0] is b.spline:
            out[i] = b.regular[1]
            continue
        dom = b.D.domain
        pts = b.spline.points.reshape(-1, 3)
        tol = COINCIDENT * float(np.ptp(dom, axis=1).max())
        if np.all(pts >= dom[:, 0] - tol) and np.all(pts <= dom[:, 1] + tol):
            ask.append(i)
        else:
            out[i] = False
    for i, ok in zip(ask, are_regular([bridges[i].spline for i in ask])):
        out[i] = bool(ok)
    for b, ok in zip(bridges, out):
        b.regular = (b.spline, ok)
    return out


_BENDS = (0.3, 0.7, 0.15, 0.85)  # bend parameters tried for a bridge that folds


def _unfold(model, prim, cls, placed, bridges: list, beta: float) -> list:
    """Rebuild the bridges that fold or leave their map's domain with other bend parameters (the first valid one
    is kept; the others stay, and are eliminated after the collisions)."""
    bad = {(b.patch, b.face): i for i, (b, ok) in enumerate(zip(bridges, _valid(bridges))) if not ok}
    out = list(bridges)
    for bend in _BENDS:
        if not bad or bend == beta:
            continue
        again, _ = build_bridges(model, prim, cls, placed, list(bad), bend)
        again = [b for b in again if (b.patch, b.face) in bad]
        for b, ok in zip(again, _valid(again)):
            if ok and (b.patch, b.face) in bad:
                out[bad.pop((b.patch, b.face))] = b
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
