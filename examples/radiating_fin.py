"""A fin held at 400 C at its root, cooled by convection and radiation (eps = 0.8) to air at 20 C.

A 0.1 x 0.02 x 0.005 m aluminium fin (205 W/(m K)); h = 10 W/(m^2 K) on every free face, where it also
radiates; the Stefan-Boltzmann condition makes the problem nonlinear, solved by Newton's method.
"""

import sys
from pathlib import Path

from geometry import primitives
from iga import HeatProblem

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
fin = primitives.box((0.1, 0.02, 0.005), degrees=(2, 2, 1), elements=(8, 2, 1))
problem = HeatProblem(fin, conductivity=205.0).dirichlet("umin", 400.0)
problem.robin("rest", 10.0, 20.0).radiation("rest", 0.8, 20.0, scale="C")
solution = problem.solve()
print(solution, "Newton residuals:", [f"{r:.1e}" for r in solution.info.newton])
solution.plot(screenshot=out / "radiating_fin.png",
              title="Aluminium fin, root at 400 C: convection h = 10 W/(m^2 K) and radiation eps = 0.8 to 20 C")
