"""Trimmed surfaces as tile members (Elber 2017, Section 2 and Fig. 7): paved with the tile, composed exactly.

A :class:`tiling.Tile` may hold :class:`geometry.TrimmedSurface` members
beside its patches (``Tile.trimmed``).  A regular paving places each member
like a patch (:class:`PlacedTrimmed`: its tensor-product surface placed by
the cell's ``[A | b]`` into D's domain); composition ``D(A S + b)`` is exact
and the loops, curves in S's own parameters, are carried unaltered, since
composition does not touch the surface's domain.  The composed members are
part of the boundary surface (:func:`tiling.export.surface`, tessellated
once per member in tile space and mapped per placement) and of the IGES
export (entity 144 over the composed surface, :func:`tiling.export.write_iges`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import TrimmedSurface, compose_placed
from geometry.patches.multipatch import PlacedPatch

__all__ = ["PlacedTrimmed", "place_trimmed", "composed_trimmed"]


@dataclass
class PlacedTrimmed:
    """A trimmed tile member placed into a map: ``trimmed`` in tile coordinates, ``placed`` its surface placed
    (``placed.tile``: the tile it belongs to, ``placed.patch_in_tile``: -1 - its index among the tile's
    trimmed members)."""

    trimmed: TrimmedSurface
    placed: PlacedPatch

    def composed(self) -> TrimmedSurface:
        """The member in physical space, exact: the composed surface with the loops unaltered."""
        return TrimmedSurface.with_loops_of(self.trimmed, self.placed.composed)


def place_trimmed(tile, placement: np.ndarray, outer, tile_index: int, level: int = 0) -> list[PlacedTrimmed]:
    """The trimmed members of ``tile`` placed by ``placement`` (3, 4) into ``outer``'s domain."""
    return [PlacedTrimmed(t, PlacedPatch(t.surface, placement, outer, tile_index, level, -1 - j))
            for j, t in enumerate(getattr(tile, "trimmed", ()))]


def composed_trimmed(members: list) -> list[TrimmedSurface]:
    """Every placed member composed (:meth:`PlacedTrimmed.composed`), in the batches of
    :func:`geometry.compose_placed` (one per member surface and map, kept on the placed surfaces);
    the order of ``members`` is kept."""
    compose_placed([m.placed for m in members])
    return [m.composed() for m in members]
