"""A random implicit micro-structure in the duck (Massarwi et al. 2018, Section 4, Fig. 14): one closed solid.

Random C1 scalar fields around the canonical tubes of 4 x 4 x 12 cells of the duck trivariate (alpha = 0.5 of
randomness, seed 0), joined until the solid is one component (connectivity 2), capped at the duck's boundary
and triangulated by marching cubes; coloured by the map's parameter w.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
s = tiling.random_implicit(primitives.duck(), (4, 4, 12), degree=3, controls=8, alpha=0.5, seed=0,
                           continuity="C1", connectivity=2, cap=True)
w = tiling.export.mesh_watertightness(s.surface())
print(f"{w['triangles']} triangles, closed {w['closed']}, {w['components']} component(s), {s.stats['rounds']} rounds")
s.render_png(out / "paper_random_duck.png", color_by="w",
             title=f"Random implicit duck, 4 x 4 x 12 cells, alpha 0.5, capped: {w['components']} component, "
                   + ("closed" if w["closed"] else "OPEN"))
