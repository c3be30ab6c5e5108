"""Two-level (multi-resolution) micro-structures: the trivariates of a micro-structure as deformation maps of a
second paving (Massarwi et al. 2018, Section 8, Fig. 12).

Every trivariate of the first micro-structure is composed exactly, optionally
reduced to a low degree (Section 6.3, :func:`geometry.reduce_model`: shared
sides stay identical, so the second level's tiles still meet across the
first level's interfaces), and paved by the second tile as its own
deformation map.  With ``seal="cap"`` the sides of those maps that are free
faces of the first level are capped by the second tile's trimmed caps
(surface tiles); open sides meet the neighbouring map's tiles.  The result
is one :class:`tiling.Microstructure` whose patches each carry their own map:
interfaces are found in physical space across the first level's interfaces,
and the face tags (``umin`` .. ``wmax``, ``boundary``, ...) are those of the
first level, so a heat problem reads the same.
"""

from __future__ import annotations

from geometry import progress, reduce_model
from geometry.errors import show
from geometry.faces import FACE_NAMES

from tiling.sealing.caps import PlacedCap
from .errors import TilingError
from .microstructure import Microstructure, PlacedPatch
from .checks import check_counts
from .paving import regular
from .tile import Tile
from tiling.members.trimmed import PlacedTrimmed

__all__ = ["compose_levels"]

_OWN = {"boundary", "exterior", "internal", "branch-in", "branch-out"}  # tags the combined build recomputes


def compose_levels(first: Microstructure, tile: Tile, counts, degree: int | None = 2, seal: str | None = None,
                   name: str = "two-level") -> Microstructure:
    """Pave every trivariate of ``first`` (reduced to ``degree``; None: exact) with ``counts`` copies of ``tile``.

    ``seal="cap"`` caps the first level's free faces (surface tiles only: volumetric plates squeeze the
    tiles, whose faces would then miss the neighbouring map's tiles across the first level's interfaces).
    """
    if not isinstance(first, Microstructure):
        raise TilingError(f"compose_levels needs a tiling.Microstructure as the first level, got {show(first)}")
    if not isinstance(tile, Tile):
        raise TilingError(f"tile must be a tiling.Tile, got {type(tile).__name__}")
    counts = check_counts(counts, 3, "counts")
    if seal not in (None, "cap"):
        raise TilingError(f"seal must be 'cap' or None for a second level, got {show(seal)}")
    if seal and tile.trivariates:
        raise TilingError(f"tile {show(tile.name)} is volumetric: a second level can be capped with surface tiles "
                          "only (plates squeeze the tiles, so they would miss the tiles across the first level's "
                          "interfaces); pass seal=None or a surface tile such as library.hollow_cross()")
    if not tile.trivariates and any(i.kind == "branch" for i in first.interfaces):
        n = sum(i.kind == "branch" for i in first.interfaces)
        raise TilingError(f"{first.name or 'the first level'} has {n} branch interfaces (a parent face glued to "
                          f"smaller child faces), and the openings of the surface tile {show(tile.name)} on a parent face "
                          "cannot meet those on its children's faces: the surface would be open inside the model; use a "
                          "first level without level changes (e.g. tiling.regular) or a volumetric tile")
    vols = [i for i, P in enumerate(first.patches) if P.spline.dim == 3]
    if len(vols) != len(first.patches):
        raise TilingError(f"{first.name or 'the first level'} has surface or curve patches; only trivariates can "
                          "be deformation maps of a second level")
    if degree is None:
        maps = first.compose_all()
    else:
        maps, _ = reduce_model(first, degree)
    free: dict = {}
    for i, f in first.tags.get("boundary", []):
        if f in FACE_NAMES:
            free.setdefault(i, set()).add(f)
    placed, tiles, caps, links, origin, trimmed = [], [], [], [], [], []
    built: dict = {}  # the tile's sealed variants, built once for every map
    for i, D in enumerate(progress.bar(maps, desc="second level", unit="map")):
        sides = sorted(free.get(i, ()), key=FACE_NAMES.index)
        sealed = bool(sides and seal)
        sub = regular(D, tile, counts, seal=seal if sealed else None,
                      seal_sides=sides if sealed and seal == "cap" else None, built=built)  # a shell: every side
        p0, t0 = len(placed), len(tiles)
        level = first.patches[i].level
        placed += [PlacedPatch(P.spline, P.placement, P.outer, P.tile + t0, level, P.patch_in_tile)
                   for P in sub.patches]
        tiles += sub.tiles
        caps += [PlacedCap(c.cap, PlacedPatch(c.placed.spline, c.placed.placement, c.placed.outer,
                                              c.placed.tile + t0, level, -1), c.first + p0) for c in sub.caps]
        trimmed += [PlacedTrimmed(m.trimmed, PlacedPatch(m.placed.spline, m.placed.placement, m.placed.outer,
                                                         m.placed.tile + t0, level, m.placed.patch_in_tile))
                    for m in sub.trimmed]
        links += [(a + p0, fa, itf.box, b + p0, fb) for itf in sub.interfaces if itf.kind == "branch"
                  for (a, fa), (b, fb) in [(itf.a, itf.b)]]
        origin.append((p0, sub))
    ms = Microstructure.build(first.outer, placed, tiles, links, name=name)
    ms.caps = caps
    ms.trimmed = trimmed
    _first_level_tags(ms, first, origin)
    return ms


def _first_level_tags(ms: Microstructure, first: Microstructure, origin) -> None:
    """Face tags of ``ms`` from the first level: a free face of the second level on side f of map i belongs to
    every tag of the first level that holds (i, f)."""
    named: dict = {}
    for tag, faces in first.tags.items():
        if tag in _OWN:
            continue
        for key in faces:
            named.setdefault(key, []).append(tag)
    free = set(ms.tags["boundary"])
    new = {tag: [] for tag in first.tags if tag not in _OWN}
    for i, (p0, sub) in enumerate(origin):
        for f in FACE_NAMES:
            for tag in named.get((i, f), ()):
                new[tag] += [(p + p0, g) for p, g in sub.tags.get(f, []) if (p + p0, g) in free]
        for tag in ("cap",):
            if tag in sub.tags:
                new.setdefault(tag, []).extend((p + p0, g) for p, g in sub.tags[tag])
    for tag in FACE_NAMES:
        new.setdefault(tag, [])
    ms.tags.update({k: sorted(set(v)) for k, v in new.items()})
    ms.tags["internal"] = sorted(set(ms.tags["boundary"]) - {f for t in FACE_NAMES for f in ms.tags[t]})
