"""Time steps of ``M du/dt + K u = f(t)`` with the constraints and Dirichlet data ``u = P_f x + g(t)``.

Each scheme is written for the full coefficient vector and projected by ``P_f^T``, so Dirichlet values that
change in time enter as in any unconstrained code, and the interface constraints hold at every step:

* theta method: ``(M / h + theta K) u1 = M u0 / h - (1 - theta) (K u0 - f0) + theta f1``; backward Euler
  (theta = 1, order 1) and Crank-Nicolson (theta = 1/2, order 2);
* BDF2 with variable steps (ratio w = h_n / h_(n-1)): ``M (a0 u1 + a1 u0 + a2 u_-1) / h + K u1 = f1`` with
  a0 = (1 + 2w) / (1 + w), a1 = -(1 + w), a2 = w^2 / (1 + w) (order 2); its first step is Crank-Nicolson
  (order 2 as well: a backward Euler start made the error of the decaying mode of the tests 3x larger; the
  modes an inconsistent start leaves undamped in that one step are damped by the BDF2 steps after it).

The matrix of a step, ``c_M M_r + c_K K_r`` (reduced), is the same for every step of one size: it is prepared
once (:func:`solvers.prepare`: a factorisation, or an AMG hierarchy whose CG starts from the extrapolated
state) and kept while the size is used (the last two sizes are kept).

Adaptive steps control the local error of each step, estimated from divided differences of the last states
(a variable-step form of the schemes' leading error terms: h^2/2 |u''| for backward Euler, h^3/12 |u'''| for
Crank-Nicolson, (1 + w)^2 / (1 + 2w) h^3 |u'''| / 6 for BDF2), in the largest coefficient (K).  A step above
the tolerance is taken again shorter; the size grows (at most x2) only when the estimate allows 25% more, and
otherwise stays, so the prepared solver is reused.  The tolerance bounds each step's error, not the end's: on
a dissipative problem the error at the end is at most the sum of the steps' errors (the tests measure it
below steps x tol).

With radiating faces or a temperature-dependent conductivity, K u becomes A(u) (:meth:`TimeStepper.operator`)
and every step is a Newton solve of ``c_M M u1 + c_K A(u1) = rhs`` from the extrapolated state, its tangent
(:meth:`TimeStepper.tangent`) solved afresh each iteration (symmetric for radiation, unsymmetric with k(T)).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import solvers
from geometry.numbers import TINY
from geometry import progress
from geometry.resources import check_memory, memory_limit
from solvers.prepared import factor_bytes

from iga.discretisation.components import model_components
from iga.discretisation.constraints import owners_of, prolongation
from iga.discretisation.dirichlet import project_dirichlet
from iga.discretisation.system import project_symmetric, reduction
from iga.errors import ProblemError
from iga.heat.coefficients import ScalarField, at_time
from iga.heat.nonlinear import tangent_forms
from iga.heat.radiation import RadiationFaces

__all__ = ["TimeStepper", "StepRecord"]

#: a step's size may grow to this factor of the last one (and is cut to no less than 1/5 on a rejection)
_GROW, _SHRINK = 2.0, 0.2
#: mass-like systems (the initial projection and rate, solved once or twice) are factorised up to this many
#: unknowns and solved by Jacobi-CG above (a few dozen iterations: the scaled mass matrix is well conditioned)
_MASS_DIRECT = 20_000
#: safety factor on the step size the error estimate proposes; sizes within [1, _KEEP) of it stay unchanged
_SAFETY, _KEEP = 0.9, 1.25


@dataclass
class StepRecord:
    """What a transient solve did: steps taken and rejected, the prepared solvers (one per step size used),
    iterations of the linear solves, the largest local error estimate accepted (K; None for fixed steps),
    Newton's residuals, where an ``until`` condition stopped it, and seconds per stage (``setup``: assembly,
    constraints and the initial state; ``steps``)."""

    method: str
    steps: int = 0
    rejected: int = 0
    prepared: int = 0
    iterations: int = 0
    solver: str = ""
    largest_estimate: float | None = None
    #: Newton's relative residuals, iteration after iteration over the steps (radiation, k(T)), else empty
    newton: list = field(default_factory=list)
    #: the time at which the solve's ``until`` condition held and the run stopped, None if it ran to the end
    stopped: float | None = None
    timings: dict = field(default_factory=dict)


class TimeStepper:
    """The stepping of one :class:`iga.heat.transient.TransientHeatProblem` with one scheme (``theta`` in
    [1/2, 1], or None for BDF2)."""

    def __init__(self, problem, method: str, theta: float | None, solver: str, solver_tol: float):
        t_start = time.perf_counter()
        self.problem, self.method, self.theta = problem, method, theta
        self.solver, self.solver_tol = solver, solver_tol
        p = problem
        #: k(T): the diffusion form changes with the temperature (iga.heat.nonlinear); K holds the Robin mass only
        self.k_of_T = p.conductivity.of_temperature is not None
        if self.k_of_T:
            f_vol, total = p.volume.load(p.source)
            loads, robin, book = p.face_terms(p.faces_by_kind())
            f, book["source"] = f_vol + loads, total
            self.K = robin if robin is not None else sp.csr_matrix((p.ndof, p.ndof))
        else:
            self.K, f, book = p.assemble()
        self.M = p.volume.mass(p.capacity)
        self.constraints = prolongation(p.model, p.spaces, p.offsets, p.weights) if p._needs_constraints() else None
        self.P = sp.identity(p.ndof, format="csr") if self.constraints is None else self.constraints.P
        # the coupled pieces (for the states' info; a transient piece needs no condition: its capacity holds it)
        self.components = model_components(p, None if self.constraints is None else self.P, p.faces_by_kind())
        self._static = None if p.changes_in_time else (f, book)
        self._volume, self._recent = None, {}
        if p.changes_in_time:  # the volume source's load, kept when it is constant in time
            self._volume = None if p.timed_source is not None else p.volume.load(p.source)
        t0 = p.start[0]
        f0, book0 = self.loads(t0)
        dd = self.dirichlet(book0)
        self.Pf, offset0, self.reaction_dofs, _ = reduction(self.constraints, dd, p.ndof)
        self._offset = None if p.changes_in_time else offset0
        self.dirichlet_data = dd
        Pf = self.Pf
        self.Kr = project_symmetric(self.K, Pf)
        self.Mr = project_symmetric(self.M, Pf)
        self._prepared: dict = {}
        self._mass = None
        self.record = StepRecord(method=method)
        u0, self.x_start = self._initial(offset0)
        self.record.timings["setup"] = time.perf_counter() - t_start
        self.first = (t0, u0, f0, offset0)

    # ----------------------------------------------------------------- data in time
    def loads(self, t: float):
        """(f (ndof,), bookkeeping of :meth:`iga.HeatProblem.face_terms` with ``source``) at time ``t``."""
        if self._static is not None:
            return self._static
        if t in self._recent:
            return self._recent[t]
        p = self.problem
        f_faces, _, book = p.face_terms(p.conditions_at(t))
        if p.timed_source is not None:
            f_vol, total = p.volume.load(at_time(p.timed_source, t, "source", p.model))
        else:
            f_vol, total = self._volume
        book["source"] = total
        if len(self._recent) >= 3:  # a step reads its two ends: the last few times are kept
            self._recent.pop(next(iter(self._recent)))
        self._recent[t] = (f_vol + f_faces, book)
        return self._recent[t]

    def dirichlet(self, book):
        """The projected Dirichlet data of a bookkeeping (:func:`iga.discretisation.dirichlet.project_dirichlet`)."""
        p = self.problem
        return project_dirichlet(p.faces, book["dirichlet"], p.ndof, self.constraints)

    def offset(self, book) -> np.ndarray:
        """g(t): the prescribed part of u at the time of ``book`` (zero rows where nothing is prescribed)."""
        if self._offset is not None:  # nothing changes in time
            return self._offset
        return reduction(self.constraints, self.dirichlet(book), self.problem.ndof)[1]

    def _initial(self, offset0: np.ndarray):
        """(u, x) at the start: a steady solution's coefficients, or the projection of a number or callable
        weighted by the capacity (the heat content int rho c T0 dV is kept) with the Dirichlet values of the
        start time."""
        p = self.problem
        spec = p.start[1]
        if hasattr(spec, "problem"):  # a steady Solution of this model and space (checked by initial())
            u = np.array(spec.u, float)
            G = self.Pf.T @ self.Pf  # each column of Pf spreads one unknown: x = (Pf^T Pf)^-1 Pf^T (u - g)
            return u, _mass_like(sp.csr_matrix(G))(np.asarray(self.Pf.T @ (u - offset0)))[0]
        T0 = ScalarField(spec, "initial temperature", model=p.model, channels=False)
        b, _ = p.volume.load(_Product(T0, p.capacity))
        x = self._mass_solve(self.Pf.T @ (b - self.M @ offset0))
        return self.Pf @ x + offset0, x

    # ----------------------------------------------------------------- one step
    def _solver(self, cM: float, cK: float):
        """The prepared solver of cM M_r + cK K_r (kept for the last two step sizes)."""
        key = (cM, cK)
        if key not in self._prepared:
            if len(self._prepared) >= 2:
                self._prepared.pop(next(iter(self._prepared)))
            A = (cM * self.Mr + cK * self.Kr).tocsr()
            self._prepared[key] = solvers.prepare(A, self._method(A), self.solver_tol)
            self.record.prepared += 1
            self.record.solver = self._prepared[key].name
        return self._prepared[key]

    def _method(self, A) -> str:
        """The solver of a step matrix: the one asked for; ``auto`` factorises where the factors fit a quarter
        of the memory budget (:func:`solvers.prepared.factor_bytes`) and uses AMG-CG otherwise."""
        if self.solver == "auto" and factor_bytes(A.shape[0]) > 0.25 * memory_limit():
            return "amg-cg"
        return self.solver

    def operator(self, u: np.ndarray, book) -> np.ndarray:
        """A(u) (ndof,) with M du/dt + A(u) = f: K u (diffusion and Robin), the diffusion with k at the
        temperature u (k(T), :func:`iga.heat.nonlinear.tangent_forms`) and the heat radiated away at the time of
        ``book`` (:mod:`iga.heat.radiation`)."""
        out = self.K @ u
        if self.k_of_T:
            out = out + tangent_forms(self.problem, u, derivative=False)[0] @ u
        if book["radiation"]:
            out = out + RadiationFaces.of(self.problem, book).load(u, self.problem.ndof)
        return out

    def tangent(self, u: np.ndarray, book):
        """dA/du (CSR): K, the k(T) diffusion and its first-order term, and the radiation's tangent."""
        J = self.K
        if self.k_of_T:
            Kt, Ct = tangent_forms(self.problem, u)
            J = J + Kt + Ct
        if book["radiation"]:
            J = J + RadiationFaces.of(self.problem, book).tangent(u, self.problem.ndof)
        return J.tocsr()

    def step(self, h: float, t1: float, hist: list) -> tuple:
        """One step of size ``h`` to ``t1`` from ``hist`` (the last states, newest last: (t, u, v, x, h)):
        returns (u1, v1 (du/dt at t1), x1 (reduced unknowns))."""
        t0, u0, v0, x0, h0 = hist[-1]
        f1, book1 = self.loads(t1)
        g1 = self.offset(book1)
        M, K = self.M, self.K
        bdf2 = self.theta is None and len(hist) >= 2
        if bdf2:
            w = h / h0
            a0, a1, a2 = (1 + 2 * w) / (1 + w), -(1 + w), w * w / (1 + w)
            um1 = hist[-2][1]
            cM, cK = a0 / h, 1.0
            rhs = f1 - M @ ((a1 * u0 + a2 * um1) / h)
        else:
            th = 0.5 if self.theta is None else self.theta
            f0, book0 = self.loads(t0)
            cM, cK = 1.0 / h, th
            rhs = M @ (u0 / h) + th * f1
            if th < 1:
                rhs -= (1 - th) * (self.operator(u0, book0) - f0)
        guess = x0 if len(hist) < 2 or hist[-2][3] is None else x0 + (x0 - hist[-2][3]) * (h / h0)
        if book1["radiation"] or self.k_of_T:  # cM M u1 + cK A(u1) = rhs: Newton's method from the guess
            x1 = self._newton(cM, cK, rhs, g1, book1, guess)
        else:
            x1, info = self._solver(cM, cK)(self.Pf.T @ (rhs - cM * (M @ g1) - cK * (K @ g1)), guess)
            self.record.iterations += int(info.iterations)
        u1 = self.Pf @ x1 + g1
        if bdf2:
            v1 = (a0 * u1 + a1 * u0 + a2 * um1) / h
        else:
            v1 = ((u1 - u0) / h - (1 - th) * v0) / th
        return u1, v1, x1

    def _newton(self, cM: float, cK: float, rhs: np.ndarray, g1: np.ndarray, book, x: np.ndarray) -> np.ndarray:
        """The reduced unknowns of a nonlinear step, cM M u + cK A(u) = rhs with u = Pf x + g1, by Newton's
        method from ``x``; the tangent (:meth:`tangent`) changes every iteration, so its matrix is solved
        afresh: by the step's solver where it is symmetric (radiation), by a sparse LU where k(T) makes it
        unsymmetric.  Converged at ``solver_tol`` (at most 1e-11) of the right-hand side."""
        Pf = self.Pf
        scale = max(float(np.linalg.norm(Pf.T @ rhs)), TINY)
        for _ in range(50):
            u = Pf @ x + g1
            r = np.asarray(Pf.T @ (cM * (self.M @ u) + cK * self.operator(u, book) - rhs))
            self.record.newton.append(float(np.linalg.norm(r)) / scale)
            if self.record.newton[-1] <= min(self.solver_tol, 1e-11):  # (the flows are small against rhs)
                return x
            J = (Pf.T @ ((cM * self.M + cK * self.tangent(u, book)) @ Pf)).tocsr()
            if self.k_of_T:
                dx = spla.splu(J.tocsc()).solve(-r)
            else:
                dx, info = solvers.prepare(J, self._method(J), self.solver_tol)(-r)
                self.record.iterations += int(info.iterations)
            x = x + dx
        raise ProblemError(f"Newton's method for the radiation did not converge in a step (relative residuals "
                           f"{[f'{v:.1e}' for v in self.record.newton[-4:]]}); take shorter steps (dt or tol)")

    def _estimate(self, hist: list) -> float | None:
        """The local error (K) of the newest step in ``hist``, or None before enough steps exist."""
        order = 1 if self.theta == 1.0 else 2
        if len(hist) < order + 2:
            return None
        ts = [s[0] for s in hist[-(order + 2):]]
        xs = [s[3] for s in hist[-(order + 2):]]
        dd = _divided_difference(ts, xs)  # u^(order+1) / (order+1)!
        h = ts[-1] - ts[-2]
        if order == 1:  # h^2 / 2 |u''| = h^2 |DD2|
            c = h * h
        elif self.theta is not None:  # Crank-Nicolson: h^3 / 12 |u'''| = h^3 / 2 |DD3|
            c = 0.5 * h ** 3
        else:  # BDF2: (1 + w)^2 / (1 + 2w) h^3 / 6 |u'''| = (1 + w)^2 / (1 + 2w) h^3 |DD3|
            w = h / (ts[-2] - ts[-3])
            c = (1 + w) ** 2 / (1 + 2 * w) * h ** 3
        return float(c * np.abs(dd).max()) if len(dd) else 0.0

    # ----------------------------------------------------------------- the loop
    def run(self, t_end: float, dt: float | None, tol: float | None, keep: int, max_steps: int, on_step=None,
            until=None):
        """Step to ``t_end``; returns the :class:`iga.heat.transient_solution.TransientSolution`.
        ``on_step(n, t, seconds)``: called after each accepted step (its number, time and wall time);
        ``until(t, u)``: the run stops after the first step for which it is true (``record.stopped``)."""
        from iga.heat.transient_solution import TransientSolution

        t_start = time.perf_counter()
        t0, u0, f0, g0 = self.first
        span = t_end - t0
        h = dt if dt is not None else 1e-4 * span
        x0 = self.x_start
        v0 = self._initial_rate(t0, u0, f0, g0, h)
        if dt is None:  # the first step changes no temperature by more than tol at the initial rate
            rate = float(np.abs(self.Pf.T @ v0).max()) if len(x0) else 0.0
            h = min(h, tol / rate) if rate > 0 else h
        hist = [(t0, u0, v0, x0, h)]
        kept = [(t0, u0, v0)]
        if dt is not None and tol is None:  # the kept states' memory, before the first step
            self._check_kept(int(np.ceil(span / dt)) // keep + 2, keep)
        n = 0
        bar = progress.bar(None, total=None, desc=f"{self.method} steps", unit="step", min_items=0) \
            if progress.active() else None
        try:
            while t_end - hist[-1][0] > 1e-12 * span:
                t = hist[-1][0]
                h, t1 = _landing(t, h, t_end, span, tol is not None)
                if n >= max_steps:
                    raise ProblemError(f"the transient solve took {max_steps} steps and reached t = {t:g} s of "
                                       f"{t_end:g} s; raise max_steps, loosen tol or take a larger dt")
                clock = time.perf_counter()
                u1, v1, x1 = self.step(h, t1, hist)
                hist.append((t1, u1, v1, x1, h))
                est = self._estimate(hist) if tol is not None else None
                if est is not None and est > tol:  # rejected: again, shorter
                    hist.pop()
                    h = self._shorter(h, est, tol, t, span, max_steps)
                    continue
                n += 1
                if est is not None:
                    self.record.largest_estimate = max(self.record.largest_estimate or 0.0, est)
                    proposal = h * min(_GROW, _SAFETY * (tol / max(est, TINY)) ** (1.0 / (self._order() + 1)))
                    h = proposal if proposal >= _KEEP * h else h  # grown by a margin only: its solver is reused
                hist = hist[-4:]
                if n % keep == 0:
                    kept.append(hist[-1][:3])
                    if len(kept) & (len(kept) - 1) == 0:  # adaptive steps: checked as the count doubles
                        self._check_kept(2 * len(kept), keep)
                if bar is not None:
                    bar.update(1)
                if on_step is not None:
                    on_step(n, hist[-1][0], time.perf_counter() - clock)
                if until is not None and until(hist[-1][0], u1):
                    self.record.stopped = float(hist[-1][0])
                    break
        finally:
            if bar is not None:
                bar.close()
        if kept[-1][0] != hist[-1][0]:
            kept.append(hist[-1][:3])
        self.record.steps = n
        self.record.timings["steps"] = time.perf_counter() - t_start
        self._prepared.clear()  # the factors are not kept with the result (1.7 GB at 349k unknowns)
        self._mass = None
        return TransientSolution(self, kept)

    def _shorter(self, h: float, est: float, tol: float, t: float, span: float, max_steps: int) -> float:
        """The step after a rejected one of size ``h`` (its estimate ``est`` above ``tol``); refused once the
        step has shrunk to nothing or the rejections exceed ``max_steps``."""
        self.record.rejected += 1
        h *= max(_SHRINK, _SAFETY * (tol / est) ** (1.0 / (self._order() + 1)))
        if h < 1e-12 * span or self.record.rejected > max_steps:
            raise ProblemError(f"the transient solve cannot meet tol = {tol:g} K at t = {t:g} s (the step shrank "
                               f"to {h:.3g} s after {self.record.rejected} rejected steps); loosen tol, or check "
                               "the data for a jump in time")
        return h

    def _check_kept(self, count: int, keep: int) -> None:
        """Refuse before ``count`` kept states (u and du/dt, 16 bytes per coefficient) exceed the memory budget."""
        check_memory(16.0 * self.problem.ndof * count, f"keeping {count} states of the transient solve",
                     ProblemError, hint=f"keep fewer (keep={keep * max(2, count // 1000)} keeps every "
                     f"{keep * max(2, count // 1000)}-th step)")

    def _order(self) -> int:
        return 1 if self.theta == 1.0 else 2

    def _initial_rate(self, t0, u0, f0, g0, h) -> np.ndarray:
        """du/dt at the start: M v0 = f0 - K u0 on the free unknowns, the Dirichlet values' rate (a difference
        over the first step) on the prescribed ones."""
        rhs = f0 - self.operator(u0, self.loads(t0)[1])
        gdot = (self.offset(self.loads(t0 + h)[1]) - g0) / h if self.problem.changes_in_time else 0.0 * g0
        return self.Pf @ self._mass_solve(self.Pf.T @ (rhs - self.M @ gdot)) + gdot

    def _mass_solve(self, b: np.ndarray) -> np.ndarray:
        """x with M_r x = b (the initial projection and rate), M_r prepared once: factorised up to
        :data:`_MASS_DIRECT` unknowns, Jacobi-CG to 1e-13 above (a mass matrix is
        well conditioned once its diagonal is scaled)."""
        if self._mass is None:
            self._mass = _mass_like(self.Mr)
        return self._mass(np.asarray(b, float))[0]

    # ----------------------------------------------------------------- a state's flows
    def reaction(self, t: float, u: np.ndarray, v: np.ndarray):
        """(reaction on the prescribed unknowns, their values or None, f (ndof,), bookkeeping) at a kept state:
        the consistent boundary flow ``P^T (M v + K u - f)`` that the steady solve reports as ``K u - f``."""
        f, book = self.loads(t)
        r = self.P.T @ (self.M @ v + self.operator(u, book) - f)
        dofs = self.reaction_dofs
        if self.constraints is None:
            prescribed = u[dofs]
        else:
            owner = owners_of(self.constraints.dof_master, self.P.shape[1])[dofs]
            prescribed = u[owner] if np.all(owner >= 0) else None
        return r[dofs], prescribed, f, book


def _landing(t: float, h: float, t_end: float, span: float, adaptive: bool) -> tuple[float, float]:
    """(h, t1): the step from ``t`` and its end, landing on ``t_end``: a step within rounding of the rest
    keeps its size (and its prepared solver) and ends exactly there; with adaptive steps, a rest shorter than
    two steps is taken in two equal ones rather than a step and a sliver."""
    rest = t_end - t
    if abs(rest - h) <= 1e-9 * span:
        return h, t_end
    if adaptive and h < rest < 2 * h:
        return 0.5 * rest, t + 0.5 * rest
    if rest < h:
        return rest, t_end
    return h, t + h


def _mass_like(A):
    """A prepared solver of a mass-like matrix to 1e-13: factorised up to :data:`_MASS_DIRECT` unknowns,
    Jacobi-CG above."""
    return solvers.prepare(A, "direct" if A.shape[0] <= _MASS_DIRECT else "cg", 1e-13)


class _Product:
    """The product of two scalar fields, evaluated as one (``values(x, chans, where)``)."""

    kind, constant = "callable", None

    def __init__(self, a, b):
        self.a, self.b = a, b

    def values(self, x, chans, where) -> np.ndarray:
        return self.a.values(x, chans, where) * self.b.values(x, chans, where)


def _divided_difference(ts, xs) -> np.ndarray:
    """The highest divided difference of states ``xs`` at times ``ts`` (len k + 1 gives the k-th)."""
    table = [np.asarray(x, float) for x in xs]
    for k in range(1, len(ts)):
        table = [(table[i + 1] - table[i]) / (ts[i + k] - ts[i]) for i in range(len(table) - 1)]
    return table[0]
