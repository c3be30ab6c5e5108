"""A V-rep Boolean model paved with tiles (Hong and Elber 2021, Fig. 13(c)): (A u B) - C of three cylinders.

Three orthogonal cylinders (radius 1, 1 and 0.8, length 4), each a trivariate paved with cross tiles; the union
of A and B minus C, the cut cells bridged to the trimming surfaces and the two primitives' tiles matched and
bridged across their shared surface; coloured by tile.
"""

import sys
from pathlib import Path

from tiling.vrep import vrep_microstructure
from tiling.vrep.examples import cylinders

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
A, B, C = cylinders((1, 1, 12))
ms = vrep_microstructure((A | B) - C).microstructure
print(ms)
ms.plot(screenshot=out / "paper_vrep_cylinders.png", samples=2, color_by="tile",
        title=f"V-rep (A u B) - C, three cylinders paved with crosses: {len(ms.patches):,} trivariates")
