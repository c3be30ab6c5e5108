"""Elasticity of a ring of crosses (Elber 2017, Fig. 12): the lower inner ring clamped, the upper outer ring lifted.

48 cross tiles (336 trivariates) paved 3 x 2 x 2 per quarter span in a full annulus (radii 1 and 2, height 1);
the bottom faces of the inner half clamped, the top faces of the outer half moved 0.5 up; E = 1, nu = 0.3.
Von Mises stress on the deformed shape (displacement at scale 1).
"""

import sys
from pathlib import Path

import numpy as np

import tiling
from geometry import primitives
from iga import ElasticityProblem
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
ms = tiling.regular(primitives.annulus(1.0, 2.0, 1.0, angle=2 * np.pi), library.cross(), (3, 2, 2))
# the radial parameter v of each patch's centre splits the bottom and top faces into inner and outer rings
centre_v = {i: float(p.placement[1, :3].sum() / 2 + p.placement[1, 3]) for i, p in enumerate(ms.patches)}
ms.tags["lower inner ring"] = [f for f in ms.tags["wmin"] if centre_v[f[0]] < 0.5]
ms.tags["upper outer ring"] = [f for f in ms.tags["wmax"] if centre_v[f[0]] > 0.5]
problem = ElasticityProblem(ms, youngs=1.0, poisson=0.3)
solution = problem.dirichlet("lower inner ring", 0.0).dirichlet("upper outer ring", [0.0, 0.0, 0.5]).solve()
print(solution)
solution.plot(screenshot=out / "paper_elastic_ring.png", warp=1.0,
              title=f"Ring of {ms.n_tiles} crosses: inner bottom clamped, outer top lifted 0.5 (E = 1, nu = 0.3)")
