"""Transient heat conduction: rho c dT/dt - div(K grad T) = f(t), with the steady problem's conditions.

:class:`TransientHeatProblem` is a :class:`iga.HeatProblem` with a volumetric heat capacity rho c (J/(m^3 K))
and an initial temperature.  Its semi-discrete system is ``M du/dt + K u = f(t)``: M the heat capacity matrix
(the mass form, :meth:`iga.HeatProblem.mass`), K and f the steady problem's stiffness (with the Robin
faces' h) and loads, on the same spaces, interface constraints and Dirichlet projection.  Condition values and
the source may change in time: a callable of ``(x, t)`` (x (N, 3) in m, t in s) instead of one of x.  The film
coefficient, the conductivity and the capacity stay constant in time (so the matrices do).

The steps are taken by :mod:`iga.heat.stepping` (theta method and variable-step BDF2, fixed or adaptive step
sizes); the result is a :class:`iga.heat.transient_solution.TransientSolution`.

Example: a bar with T = 0 at both ends starting from its first mode, sin(pi x), decays as
exp(-pi^2 t) (k = rho c = 1, L = 1).

>>> import numpy as np
>>> from geometry import primitives
>>> bar = primitives.box(degrees=(3, 1, 1))
>>> problem = TransientHeatProblem(bar, conductivity=1.0, capacity=1.0, refine=3)
>>> problem = problem.dirichlet("umin", 0.0).dirichlet("umax", 0.0)
>>> history = problem.initial(lambda x: np.sin(np.pi * x[:, 0])).solve(t_end=0.1, dt=0.005, method="bdf2")
>>> T = history.probe(np.array([[0.5, 0.5, 0.5]]))[:, 0]
>>> bool(abs(T[-1] - np.exp(-np.pi ** 2 * 0.1)) < 1e-3), len(history.times)
(True, 21)
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.errors import ProblemError
from iga.heat.coefficients import ScalarField, at_time, is_number, takes_time
from iga.heat.problem import HeatProblem
from iga.heat.solution import Solution
from iga.heat.stepping import TimeStepper

__all__ = ["TransientHeatProblem", "SCHEMES"]

#: the time schemes by name: theta of the theta method, or None for BDF2
SCHEMES = {"backward-euler": 1.0, "crank-nicolson": 0.5, "bdf2": None}


class TransientHeatProblem(HeatProblem):
    """Transient heat transfer on a patch, patches or a micro-structure: rho c dT/dt = div(K grad T) + f.

    Parameters
    ----------
    model, conductivity, degree_elevation, refine, quadrature_extra, degree, bases : as :class:`iga.HeatProblem`
        (the conductivity in W/(m K), constant in time; a k(x, T) or a (T, k) table makes every step a
        Newton solve)
    capacity : the volumetric heat capacity rho c in J/(m^3 K) (density times specific heat; steel about
        3.5e6, aluminium 2.4e6): a number, a channel name or a callable of x; must be positive
    source : W/m^3: a number, a channel name, a callable of x, or a callable of (x, t)

    The conditions (:meth:`dirichlet`, :meth:`neumann`, :meth:`robin`) are the steady problem's; their values
    may also be callables of (x, t).  Set the temperature at the start with :meth:`initial`, then
    :meth:`solve`.
    """

    def __init__(self, model, conductivity=1.0, capacity=1.0, source=0.0, degree_elevation=0, refine: int = 0,
                 quadrature_extra: int = 0, degree=None, bases=None):
        timed = takes_time(source)
        super().__init__(model, conductivity, 0.0 if timed else source, degree_elevation, refine,
                         quadrature_extra, degree, bases)
        if takes_time(capacity):
            raise ProblemError("capacity must not depend on time (got a callable of (x, t)); give a number, a "
                               "channel or a callable of x in J/(m^3 K)")
        self.capacity = ScalarField(capacity, "heat capacity rho c (J/(m^3 K))", positive=True, model=self.model)
        if timed:
            at_time(source, 0.0, "source", self.model)  # the kind of value is checked now, its values per step
        #: the source as a callable of (x, t), or None when it is constant in time (then ``source`` holds it)
        self.timed_source = source if timed else None
        #: the initial state: (time in s, a number, a callable of x or a steady Solution), set by initial()
        self.start = None

    # ------------------------------------------------------------ conditions
    def _condition(self, kind, tag, value, h=None) -> "TransientHeatProblem":
        if not takes_time(value):
            return super()._condition(kind, tag, value, h)
        super()._condition(kind, tag, lambda x: np.zeros(len(x)), h)  # the tag and kind checked as usual
        self.conditions[-1].timed = value
        return self

    def robin(self, tag: str, h, ambient) -> "TransientHeatProblem":
        """Convection -k dT/dn = h (T - ambient) on ``tag``; h in W/(m^2 K) (> 0, constant in time), the ambient
        temperature a number, a callable of x or of (x, t)."""
        if takes_time(h):
            raise ProblemError(f"the film coefficient h on {show(tag)} must not depend on time (the matrix would "
                               "change every step); give a number or a callable of x in W/(m^2 K)")
        return super().robin(tag, h, ambient)

    def radiation(self, tag: str, emissivity, ambient, scale: str = "K") -> "TransientHeatProblem":
        """Radiation as :meth:`iga.HeatProblem.radiation` (the ambient may be a callable of (x, t), the
        emissivity is constant in time); every step is then solved by Newton's method."""
        if takes_time(emissivity):
            raise ProblemError(f"the emissivity on {show(tag)} must not depend on time; give a number or a "
                               "callable of x")
        return super().radiation(tag, emissivity, ambient, scale)

    def conditions_at(self, t: float) -> dict:
        """The conditions by kind and face (as :meth:`iga.HeatProblem.faces_by_kind`) with the values of those
        that change in time taken at ``t`` (s)."""
        by_kind = self.faces_by_kind()
        now: dict = {}
        for faces in by_kind.values():
            for key, c in faces.items():
                if c.timed is None:
                    continue
                if id(c) not in now:  # one field per condition, shared by its faces
                    what = {"dirichlet": "Dirichlet value", "neumann": "Neumann flux",
                            "robin": "ambient temperature", "radiation": "radiation's ambient temperature"}[c.kind]
                    now[id(c)] = type(c)(c.kind, c.tag, at_time(c.timed, t, f"{what} on {show(c.tag)}",
                                                                 channels=False), c.h, offset=c.offset)
                faces[key] = now[id(c)]
        return by_kind

    @property
    def changes_in_time(self) -> bool:
        """Whether the source or some condition's value is a callable of (x, t)."""
        return self.timed_source is not None or any(c.timed is not None for c in self.conditions)

    # ------------------------------------------------------------- the start
    def initial(self, temperature, time: float = 0.0) -> "TransientHeatProblem":
        """The temperature at the start ``time`` (s): a number (K or C), a callable of x, or a steady
        :class:`iga.Solution` of a problem on this model and these spaces (its coefficients are taken as they
        are).  A number or callable is projected (L2, with the capacity as weight) into the space, the
        Dirichlet values at the start time replacing it where they apply."""
        if not (is_number(time) and np.isfinite(time)):
            raise ProblemError(f"the start time must be a finite number of seconds, got {show(time)}")
        if isinstance(temperature, Solution):
            other = temperature.problem
            if other.model is not self.model:
                raise ProblemError("the initial state is a solution on another model object; solve the steady "
                                   "problem on the model this problem was built on (HeatProblem(problem.model, "
                                   "...)), or give a number or a callable of x")
            if other.ndof != self.ndof or not np.array_equal(other.offsets, self.offsets):
                raise ProblemError(
                    f"the initial state is a solution in another space ({other.ndof} coefficients against "
                    f"{self.ndof} here); solve the steady problem with this problem's degree_elevation, refine and "
                    "degree, or give a number or a callable of x")
        elif takes_time(temperature):
            raise ProblemError("the initial temperature is a callable of (x, t); give a callable of x (the "
                               "temperature at the start time), a number or a steady Solution")
        else:
            ScalarField(temperature, "initial temperature", model=self.model, channels=False)
        self.start = (float(time), temperature)
        return self

    # ------------------------------------------------------------------ solve
    def solve(self, t_end: float | None = None, dt: float | None = None, method: str = "bdf2", tol: float | None = None,
              theta: float | None = None, solver: str = "auto", solver_tol: float = 1e-10, keep: int = 1,
              max_steps: int = 100_000, until=None):
        """Step from the initial state to ``t_end`` (s); returns a
        :class:`iga.heat.transient_solution.TransientSolution`.

        ``dt``: the step (s); with ``tol`` (K, the local error allowed per step) the steps adapt to it and
        ``dt`` is the first one (default: the step over which the initial rate changes no coefficient by more
        than ``tol``, at most 1e-4 of the interval).  ``method``: ``"bdf2"`` (order 2, damps
        stiff modes), ``"crank-nicolson"`` (order 2, undamped), ``"backward-euler"`` (order 1) or ``"theta"``
        with ``theta`` in [1/2, 1].  ``solver``: ``auto``, ``direct``, ``amg-cg`` or ``cg`` (prepared once
        per step size, :func:`solvers.prepare`), ``solver_tol`` the relative residual of the iterative ones.
        ``keep``: every ``keep``-th step is kept (and the last), for :meth:`at`, probes and the ParaView
        series; ``max_steps``: the most steps taken before the solve is refused as too fine; ``until(t, u)``:
        a callable of the time (s) and the coefficients (ndof,) after each step; the solve stops at the first
        step where it is true (``record.stopped``), e.g. when a probe (:meth:`probe_matrix`) reaches a value.
        """
        if self.start is None:
            raise ProblemError("the transient problem has no initial temperature; call problem.initial(T0) (a "
                               "number, a callable of x or a steady Solution) before solve")
        t0 = self.start[0]
        if t_end is None:
            raise ProblemError("give the end time t_end (s) of the transient solve (a steady state is "
                               "HeatProblem(...).solve(), or t_end with until= to stop when it is reached)")
        if not (is_number(t_end) and np.isfinite(t_end)) or t_end <= t0:
            raise ProblemError(f"t_end must be a time after the start ({t0:g} s), got {show(t_end)}")
        if dt is not None and not (is_number(dt) and np.isfinite(dt) and dt > 0):
            raise ProblemError(f"dt must be a positive number of seconds, got {show(dt)}")
        if tol is not None and not (is_number(tol) and np.isfinite(tol) and tol > 0):
            raise ProblemError(f"tol must be a positive temperature (the local error allowed per step), got "
                               f"{show(tol)}")
        if dt is None and tol is None:
            raise ProblemError("give the step dt (s), or tol (K) for adaptive steps")
        if method == "theta":
            if not (is_number(theta) and 0.5 <= theta <= 1):
                raise ProblemError(f"method 'theta' needs theta in [0.5, 1] (0.5 Crank-Nicolson, 1 backward Euler; "
                                   f"below 0.5 the scheme is unstable), got {show(theta)}")
        elif method not in SCHEMES:
            raise ProblemError(f"unknown time scheme {show(method)}; choose one of {sorted(SCHEMES) + ['theta']}")
        elif theta is not None:
            raise ProblemError(f"theta is the parameter of method='theta', not of {method!r}")
        for name, value, low in (("keep", keep, 1), ("max_steps", max_steps, 1)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ProblemError(f"{name} must be an integer >= {low}, got {show(value)}")
        if until is not None and not callable(until):
            raise ProblemError(f"until must be a callable of (t, u) returning True to stop, got {show(until)}")
        return TimeStepper(self, method, theta if method == "theta" else SCHEMES[method], solver,
                           solver_tol).run(float(t_end), dt, tol, int(keep), int(max_steps), until=until)
