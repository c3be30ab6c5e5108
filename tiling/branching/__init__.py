"""Bifurcation structures (Massarwi et al. 2018, Section 5): the adaptive topological subdivision of the
map's domain (:mod:`.subdivision`, Algorithm 1), layered tilings of parametric split and join tiles
(:mod:`.paving`), and implicit bifurcations on the subdivision (:mod:`.implicit`)."""
