"""Von Mises stress in a lattice of crosses pulled at one end and held at the other (E = 70 GPa, nu = 0.33).

A 4 x 2 x 2 paving of cross tiles in a 0.04 x 0.02 x 0.02 m block: the umin face held, a traction of
1 MPa along x on the umax face; drawn on the shape deformed 200 times.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives
from iga import ElasticityProblem
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
D = primitives.box((0.04, 0.02, 0.02), degrees=(1, 1, 1))
lattice = tiling.regular(D, library.cross(0.4), (4, 2, 2))
problem = ElasticityProblem(lattice, youngs=70e9, poisson=0.33)
problem.dirichlet("umin", 0.0).traction("umax", [1e6, 0.0, 0.0])
solution = problem.solve()
print(solution)
solution.plot(screenshot=out / "bracket_stress.png", warp=200.0,
              title="Lattice of 16 crosses: one end held, 1 MPa pull on the other (shape x 200)")
