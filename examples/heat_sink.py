"""A two-level heat sink: steady heat through a graded, hierarchical micro-structure.

Tile T2 of Massarwi et al. 2018 paved 2 x 2 on the vertical heat-sink map, each fin carrying a second level;
aluminium (205 W/(m K)) at the base graded to steel (54 W/(m K)) at the top; 1515.8 W/m^2 into the base,
convection h = 5 W/(m^2 K) to air at 30 C everywhere else.
"""

import sys
from pathlib import Path

import tiling
from iga import HeatProblem
from iga.app.pipeline import vertical_heat_sink_map
from tiling import library
from tiling.materials import graded_channel

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
D = graded_channel(vertical_heat_sink_map(), "k", near=205.0, far=54.0, face="wmin")
sink = tiling.hierarchical(D, library.heat_sink_t2(), counts=(2, 2), levels=2, scale=0.5)
problem = HeatProblem(sink, conductivity="k").neumann("branch-in", 1515.8).robin("exterior", 5.0, 30.0)
solution = problem.solve()
print(solution)
solution.plot(screenshot=out / "heat_sink.png",
              title=f"Two-level sink, {sink.n_tiles} tiles: 1515.8 W/m^2 in at the base, h = 5 W/(m^2 K) to 30 C")
