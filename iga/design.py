"""Design by gradient: the control values of a material channel of the deformation map, optimised for an output.

:func:`optimize` takes a steady :class:`iga.HeatProblem` whose conductivity is a channel NAME of the deformation
map D (a graded material, e.g. aluminium near the heated face and steel away from it: Massarwi et al. 2018,
Fig. 18) and changes that channel's control values, within ``bounds``, to minimise an output of
:mod:`iga.outputs` (e.g. ``TemperatureNorm(8)``, a smooth maximum of the temperature), optionally at a fixed
volume mean of the channel (for a channel interpolated linearly between two materials, a fixed mean is a
fixed volume of each: the mass).  Every evaluation is an exact analysis of the same micro-structure with the
new map; the gradient is one adjoint solve (:func:`iga.sensitivity.channel_sensitivity`).  SciPy's SLSQP
(sequential quadratic programming, which takes bounds and the linear mean constraint directly) runs in
variables scaled to [0, 1]; the objective is scaled by its initial value.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from geometry import progress
from geometry.errors import show
from geometry.numbers import is_real
from geometry.patches.multipatch import PlacedPatch

from iga.errors import ProblemError
from iga.heat.problem import HeatProblem
from iga.model import same_kind
from iga.outputs import Output, gauss_pass
from iga.adjoint import design_map, map_basis, map_parameters
from iga.sensitivity import channel_sensitivity

__all__ = ["optimize", "DesignResult", "DesignStep"]


@dataclass(frozen=True)
class DesignStep:
    """One iteration: the ``objective`` (the output's units), the ``mean`` of the channel (its units), the
    ``step`` (largest change of a control value, the channel's units) and the iteration's ``seconds``."""

    iteration: int
    objective: float
    mean: float
    step: float
    seconds: float


@dataclass(frozen=True)
class DesignResult:
    """What :func:`optimize` found: the channel's control ``values`` (shaped like D's control grid), the ``solution``
    of the final design, the objective at the start and the end, the ``history``, SciPy's ``success`` and
    ``message``, and the number of analyses (``evaluations``)."""

    values: np.ndarray
    solution: object
    initial: float
    objective: float
    history: tuple
    success: bool
    message: str
    evaluations: int

    @property
    def improvement(self) -> float:
        """Relative decrease of the objective, (initial - final) / |initial|."""
        return (self.initial - self.objective) / abs(self.initial) if self.initial else 0.0


def redesigned(model, D, new, placed: bool):
    """The model with its deformation map D replaced by ``new`` (the same map with other channel values, or with
    knots inserted: the same geometry): the same tiles, placements, interfaces and tags (a model of one spline:
    that spline replaced)."""
    if placed:
        patches = [PlacedPatch(p.spline, p.placement, new if p.outer is D else p.outer, p.tile, p.level,
                               p.patch_in_tile, refinement=p.refinement) for p in model.patches]
    else:
        p = model.patches[0]
        patches = [PlacedPatch(new, p.placement, p.outer, p.tile, p.level, p.patch_in_tile, refinement=p.refinement)]
    return same_kind(model, patches, list(model.interfaces), {t: list(v) for t, v in model.tags.items()},
                     dict(getattr(model, "face_regions", {})))


def channel_volumes(problem, D, placed: bool) -> np.ndarray:
    """int R_c dV (m^3) of every control value c of D's channels over the model (D's basis at each Gauss point's
    parameter): the mean of a channel with control values k is volumes . k / volume."""
    patches = problem.model.patches
    out = np.zeros(int(np.prod(D.control_points.shape[:3])))

    def add(chunk, space, vals, grads, wv, x, chans):
        out[:] += map_basis(D, map_parameters(patches, chunk, space, D, placed)).T @ wv

    gauss_pass(problem, np.zeros((1, problem.ndof)), add)
    return out


def _check(problem, objective, wrt, bounds, mean, maxiter):
    if type(problem) is not HeatProblem:
        raise ProblemError(f"optimize takes a steady iga.HeatProblem, got {type(problem).__name__}")
    if not isinstance(objective, Output) or not hasattr(objective, "gradient"):
        raise ProblemError(f"objective must be an output of iga.outputs with a gradient (e.g. TemperatureNorm(8)), "
                           f"got {show(objective)}")
    if not (isinstance(wrt, str) and wrt.startswith("channel:")):
        raise ProblemError(f"wrt must be 'channel:NAME' (the control values of the map's channel NAME, which the "
                           f"conductivity reads), got {show(wrt)}")
    ok = (isinstance(bounds, (tuple, list)) and len(bounds) == 2 and all(is_real(b) and np.isfinite(b) for b in bounds)
          and 0 < bounds[0] < bounds[1])
    if not ok:
        raise ProblemError(f"bounds must be (low, high) conductivities with 0 < low < high (W/(m K)), e.g. (54, 205) "
                           f"for steel to aluminium, got {show(bounds)}")
    if mean is not None and not (is_real(mean) and bounds[0] <= mean <= bounds[1]):
        raise ProblemError(f"mean = {show(mean)} cannot be met within bounds {show(tuple(bounds))}: a mean of the "
                           "channel lies between its bounds")
    if not (isinstance(maxiter, int) and maxiter >= 1):
        raise ProblemError(f"maxiter must be an integer >= 1, got {show(maxiter)}")


def optimize(problem, objective: Output, wrt: str = "channel:k", bounds=(54.0, 205.0), mean: float | None = None,
             maxiter: int = 30, tol: float = 1e-6, solver: str = "auto") -> DesignResult:
    """Minimise ``objective`` over the control values of the map's channel named in ``wrt`` (see the module).

    Parameters
    ----------
    problem : a steady :class:`iga.HeatProblem` whose conductivity is the channel (``conductivity="k"``)
    objective : an output of :mod:`iga.outputs` with a gradient, e.g. ``TemperatureNorm(8)`` (C)
    wrt : ``"channel:NAME"``
    bounds : (low, high) of every control value (W/(m K)); the initial values must lie within them
    mean : the volume mean of the channel to keep (W/(m K)); None: free
    maxiter, tol : SLSQP's iteration limit and tolerance (on the objective scaled by its initial value)
    solver : the linear solver of every analysis and adjoint

    Progress: one line per iteration on stderr where progress is on.
    """
    _check(problem, objective, wrt, bounds, mean, maxiter)
    name = wrt.split(":", 1)[1]
    D, placed = design_map(problem, name)
    v0 = np.asarray(D.channel(name), float).reshape(-1)
    lo, hi = float(bounds[0]), float(bounds[1])
    if v0.min() < lo - 1e-9 * hi or v0.max() > hi + 1e-9 * hi:
        raise ProblemError(f"the channel {show(name)} starts at {v0.min():.4g} .. {v0.max():.4g}, outside bounds "
                           f"{show((lo, hi))}; widen the bounds or start from a design inside them")
    vol = channel_volumes(problem, D, placed)
    total = float(vol.sum())
    cache: dict = {}

    def analyse(z):
        key = np.asarray(z, float).tobytes()
        if key not in cache:
            values = lo + np.clip(z, 0, 1) * (hi - lo)
            new = D.with_channel(name, values.reshape(D.control_points.shape[:3]))
            sol = problem.on(redesigned(problem.model, D, new, placed)).solve(solver=solver, keep=True)
            cache.clear()  # one design at a time: SLSQP asks for the value and the gradient of the same point
            cache[key] = (values, sol, objective.value(sol), channel_sensitivity(sol, objective, name, solver))
        return cache[key]

    z0 = (np.clip(v0, lo, hi) - lo) / (hi - lo)
    values0, sol0, J0, _ = analyse(z0)
    scale = abs(J0) if J0 else 1.0
    history: list = []
    state = {"z": z0, "t": time.perf_counter(), "evals": 0}

    def fun(z):
        state["evals"] += int(np.asarray(z, float).tobytes() not in cache)
        return analyse(z)[2] / scale

    def jac(z):
        return analyse(z)[3].reshape(-1) * (hi - lo) / scale

    def record(z):
        values, _, J, _ = analyse(z)
        step = float(np.abs(z - state["z"]).max() * (hi - lo))
        history.append(DesignStep(len(history) + 1, float(J), float(vol @ values / total), step,
                                  time.perf_counter() - state["t"]))
        state["z"], state["t"] = np.array(z, float), time.perf_counter()
        if progress.active():
            print(f"[design {len(history)}] {objective.name} = {J:.6g}, mean {history[-1].mean:.4g}, step "
                  f"{step:.3g}, {history[-1].seconds:.2f} s", file=sys.stderr, flush=True)

    constraints = []
    if mean is not None:
        # vol . (lo + z (hi - lo)) / total = mean, i.e. vol . z / total = (mean - lo) / (hi - lo): linear, O(1)
        a, b = vol / total, (mean - lo) / (hi - lo)
        constraints = [{"type": "eq", "fun": lambda z: np.array([a @ z - b]), "jac": lambda z: a[None, :]}]
    res = minimize(fun, z0, jac=jac, bounds=[(0.0, 1.0)] * len(z0), constraints=constraints, method="SLSQP",
                   callback=record, options={"maxiter": maxiter, "ftol": tol})
    values, sol, J, _ = analyse(res.x)
    return DesignResult(values.reshape(D.control_points.shape[:3]), sol, float(J0), float(J), tuple(history),
                        bool(res.success), str(res.message), state["evals"] + 1)
