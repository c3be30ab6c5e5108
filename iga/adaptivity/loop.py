"""The adaptive loop: solve, estimate, mark (Dorfler), refine by tiles, until the estimate meets the tolerance.

:func:`adaptive_solve` takes a :class:`iga.HeatProblem` as set up (conductivity, source, conditions, solution
degree and refinement) and replays it on ever finer models of :class:`iga.adaptivity.tree.TileRefinement`: each
step solves, estimates the error per patch (:func:`iga.adaptivity.estimator.estimate_error`), marks the
fewest patches whose indicators carry a fraction ``marking`` of the estimate's square (Dorfler 1996), and
splits them into 2 x 2 x 2 children (patches with discontinuity planes are bisected in place).  It stops when
the estimate relative to the solution's energy norm is at most ``tolerance``, or before a step would exceed
``max_unknowns`` unknowns, and returns the last solution with the history of every step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from geometry import progress
from geometry.errors import show
from geometry.numbers import is_real as is_number

from iga.adaptivity import goal as goals_of
from iga.adaptivity import hp
from iga.adaptivity.estimator import ErrorEstimate, estimate_error
from iga.adaptivity.tree import TileRefinement
from geometry.faces import FACE_AXIS

from iga.discretisation.constraints import needs_constraints, prolongation
from iga.errors import ProblemError
from iga.heat.problem import HeatProblem

__all__ = ["AdaptiveStep", "AdaptiveResult", "adaptive_solve", "dorfler", "unknowns"]


@dataclass(frozen=True)
class AdaptiveStep:
    """One step of the loop: ``unknowns`` solved for, ``dofs`` before constraints, ``patches``, the ``estimate``
    (energy norm, sqrt(W K)) and it ``relative`` to the solution's, the true relative ``error`` (when the exact
    gradient was given, else None), the patches ``marked`` for the next step and the step's ``seconds``."""

    unknowns: int
    dofs: int
    patches: int
    estimate: float
    relative: float
    error: float | None
    marked: int
    seconds: float
    #: with a goal: the estimate sum_P eta_P(T) eta_P(z) of the weighted flows' error (:mod:`iga.adaptivity.goal`)
    goal: float | None = None

    @property
    def effectivity(self) -> float | None:
        """Estimate over true error (None without the exact gradient)."""
        return None if not self.error else self.relative / self.error


@dataclass(frozen=True)
class AdaptiveResult:
    """What :func:`adaptive_solve` found: the last ``solution`` (its model the refined one), its ``estimate``,
    the ``history`` of every step, whether the tolerance was ``reached``, and ``reason``: why the loop stopped.
    Unpacks as ``solution, history``."""

    solution: object
    estimate: ErrorEstimate
    history: tuple
    reached: bool
    reason: str

    @property
    def model(self):
        """The refined model of the last solution."""
        return self.solution.problem.model

    def __iter__(self):
        """``solution, history = adaptive_solve(...)`` unpacks the last solution and the steps."""
        return iter((self.solution, self.history))


def dorfler(indicators, fraction: float) -> np.ndarray:
    """The fewest indices whose ``indicators`` (squares) sum to at least ``fraction`` of the total (largest first)."""
    eta = np.asarray(indicators, float)
    order = np.argsort(-eta, kind="stable")
    cum = np.cumsum(eta[order])
    if cum[-1] <= 0:
        return np.zeros(0, np.int64)
    # the first count reaching the fraction, with a margin below it so that round-off in the sum marks no extra
    n = int(np.searchsorted(cum, fraction * cum[-1] * (1 - 1e-12), side="left")) + 1
    return np.sort(order[: min(n, len(eta))])


def _check(problem, tolerance, max_unknowns, marking, refine, max_steps) -> None:
    if type(problem) is not HeatProblem:
        raise ProblemError(f"adaptive_solve takes a steady iga.HeatProblem, got {type(problem).__name__}")
    if not (is_number(tolerance) and np.isfinite(tolerance) and tolerance > 0):
        raise ProblemError(f"tolerance must be a positive number (the estimate relative to the solution's energy "
                           f"norm, e.g. 1e-3), got {show(tolerance)}")
    if not (is_number(marking) and 0 < marking <= 1):
        raise ProblemError(f"marking must lie in (0, 1] (the fraction of the squared estimate the marked patches "
                           f"carry; 0.5 is usual), got {show(marking)}")
    if max_unknowns is not None and not (is_number(max_unknowns) and max_unknowns >= 1):
        raise ProblemError(f"max_unknowns must be a positive number or None, got {show(max_unknowns)}")
    if not (isinstance(max_steps, (int, np.integer)) and not isinstance(max_steps, bool) and max_steps >= 1):
        raise ProblemError(f"max_steps must be an integer >= 1, got {show(max_steps)}")
    if refine not in ("h", "h-in-place", "p", "hp"):
        raise ProblemError(f"refine must be 'h' (split patches into 2 x 2 x 2 children; those with discontinuity "
                           f"planes bisected in place), 'h-in-place' (bisect every marked patch's knot spans), 'p' "
                           f"(raise every marked patch's degree by one) or 'hp' (either, per patch), got "
                           f"{show(refine)}")
    if refine in ("p", "hp") and problem.space_args[3] is not None:
        raise ProblemError("refine='p' raises each marked patch's degree; the problem fixes every patch's degree "
                           "(degree=...): give degree_elevation instead")
    own = [tuple(U.tobytes() for U in p.spline.knots) for p in problem.model.patches]
    given = [tuple(np.asarray(U, float).tobytes() for U in knots) for knots, _ in problem.bases]
    if own != given:
        raise ProblemError("adaptive_solve refines each patch's own basis; a problem analysed in other bases "
                           "(bases=...) cannot be refined by tiles")
    start = unknowns(problem) if max_unknowns is not None else 0
    if max_unknowns is not None and start > max_unknowns:
        raise ProblemError(f"the problem already has {start:,} unknowns, more than max_unknowns = "
                           f"{int(max_unknowns):,}; raise the budget or start coarser")


