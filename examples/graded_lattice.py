"""A lattice graded in all three directions: cross arms thickening towards one corner, heated through it.

Crosses paved 4 x 4 x 4 in a 40 mm cube of aluminium (205 W/(m K)); each arm's width on a cell face is the
field 0.15 + 0.35 r^2 of the cell size, r the normalised distance from the opposite corner, taken on every
shared face so neighbouring tiles meet face to face. 5,000 W/m^2 enter at the corner's three faces, h = 10
W/(m^2 K) to air at 20 C elsewhere.
"""

import sys
from pathlib import Path

import numpy as np

import tiling
from geometry import primitives
from iga import HeatProblem
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
D = primitives.box((0.04, 0.04, 0.04), degrees=(1, 1, 1))
lattice = tiling.field_graded(D, library.face_graded_cross, (4, 4, 4),
                              lambda s: 0.15 + 0.35 * np.sum(s**2, axis=1) / 3)
problem = HeatProblem(lattice, conductivity=205.0)
problem.neumann("umax | vmax | wmax", 5000.0).robin("rest", 10.0, 20.0)
solution = problem.solve()
print(lattice, solution, sep="\n")
solution.plot(screenshot=out / "graded_lattice.png",
              title=f"Crosses graded in 3 directions ({lattice.n_tiles} tiles): 5 kW/m^2 in at the thick corner")
