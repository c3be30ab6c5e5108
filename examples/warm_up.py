"""A lattice of crosses switched on: the temperature after one minute of heating from below.

A 3 x 3 x 2 paving of cross tiles in a 0.03 x 0.03 x 0.02 m aluminium block (205 W/(m K),
rho c = 2.4e6 J/(m^3 K)) at 20 C; 2e4 W/m^2 into the base from t = 0, convection h = 10 W/(m^2 K) to air at
20 C on the top; BDF2 steps of 5 s.
"""

import sys
from pathlib import Path

import tiling
from geometry import primitives
from iga import TransientHeatProblem
from tiling import library

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
D = primitives.box((0.03, 0.03, 0.02), degrees=(1, 1, 1))
lattice = tiling.regular(D, library.cross(0.4), (3, 3, 2))
problem = TransientHeatProblem(lattice, conductivity=205.0, capacity=2.4e6)
problem.neumann("wmin", 2e4).robin("wmax", 10.0, 20.0).initial(20.0)
history = problem.solve(t_end=60.0, dt=5.0)
state = history.at(60.0)
print(history, state.balance().stored_W, "W stored at 60 s")
state.plot(screenshot=out / "warm_up.png", title=f"a cross lattice 60 s after switching on: {problem.ndof} DOFs, "
           f"{state.balance().inflow_W:.3g} W in, {state.stored_W:.3g} W stored")
