"""Random implicit micro-structures with guaranteed connectivity (Massarwi et al. 2018, Section 4).

A random spline field per cell of the map's parameter grid, made connected across cells and inside each
(:mod:`.connect`), certified connected on the spline itself (:mod:`.certify`, :mod:`.boxes`), and its zero set
extracted as one welded, outward-oriented surface (:mod:`.surface`) or drawn (:mod:`.render`).
"""

from tiling.implicit.structure import ImplicitStructure, canonical_tubes, random_implicit

__all__ = ["ImplicitStructure", "canonical_tubes", "random_implicit"]
