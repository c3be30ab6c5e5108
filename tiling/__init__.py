"""Tiles, pavings and the Microstructure model.

Public names: :class:`Tile`, :class:`BranchFace`, :func:`regular`,
:func:`hierarchical`, :class:`Microstructure`, :func:`random_implicit` (random
implicit structures, :class:`ImplicitStructure`), :func:`topo_subdiv` (adaptive
subdivision, :class:`CellComplex`), :func:`bifurcation` (layered bifurcation
tilings), :func:`implicit_bifurcation`, :func:`compose_levels` (two-level structures), :func:`graded` (layers of a tile family),
:func:`field_graded` (a tile family's face values from a field, in three directions), :func:`leaf_graded` (the last
level of a hierarchical paving graded by a field),
:func:`round_struts` (curve tiles swept with circular sections),
:class:`TilingError` and the
``library`` module of built-in tiles.
"""

from .errors import TilingError
from .tile import BranchFace, Tile, discontinuity_branches
from .microstructure import Interface, Microstructure, PlacedPatch
from .paving import hierarchical, regular
from tiling.implicit.structure import ImplicitStructure, canonical_tubes, random_implicit
from tiling.branching.subdivision import CellComplex, topo_subdiv
from tiling.branching.paving import bifurcation, bifurcation_tiles
from tiling.branching.implicit import BifurcationStructure, implicit_bifurcation
from tiling.members.polygons import PolygonTile, pave_polygons
from .levels import compose_levels
from .graded_layers import field_graded, graded, leaf_graded
from tiling.members.struts import round_struts
from . import library

__all__ = ["TilingError", "Tile", "BranchFace", "discontinuity_branches", "Microstructure", "PlacedPatch",
           "Interface", "regular", "hierarchical", "library",
           "random_implicit", "ImplicitStructure", "canonical_tubes", "topo_subdiv", "CellComplex", "bifurcation",
           "bifurcation_tiles", "implicit_bifurcation", "BifurcationStructure",
           "PolygonTile", "pave_polygons", "compose_levels", "graded", "field_graded", "leaf_graded",
           "round_struts"]