def adaptive_solve(problem, tolerance: float, max_unknowns: int | None = None, marking: float = 0.5,
                   refine: str = "h", solver: str = "auto", exact_gradient=None, max_steps: int = 50,
                   tol: float = 1e-10, goal=None) -> AdaptiveResult:
    """Solve ``problem`` adaptively until the error estimate relative to the solution's energy norm is at most
    ``tolerance`` (see the module notes).

    Parameters
    ----------
    problem : a steady :class:`iga.HeatProblem` with its conditions; its ``degree_elevation``, ``refine`` and
        ``degree`` apply to every patch of every step
    tolerance : the relative energy-norm error wanted (> 0), e.g. 1e-3
    max_unknowns : the budget of unknowns solved for (:func:`unknowns`): a step that would exceed it refines
        only the marked patches with the largest indicators that fit, and its solve is the last; when none fits,
        the loop stops; either way the best solution so far is returned with ``reached=False`` and the reason
    marking : Dorfler's fraction in (0, 1]: the marked patches carry at least this fraction of eta^2
    refine : ``"h"`` splits marked patches into 2 x 2 x 2 children (patches with discontinuity planes are bisected
        in place), ``"h-in-place"`` bisects every marked patch's knot spans, ``"p"`` raises every marked patch's
        degree by one (its neighbours' faces of lower degree glued by degree-elevation matrices), ``"hp"`` chooses
        per patch: split where its indicator exceeds the one predicted for it, else raise its degree
        (:mod:`iga.adaptivity.hp`)
    solver, tol : for each solve (:meth:`iga.HeatProblem.solve`)
    exact_gradient : optional callable grad T(x (N, 3)) -> (N, 3) of the exact solution: the history then holds the
        true relative energy-norm error of every step (conductivity constant per patch, as the estimate needs)
    max_steps : at most this many solves
    goal : optional :class:`iga.outputs.HeatFlow` or list of them (flows through Robin faces): mark by the
        product of the solution's and the dual solution's indicators and stop when the estimated error of the
        flows, each relative to its size, is at most ``tolerance`` (:mod:`iga.adaptivity.goal`; one more solve
        per step)

    Progress: one line per step on stderr when progress is on (the ``iga`` command line, the benchmarks).
    """
    _check(problem, tolerance, max_unknowns, marking, refine, max_steps)
    goals = None if goal is None else goals_of.check_goals(problem, goal)
    weights = None
    tree = TileRefinement(problem.model)
    current = problem if len(tree.leaves) == len(problem.model.patches) else problem.on(tree.model())
    history, reached, reason, last = [], False, f"{max_steps} steps taken", False
    solution = estimate = None
    predicted: dict = {}  # refine="hp": the predicted squared indicator of each leaf
    for step in range(1, max_steps + 1):
        t0 = time.perf_counter()
        solution = current.solve(solver=solver, tol=tol)
        estimate = estimate_error(solution)
        error = _true_error(solution, estimate, exact_gradient) if exact_gradient is not None else None
        indicators, goal_estimate = estimate.patch, None
        if goals is not None:  # the dual-weighted product of the two solutions' indicators
            weights = goals_of.goal_weights(solution, goals) if weights is None else weights
            dual = estimate_error(goals_of.dual_problem(current, goals, weights).solve(solver=solver, tol=tol))
            indicators = np.sqrt(estimate.patch * dual.patch)
            goal_estimate = float(indicators.sum())
        reached = bool((estimate.relative if goals is None else goal_estimate) <= tolerance)
        marked = np.zeros(0, np.int64) if reached else dorfler(indicators, marking)
        history.append(AdaptiveStep(int(solution.info.free_dofs), int(current.ndof), len(current.model.patches),
                                    estimate.total, float(estimate.relative), error, len(marked),
                                    time.perf_counter() - t0, goal_estimate))
        _report(step, history[-1])
        if reached:
            reason = f"the estimate {estimate.relative if goals is None else goal_estimate:.3g} met the tolerance " \
                     f"{tolerance:g}"
            break
        if last:
            reason = (f"the budget of {int(max_unknowns):,} unknowns is used; the estimate reached "
                      f"{estimate.relative:.3g} (tolerance {tolerance:g})")
            break
        if step == max_steps:
            break
        now = int(solution.info.free_dofs)  # the budget's measure, this step
        step_to = _next_step(problem, tree, estimate, marked, refine, max_unknowns, now, predicted, indicators)
        if isinstance(step_to, str):
            reason = f"{step_to}; the estimate reached {estimate.relative:.3g} (tolerance {tolerance:g})"
            break
        # last: the budget cut the step short, the next solve is the last
        tree, current, refined, last, predicted = step_to
        history[-1] = replace(history[-1], marked=refined)
    return AdaptiveResult(solution, estimate, tuple(history), reached, reason)


