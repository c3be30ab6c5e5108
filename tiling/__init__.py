"""Tiles, pavings and the Microstructure model.

Public names: :class:`Tile`, :class:`BranchFace`, :func:`regular`,
:func:`hierarchical`, :class:`Microstructure`, :class:`TilingError` and the
``library`` module of built-in tiles.
"""

from geometry.errors import ToolkitError


class TilingError(ToolkitError):
    """Invalid tile, paving request or micro-structure."""


from .tile import BranchFace, Tile, discontinuity_branches  # noqa: E402
from .microstructure import Interface, Microstructure, PlacedPatch  # noqa: E402
from .paving import hierarchical, regular  # noqa: E402
from . import library  # noqa: E402

__all__ = ["TilingError", "Tile", "BranchFace", "discontinuity_branches", "Microstructure", "PlacedPatch",
           "Interface", "regular", "hierarchical", "library"]
