"""Members of a tile that are not trivariate patches: polygons and polylines (:mod:`.polygons`), curves swept
into round struts (:mod:`.struts`), trimmed surfaces (:mod:`.trimmed`) and the three-cylinder trimmed tile
(:mod:`.cylinders`).  Elber 2017, Section 2, Figs. 7 and 10."""
