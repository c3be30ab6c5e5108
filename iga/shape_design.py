"""Shape design by gradient: the deformation map's control points moved to minimise an output at a fixed solid volume.

:func:`optimize_shape` (``iga.optimize(problem, objective, wrt="map", bounds=move, hold=(...))``) moves every
coordinate of the map's control points within ``move`` metres of its start, except those on the map's faces
named in ``hold`` (e.g. the face that takes the heat, so that the heated area and so the power stay as given),
keeping the solid volume of the micro-structure at its start (a nonlinear equality: its shape gradient is
:class:`iga.outputs.Volume`'s, by :func:`iga.shape_sensitivity.shape_sensitivity`).  Every evaluation is an exact
analysis of the same tiles composed into the moved map; the gradient is one adjoint solve
(:mod:`iga.shape_sensitivity`).  SLSQP runs in variables z in [-1, 1] (move = z ``move``).  A move that folds
the map is refused by the analysis (:class:`iga.errors.ProblemError` naming the patch): keep ``move`` below
about a quarter of the spacing of the map's control points.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry.errors import show
from geometry.numbers import is_real

from iga.errors import ProblemError
from iga.optimiser import check_design, free_mask, redesigned, run_slsqp
from iga.outputs import Output, Volume, evaluated
from iga.adjoint import shape_map
from iga.shape_sensitivity import shape_sensitivity

__all__ = ["optimize_shape", "moved_map", "valid_axes"]


def moved_map(D, points: np.ndarray) -> BSpline:
    """D with its control points' coordinates replaced by ``points`` (n1, n2, n3, 3): the same degrees, knots,
    weights and channel values."""
    cp = np.array(D.control_points, float)
    cp[..., :3] = points
    return BSpline(D.degrees, D.knots, cp, D.weights, channels=D.channels)


def valid_axes(axes) -> bool:
    """Whether ``axes`` names coordinates a shape design may move: some of "x", "y", "z", each once."""
    return isinstance(axes, str) and bool(axes) and set(axes) <= set("xyz") and len(set(axes)) == len(axes)


def _check(move, axes) -> None:
    """The arguments of a shape design (:func:`iga.optimiser.check_design` checks the rest)."""
    if not (is_real(move) and np.isfinite(move) and move > 0):
        raise ProblemError(f"wrt='map': bounds is the largest move of a control point coordinate, a number > 0 (m), "
                           f"got {show(move)}")
    if not valid_axes(axes):
        raise ProblemError(f"wrt='map': axes names the coordinates that move, some of 'x', 'y', 'z' once each (e.g. "
                           f"'z': heights only), got {show(axes)}")


def optimize_shape(problem, objective: Output, move: float, hold=(), keep_volume: bool = True, maxiter: int = 30,
                   tol: float = 1e-6, solver: str = "auto", axes: str = "xyz"):
    """Minimise ``objective`` over the map's control points (module notes); ``axes``: the coordinates that move
    (``"z"``: the heights alone, e.g. where a tile's base ends across a sink); returns an
    :class:`iga.design.DesignResult` whose ``values`` are the final control points (n1, n2, n3, 3) and whose steps
    record the solid volume (m^3)."""
    check_design(problem, objective, maxiter)
    _check(move, axes)
    D, placed = shape_map(problem)
    P0 = np.array(D.control_points, float)[..., :3]
    free = np.repeat(free_mask(P0.shape[:3], hold)[..., None], 3, axis=-1)
    free[..., ["xyz".index(a) for a in "xyz" if a not in axes]] = False
    if not free.any():
        raise ProblemError(f"hold = {show(list(hold))} holds every control point of the map: nothing can move")
    volume = Volume()

    def analyse(z):
        P = P0.copy()
        P[free] += np.clip(z, -1.0, 1.0) * move
        sol = problem.on(redesigned(problem.model, D, moved_map(D, P), placed)).solve(solver=solver, keep=True)
        g = shape_sensitivity(sol, objective, solver)[free] * move
        gV = shape_sensitivity(sol, volume, solver)[free] * move
        return P, sol, evaluated(objective, sol), g, evaluated(volume, sol), gV

    return run_slsqp(objective, analyse, np.zeros(int(free.sum())), (-1.0, 1.0), move, [], maxiter, tol, "volume",
                     P0.shape, keep_measure=keep_volume)
