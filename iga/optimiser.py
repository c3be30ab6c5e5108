"""The optimisation loop every design shares: SciPy's SLSQP over scaled variables, one exact analysis and its
adjoint gradient per design, typed results (:class:`DesignResult`, :class:`DesignStep`), and the model of a
redesigned map (:func:`redesigned`).  Used by :mod:`iga.design` (a channel of the map) and :mod:`iga.shape_design`
(the map's control points)."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from geometry import progress
from geometry.errors import show
from geometry.faces import FACE_AXIS
from geometry.numbers import is_real
from geometry.patches.multipatch import PlacedPatch

from iga.errors import ProblemError
from iga.heat.problem import HeatProblem
from iga.model import same_kind
from iga.outputs import Compliance, Output, VonMisesNorm

__all__ = ["DesignStep", "DesignResult", "redesigned", "run_slsqp", "check_design", "free_mask", "bounds_pair",
           "analysed"]


@dataclass(frozen=True)
class DesignStep:
    """One iteration: the ``objective`` (the output's units), the ``mean`` of the channel (its units; a shape
    design: the solid volume, m^3; a macro model kept at its solid fraction: that fraction), the ``step``
    (largest change of a control value: the channel's units, or m)
    and the iteration's ``seconds``."""

    iteration: int
    objective: float
    mean: float
    step: float
    seconds: float


@dataclass(frozen=True)
class DesignResult:
    """What :func:`optimize` found: the channel's control ``values`` (shaped like D's control grid; a shape design:
    the control points' coordinates, (n1, n2, n3, 3)), the ``solution``
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


def free_mask(shape, hold) -> np.ndarray:
    """Mask ``shape`` (n1, n2, n3) of the control values that move: all but those on the faces ``hold`` of their
    grid (a clamped spline's face is its face's control values alone: the map's faces, a field's walls there)."""
    if isinstance(hold, str) or not all(isinstance(h, str) for h in hold):
        raise ProblemError(f"hold must be a list of the map's face names, e.g. ['wmin'], got {show(hold)}")
    free = np.ones(tuple(shape), bool)
    for face in hold:
        if face not in FACE_AXIS:
            raise ProblemError(f"hold: {show(face)} is not a face of the map; use 'umin', 'umax', 'vmin', 'vmax', "
                               "'wmin' or 'wmax'")
        k, side = FACE_AXIS[face]
        index = [slice(None)] * 3
        index[k] = -1 if side else 0
        free[tuple(index)] = False
    return free


def bounds_pair(bounds, positive: bool = False) -> bool:
    """Whether ``bounds`` is (low, high) of finite numbers with low < high (and 0 < low where ``positive``)."""
    return (isinstance(bounds, (tuple, list)) and len(bounds) == 2 and all(is_real(b) and np.isfinite(b) for b in bounds)
            and (not positive or 0 < bounds[0]) and bounds[0] < bounds[1])


def analysed(problem, solver: str):
    """One analysis of a design: a heat problem keeps its factorisation for the adjoint solves that follow; an
    elastic one (its compliance is self-adjoint) needs none; both keep their Gauss points' geometry."""
    problem.gauss_geometry.keep(problem)  # the design step passes over the Gauss points three times and more
    return problem.solve(solver=solver) if hasattr(problem, "material") else problem.solve(solver=solver, keep=True)


def check_design(problem, objective, maxiter, elastic: bool = False) -> None:
    """What every design needs: a steady heat problem (or, where ``elastic``, an elasticity problem whose
    objective is its compliance or its von Mises norm), an output to minimise, an iteration limit."""
    from iga.elasticity.problem import ElasticityProblem

    if elastic and type(problem) is ElasticityProblem:
        if not isinstance(objective, (Compliance, VonMisesNorm)):
            raise ProblemError(f"an elastic design minimises Compliance() or VonMisesNorm(p) (the outputs with "
                               f"elastic gradients), got {show(objective)}")
    elif type(problem) is not HeatProblem:
        raise ProblemError(f"optimize takes a steady iga.HeatProblem{' or an iga.ElasticityProblem' if elastic else ''}"
                           f", got {type(problem).__name__}")
    if not isinstance(objective, Output):
        raise ProblemError(f"objective must be an output of iga.outputs with a gradient (e.g. TemperatureNorm(8)), "
                           f"got {show(objective)}")
    if not (isinstance(maxiter, int) and maxiter >= 1):
        raise ProblemError(f"maxiter must be an integer >= 1, got {show(maxiter)}")


def run_slsqp(objective, analyse, z0, box, unit: float, constraints, maxiter: int, tol: float, measured: str,
              shape, keep_measure: bool = False) -> DesignResult:
    """SLSQP over scaled variables z in ``box`` from ``z0``: ``analyse(z) -> (values, solution, J, dJ/dz, measure,
    d measure/dz or None)`` (one analysis and its gradients per design; the last design is kept, as SLSQP asks for
    the value, the gradient and the constraints of the same point), the objective scaled by its initial value;
    ``unit`` converts a step in z to the values' units; ``measured`` names the measure (``mean``, ``volume``) in
    the progress lines; ``shape`` the values' shape in the result; ``keep_measure``: the measure kept at its value
    at ``z0`` (an equality with its gradient, relative to that value), besides ``constraints``."""
    cache: dict = {}

    def at(z):
        key = np.asarray(z, float).tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = analyse(np.asarray(z, float))
        return cache[key]

    _, _, J0, _, M0, dM0 = at(z0)
    scale = abs(J0) if J0 else 1.0
    if keep_measure and not np.abs(dM0).max() > 1e-12 * abs(M0):  # SLSQP: "Singular matrix C", nothing done
        raise ProblemError(f"the {measured} does not change to first order with these design variables (its gradient "
                           f"vanishes at the start), so it cannot be kept as an equality; design without keeping it "
                           f"(keep_volume=False, keep_fraction=False) or free other variables")
    if keep_measure:
        constraints = list(constraints) + [{"type": "eq", "fun": lambda z: np.array([(at(z)[4] - M0) / abs(M0)]),
                                            "jac": lambda z: at(z)[5][None, :] / abs(M0)}]
    history: list = []
    state = {"z": np.array(z0, float), "t": time.perf_counter(), "evals": 0}

    def fun(z):
        state["evals"] += int(np.asarray(z, float).tobytes() not in cache)
        return at(z)[2] / scale

    def record(z):
        _, _, J, _, measure, _ = at(z)
        step = float(np.abs(z - state["z"]).max() * unit)
        history.append(DesignStep(len(history) + 1, float(J), float(measure), step, time.perf_counter() - state["t"]))
        state["z"], state["t"] = np.array(z, float), time.perf_counter()
        if progress.active():
            print(f"[design {len(history)}] {objective.name} = {J:.6g}, {measured} {measure:.4g}, step "
                  f"{step:.3g}, {history[-1].seconds:.2f} s", file=sys.stderr, flush=True)

    res = minimize(fun, z0, jac=lambda z: at(z)[3] / scale, bounds=[box] * len(z0), constraints=constraints,
                   method="SLSQP", callback=record, options={"maxiter": maxiter, "ftol": tol})
    values, sol, J = at(res.x)[:3]
    return DesignResult(np.asarray(values).reshape(shape), sol, float(J0), float(J), tuple(history),
                        bool(res.success), str(res.message), state["evals"] + 1)
