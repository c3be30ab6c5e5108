"""Trimmed surfaces as tile members (Elber 2017, Fig. 7): three through-cylinders paved 4 x 4 x 2.

The tile is six trimmed NURBS half-cylinders (radius 0.25 of the cell) whose trimming loops follow the other
cylinders; paved in a 4 x 4 x 2 box and composed exactly, the loops carried unaltered; coloured by tile.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives
from tiling.members.cylinders import through_cylinders

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
D = primitives.box((4.0, 4.0, 2.0)).elevate_to((2, 2, 2))
ms = tiling.regular(D, through_cylinders(0.25), (4, 4, 2), name="Fig. 7")
print(ms)
ms.plot(screenshot=out / "paper_trimmed_cylinders.png", samples=4, color_by="tile",
        title=f"Three trimmed through-cylinders per tile, paved 4 x 4 x 2: {ms.n_tiles} tiles")
