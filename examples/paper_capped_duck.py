"""A sealed lattice in the duck (Elber 2017, Fig. 2(d)): hollow crosses capped where they meet the boundary.

Hollow-cross surface tiles paved 4 x 4 x 1 in the duck trivariate and composed into it; every tube end on the
map's boundary is closed by a cap, so the lattice is one closed, watertight surface ready to print.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
ms = tiling.regular(primitives.duck(), library.hollow_cross(), (4, 4, 1), seal="cap")
boundary = ms.surface(samples=3)  # computed once: checked, then drawn
w = tiling.export.mesh_watertightness(boundary)
print(f"{ms}; {len(ms.caps)} caps; closed {w['closed']}, manifold {w['manifold']}, {w['components']} component(s)")
ms.plot(screenshot=out / "paper_capped_duck.png", mesh=boundary,
        title=f"Hollow crosses in the duck, capped: {len(ms.caps)} caps, " + ("closed" if w["closed"] else "OPEN"))
