"""Micro-structures in V-rep Boolean models (Hong and Elber 2021): primitives, Boolean trees, bridging tiles.

:class:`Primitive` (a map, a tile, counts, a priority), combined by ``|``
(union), ``-`` (subtraction) and ``&`` (intersection) into a :class:`VModel`;
:func:`classify` sorts a primitive's tiles into inside / outside /
intersecting / to-be-bridged (Section 3.1); :func:`vrep_microstructure`
keeps the inside and to-be-bridged tiles of every primitive that carries
tiles as one :class:`tiling.Microstructure` with per-primitive, per-side and
anchoring-face tags, and bridges the anchoring faces: to the trimming
surfaces (:mod:`.bridges`, Sections 3.2-3.3) and, across a surface shared
in a union, to the other primitive's tile faces by matched tubes and
bifurcations (:mod:`.matching`, :mod:`.union`, :mod:`.tubes`, Sections
3.4-3.6).  The result is a heat model: every bridge meets its tiles by
identity interfaces.  :mod:`.examples` builds the paper's models.
"""

from .assemble import VResult, vrep_microstructure
from .classify import INSIDE, INTERSECTING, MARGIN, OUTSIDE, TO_BE_BRIDGED, Classification, classify
from .model import Primitive, VCell, VModel

__all__ = ["Primitive", "VModel", "VCell", "classify", "Classification", "vrep_microstructure", "VResult", "OUTSIDE",
           "INTERSECTING", "INSIDE", "TO_BE_BRIDGED", "MARGIN"]
