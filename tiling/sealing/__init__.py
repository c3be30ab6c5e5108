"""Sealing a micro-structure's boundary: trivariate plates glued to the tiles (:mod:`.plates`), trimmed caps
and shells of surface tiles (:mod:`.caps`, :mod:`.shells`, :mod:`.clipping`, :mod:`.rims`), and the check that the
result is closed (:mod:`.watertight`).  Elber 2017, Sections 2-3; Massarwi et al. 2018, Section 6.2."""
