"""Files of the analysis: VTU for ParaView (sampled :mod:`.vtu`, exact Bezier :mod:`.vtu_bezier`), G+Smo XML
(:mod:`.gismo`), solution fields on sample grids (:mod:`.sampling`) and ``iga info`` (:mod:`.describe`)."""