def unknowns(problem) -> int:
    """The unknowns a problem solves for, counted before assembly: those its interface constraints leave, less
    those owning a DOF on a face of a Dirichlet condition (slave DOFs there, on faces a branch refines, tie
    their masters by fewer conditions than they count; the count is then an upper bound).  The budget's
    measure, the ``unknowns`` of :class:`AdaptiveStep`."""
    faces = [key for key in problem.faces_by_kind()["dirichlet"] if key[1] in FACE_AXIS]
    if not needs_constraints(problem.model, problem.spaces):
        owner, n = np.arange(problem.ndof), problem.ndof
    else:
        c = prolongation(problem.model, problem.spaces, problem.offsets, problem.weights)
        owner, n = c.dof_master, c.P.shape[1]
    dofs = [problem.spaces[pi].face_dofs(face) + problem.offsets[pi] for pi, face in faces]
    held = owner[np.concatenate(dofs)] if dofs else np.zeros(0, np.int64)
    return int(n - len(np.unique(held[held >= 0])))


def _next_step(problem, tree, estimate, marked, refine, max_unknowns, now, predicted, indicators):
    """(refinement, problem, patches refined, whether the budget cut the step, the hp predictions) of the next
    step, or why there is none (a string).

    Where refining every marked patch would exceed ``max_unknowns`` (:func:`unknowns`), the longest prefix of
    the marked patches (largest indicators first) that fits is refined (found by bisection on its length, to 2%
    of the marked patches), so that the budget is used rather than the loop stopping short of it; ``now`` the
    unknowns of the current step."""
    order = marked[np.argsort(-indicators[marked], kind="stable")]  # (the marking's, energy or goal)

    def attempt(n):
        chosen, depth = order[:n], problem.space_args[2]
        if refine == "hp":
            split, raise_ = hp.choose(tree, estimate.patch, chosen, predicted)
            new = hp.refine_hp(tree, split, raise_, depth)
            guess = hp.predictions(tree, new, estimate.patch, split, raise_, predicted)
        else:
            new, guess = tree.refined(chosen, refine, analysis_refine=depth), predicted
        if len(new.held) == n:
            return None
        nxt = problem.on(new.model())
        return new, nxt, n - len(new.held), None if max_unknowns is None else unknowns(nxt), guess

    n = len(order)
    first = attempt(n)
    if first is None:
        return (f"none of the {n} marked patches can be refined: their branch children sit on boxes that their "
                "refinement would not keep nested, or their degree is the highest (refine='p')")
    if max_unknowns is None or first[3] <= max_unknowns:
        return (*first[:3], False, first[4])
    # the budget allows part of the step: the largest-indicator prefix that fits, by bisection on its length
    # (a prefix that fits at lo, one that does not at hi), to within 2% of the marked patches
    lo, hi, best = 0, n, None
    guess = int((max_unknowns - now) / max(first[3] - now, 1) * n)
    while hi - lo > max(1, n // 50):
        mid = min(max((lo + hi) // 2 if guess is None else guess, lo + 1), hi - 1)
        trial = attempt(mid)
        if trial is not None and trial[3] <= max_unknowns:
            lo, best = mid, trial
        else:
            hi = mid
        guess = None
    if best is None:
        return f"no marked patch can be refined within max_unknowns = {int(max_unknowns):,} (now {now:,} unknowns)"
    return (*best[:3], True, best[4])


def _true_error(solution, estimate, exact_gradient) -> float:
    """The relative energy-norm error ||grad(T - T_h)||_K / ||grad T_h||_K (conductivity constant per patch)."""
    err = solution.h1_error(exact_gradient)
    k = solution.problem.conductivity.constant
    if k is None or np.ndim(k):
        raise ProblemError("the true error needs a constant isotropic conductivity (a number)")
    return float(np.sqrt(k) * err / np.sqrt(estimate.energy)) if estimate.energy > 0 else float("inf")


def _report(step: int, s: AdaptiveStep) -> None:
    if progress.active():
        import sys

        err = (f", error {s.error:.3g}" if s.error is not None else "") + \
            (f", goal {s.goal:.3g}" if s.goal is not None else "")
        print(f"[adapt {step}] {s.patches} patches, {s.unknowns:,} unknowns: estimate {s.relative:.3g}{err}, "
              f"{s.marked} marked, {s.seconds:.2f} s", file=sys.stderr, flush=True)
