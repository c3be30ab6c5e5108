"""A micro-structure of a micro-structure (Massarwi et al. 2018, Fig. 12): every trivariate paved again.

First level: cross tiles paved 2 x 2 x 1 in a box twisted by 0.5 rad and tapered to 0.6 at the top. Second
level: every one of its 28 trivariates reduced to degree 2 and paved 2 x 2 x 2 with hollow crosses, the free
sides capped; coloured by tile.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
box = primitives.box((1.0, 1.0, 1.6), degrees=(2, 2, 2))
D = primitives.tapered(primitives.twisted(box, 0.5, axis_point=(0.5, 0.5)), 0.6, axis_point=(0.5, 0.5))
first = tiling.regular(D, library.cross(), (2, 2, 1))
ms = tiling.compose_levels(first, library.hollow_cross(), (2, 2, 2), degree=2, seal="cap")
boundary = ms.surface(samples=2)  # computed once: checked, then drawn
w = tiling.export.mesh_watertightness(boundary)
print(f"{first}\n{ms}; {len(ms.caps)} caps; closed {w['closed']}, {w['components']} component(s)")
ms.plot(screenshot=out / "paper_two_level.png", mesh=boundary, color_by="tile",
        title=f"Two levels: {len(first.patches)} trivariates of crosses, each paved with hollow crosses "
              f"({len(ms.patches):,} surfaces, {len(ms.caps)} caps, " + ("closed)" if w["closed"] else "OPEN)"))
