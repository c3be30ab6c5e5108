"""Helical tubes composed into a knot (Elber 2017, Fig. 4(c)): 47 tiles along a tricubic trefoil trivariate.

The tile is four bicubic tubes, quarter turns of helices (Fig. 4(a)); paved once per knot span of a square
section swept along a trefoil knot (lengths 4 x 4 x 50), each copy composed exactly into the map: 188 surfaces
of degrees (27, 27); coloured by tile.
"""

import sys
from pathlib import Path

import tiling
from geometry.shapes.sweep import trefoil
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
ms = tiling.regular(trefoil(), library.helical_tubes(), (1, 1, 1), name="knot")
composed = ms.compose_all()
print(f"{ms}; composed degrees {composed[0].degrees}")
ms.plot(screenshot=out / "paper_knot.png", samples=2, color_by="tile",
        title=f"{ms.n_tiles} helical tiles composed into a trefoil knot: {len(composed)} surfaces of degrees "
              f"{composed[0].degrees}")
