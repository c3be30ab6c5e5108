"""Adaptive bifurcation in the duck (Massarwi et al. 2018, Section 5): 1-to-4 tiles where the map widens.

The duck trivariate paved by layers along w; a layer's cells split in four (the 1-4a bifurcation tile) wherever
the map stretches a cell beyond 0.35 model units, so the tiles stay near one size; coloured by level. Branch
faces (one coarse face on four fine ones) are glued by refinement matrices in an analysis.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
ms = tiling.bifurcation(primitives.duck(), 0.35, "1-4a")
branch = sum(i.kind == "branch" for i in ms.interfaces)
print(f"{ms}; {branch} branch interfaces")
ms.plot(screenshot=out / "paper_bifurcation_duck.png", color_by="level",
        title=f"Adaptive 1-4 bifurcation of the duck, epsilon = 0.35: {ms.n_tiles} tiles, {ms.levels} levels")
