"""Heat through a V-rep winged duck (Hong and Elber 2021, Fig. 16): aluminium body, steel wings, one hole.

(body | left wing | right wing) - hole, each primitive a trivariate paved with cross tiles (the body 4 x 4 x 4,
each wing 4 x 8 x 1 per knot span; wings of higher priority), cut cells bridged to the trimming surfaces and the
wings' tiles bridged to the body's (at these reduced counts 28 anchoring faces find no room for a bridge: the
build warns, and their tiles end at free faces); k = 205 W/(m K) in the body, 54 in the wings. The left wing's
tip held at 80 C, the bottom of the body at 20 C.
"""

import sys
from pathlib import Path

from iga import HeatProblem
from tiling.vrep import vrep_microstructure
from tiling.vrep.examples import winged_duck

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
ms = vrep_microstructure(winged_duck((4, 4, 4), (4, 8, 1)), margin=0.03).microstructure
solution = HeatProblem(ms, conductivity="k").dirichlet("wingL:vmax", 80.0).dirichlet("body:wmin", 20.0).solve()
print(solution)
solution.plot(screenshot=out / "paper_winged_duck_heat.png",
              title=f"Winged duck V-model, {len(ms.patches):,} trivariates: left wing tip 80 C, body bottom 20 C")
