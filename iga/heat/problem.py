"""Steady heat conduction: -div(K grad T) = f with Dirichlet, Neumann and Robin faces.

Units are the user's, consistently: with lengths in m, conductivity in
W/(m K), sources in W/m^3, fluxes in W/m^2 and film coefficients in
W/(m^2 K), temperatures are in K (or degrees C) and heat flows in W.

:class:`HeatProblem` composes the weak form (:mod:`iga.heat.forms`; Massarwi et al.
2018, Eq. 9) from its pieces: the diffusion and source forms over the volume
(:class:`iga.heat.volume.VolumeAssembler`), the Neumann and Robin forms over faces
(:class:`iga.discretisation.faces.FaceQuadrature`), the Dirichlet data by L2 projection
(:mod:`iga.discretisation.dirichlet`), and the interface constraints and the reduced solve
(:mod:`iga.discretisation.constraints`, :mod:`iga.discretisation.system`).  Each patch uses its own B-spline
basis (Massarwi et al. 2018, Remark 2), optionally elevated and refined.
"""

from __future__ import annotations

import time

import numpy as np


from iga.heat.coefficients import Conductivity, ScalarField, is_number
from iga.discretisation.components import analyse_components
from iga.discretisation.constraints import needs_constraints, prolongation
from iga.discretisation.dirichlet import project_dirichlet
from iga.discretisation.fields import evaluation_matrix
from iga.discretisation.locate import Locator
from iga.discretisation.problem import Problem, SolveRecord
from iga.discretisation.setting import count
from iga.errors import ProblemError
from iga.discretisation.faces import FaceData
from iga.assembly.tensor import add_within
from iga.heat.conditions import Condition, face_terms, face_values, refuse_floating
from iga.heat.radiation import RadiationFaces, solve_radiation
from iga.heat.nonlinear import solve_temperature_dependent
from iga.model import tag_faces
from iga.distributed.rank_setup import rank_setup
from iga.tags import as_expression, condition_faces, mentions_rest
from iga.heat.solution import Solution
from iga.distributed import solve as distributed
from iga.discretisation.multilevel import solver_options
from iga.discretisation.system import solve_system
from geometry.errors import show

__all__ = ["HeatProblem"]


class HeatProblem(Problem):
    """Steady heat transfer on a trivariate patch, a list of patches or a micro-structure.

    Parameters
    ----------
    model : BSpline, list of BSpline (conforming shared faces are coupled), or a
        model such as ``tiling.Microstructure``
    conductivity : W/(m K): a number, a channel name, a callable ``k(x (N, 3)) -> (N,)``,
        a constant symmetric positive definite 3 x 3 matrix, six channel names
        (xx, yy, zz, xy, xz, yz) or a callable returning (N, 3, 3); must be positive (definite).
        Temperature-dependent: a callable ``k(x, T)`` (T (N,) the temperature) or a table of rows
        (T, k) (interpolated monotonically, PCHIP); the solve is then Newton's (:mod:`iga.heat.nonlinear`)
    source : W/m^3: a number, a channel name or a callable ``f(x) -> (N,)``
    degree_elevation, refine : applied to every patch's solution space
        (degree + ``degree_elevation``, an int or one per direction, then
        ``refine`` rounds of knot-span bisection)
    degree : optional solution degrees (int or three) replacing patch degree +
        elevation; continuity at each knot is kept, capped at C^(p-1)
    quadrature_extra : Gauss points per element and direction beyond ``p + 1``
    bases : optional per patch ``(knots, degrees)`` of the solution basis before elevation and
        refinement, instead of the patch geometry's own (a file of composed geometry analysed in the
        tiles' bases, :func:`iga.io.gismo.problem_from_gismo`); same parameter domains

    Boundary conditions refer to the model's tags (``umin`` .. ``wmax``,
    ``boundary``, and for micro-structures ``branch-in``, ``internal`` and user
    tags); faces with no condition are insulated.

    Example: a unit cube between 0 and 1 degree has a linear temperature.

    >>> import numpy as np
    >>> from geometry import primitives
    >>> problem = HeatProblem(primitives.box(degrees=(2, 2, 2)), conductivity=3.0)
    >>> solution = problem.dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    >>> round(float(solution.probe(np.array([[0.25, 0.5, 0.5]]))[0]), 12)
    0.25
    >>> round(solution.flux("umax"), 9)  # W, outward: 3 W/(m K) x 1 K/m x 1 m^2 flows in
    -3.0
    """

    def __init__(self, model, conductivity=1.0, source=0.0, degree_elevation=0, refine: int = 0,
                 quadrature_extra: int = 0, degree=None, bases=None):
        super().__init__(model, degree_elevation, refine, quadrature_extra, degree, bases)
        self.conductivity = Conductivity(conductivity, self.model)
        self.source = ScalarField(source, "source", model=self.model)
        self.conditions: list[Condition] = []

    def on(self, model) -> "HeatProblem":
        """This problem set up again on another ``model`` with the same tags and channels (refined, redesigned):
        the same coefficients, conditions, and solution degree and refinement of every patch."""
        quadrature_extra, degree_elevation, refine, degree = self.space_args
        new = type(self)(model, 1.0, 0.0, degree_elevation, refine, quadrature_extra, degree)
        new.conductivity, new.source, new.conditions = self.conductivity, self.source, list(self.conditions)
        return new

    # ------------------------------------------------------------ conditions
    def _condition(self, kind, tag, value, h=None) -> "HeatProblem":
        tag = as_expression(tag)
        self.faces_of(tag, kind)
        what = {"dirichlet": "Dirichlet value", "neumann": "Neumann flux", "robin": "ambient temperature",
                "radiation": "radiation's ambient temperature"}[kind]
        field = ScalarField(value, f"{what} on {show(tag)}", model=self.model, channels=False)
        self.conditions.append(Condition(kind, tag, field, h))
        return self

    def dirichlet(self, tag: str, value=0.0) -> "HeatProblem":
        """Prescribed temperature on the faces tagged ``tag`` (number or callable of x)."""
        return self._condition("dirichlet", tag, value)

    def neumann(self, tag: str, flux) -> "HeatProblem":
        """Inward heat flux q (W/m^2; q > 0 heats the body) on the faces tagged ``tag``."""
        return self._condition("neumann", tag, flux)

    def radiation(self, tag: str, emissivity, ambient, scale: str = "K") -> "HeatProblem":
        """Radiation from the faces tagged ``tag`` to surroundings at ``ambient``: an outward flux
        sigma eps (T^4 - T_amb^4) W/m^2 (Stefan-Boltzmann), with the emissivity eps in [0, 1] (a number or a
        callable of x).  ``scale``: the problem's temperatures are in ``"K"`` or ``"C"`` (then 273.15 is
        added before the fourth power).  Makes the problem nonlinear: :meth:`solve` runs Newton's method
        (:mod:`iga.heat.radiation`) and reports its residuals in ``info["newton"]``.  A face may radiate and
        convect (Robin) at once."""
        if scale not in ("K", "C"):
            raise ProblemError(f"scale must be 'K' or 'C' (the unit of the problem's temperatures), got {show(scale)}")
        eps = ScalarField(emissivity, f"emissivity on {show(tag)}", model=self.model, channels=False)
        if eps.constant is not None and not 0 <= eps.constant <= 1:
            raise ProblemError(f"the emissivity on {show(tag)} must lie in [0, 1], got {show(emissivity)}")
        self._condition("radiation", tag, ambient, eps)
        self.conditions[-1].offset = 273.15 if scale == "C" else 0.0
        return self

    def robin(self, tag: str, h, ambient) -> "HeatProblem":
        """Convection -k dT/dn = h (T - ambient) on ``tag``; h in W/(m^2 K), must be > 0."""
        hh = ScalarField(h, f"film coefficient h on {show(tag)}", positive=True, model=self.model, channels=False)
        return self._condition("robin", tag, ambient, hh)

    # --------------------------------------------------------------- assembly
    def face_data(self, pi: int, face: str) -> FaceData:
        """Geometry and DOFs of one patch face at its Gauss points (see :class:`iga.discretisation.faces.FaceQuadrature`)."""
        return self.faces([(pi, face)])[0]

    def faces_data(self, keys) -> list[FaceData]:
        """Geometry and DOFs of patch faces ``[(patch, face), ...]`` at their Gauss points (cached)."""
        return self.faces(keys)

    def field_on(self, field: ScalarField, fds, tag) -> list[np.ndarray]:
        """A scalar field evaluated on several faces at once -> one (N_f,) array per face
        (:func:`iga.heat.conditions.face_values`)."""
        return face_values(field, fds, tag)

    def tag_faces(self, tag) -> list:
        """The faces of a tag or tag expression of this problem; ``rest``: every free face that no condition
        without ``rest`` covers (:mod:`iga.tags`)."""
        if not mentions_rest(self.model, tag):
            return tag_faces(self.model, tag)
        covered = {f for c in self.conditions if not mentions_rest(self.model, c.tag)
                   for f in tag_faces(self.model, c.tag)}
        rest = [f for f in self.model.tags.get("boundary", []) if f not in covered]
        return tag_faces(self.model, tag, rest)

    def faces_by_kind(self):
        """{kind: {(patch, face): condition}}; one condition per face and kind, and Dirichlet faces alone."""
        out = {"dirichlet": {}, "neumann": {}, "robin": {}, "radiation": {}}
        for c in self.conditions:
            for key in condition_faces(self.tag_faces(c.tag), c.tag):
                other = out[c.kind].get(key)
                if other is not None:
                    raise ProblemError(
                        f"patch {key[0]} face {key[1]} has two {c.kind} conditions (tags {show(other.tag)} and "
                        f"{show(c.tag)}); give each face one condition of each kind")
                out[c.kind][key] = c
        clash = set(out["dirichlet"]) & (set(out["neumann"]) | set(out["robin"]) | set(out["radiation"]))
        if clash:
            key = sorted(clash)[0]
            d = out["dirichlet"][key]
            o = out["neumann"].get(key) or out["robin"].get(key) or out["radiation"][key]
            way = (f"e.g. {o.kind} on {show(f'{o.tag} - {d.tag}')} or on 'rest' (every free face no other condition "
                   "covers)") if o.tag != d.tag else "one tag cannot carry both"
            raise ProblemError(
                f"patch {key[0]} face {key[1]} has a Dirichlet condition (tag {show(d.tag)}) and a {o.kind} condition "
                f"(tag {show(o.tag)}); give each face one kind: {way}")
        return out

    def assemble(self, patches=None):
        """Assemble ``a(T, v) = l(v)``: (K, f, bookkeeping dict); only ``patches`` (a set: one MPI rank's share)
        when given: their volumes and their Neumann and Robin faces (the bookkeeping holds those faces; the
        Dirichlet faces are all kept, as every rank projects the Dirichlet data)."""
        by_kind = self.faces_by_kind()
        if patches is not None:  # a rank's faces only: their Gauss-point data is not replicated
            for kind in ("neumann", "robin"):
                by_kind[kind] = {key: c for key, c in by_kind[kind].items() if key[0] in patches}
        t0 = time.perf_counter()
        K, f, source_total = self.volume.assemble(self.conductivity, self.source, patches)
        t1 = time.perf_counter()
        loads, robin_mass, book = self.face_terms(by_kind, patches)
        if by_kind["neumann"] or by_kind["robin"]:  # (a zero vector otherwise: nothing to add)
            f += loads
        if robin_mass is not None:
            K = add_within(K, robin_mass)  # in place: no copy of K
        book["source"] = source_total
        book["timings"] = {"assembly_volume": t1 - t0, "assembly_faces": time.perf_counter() - t1}
        return K, f, book

    def face_terms(self, by_kind, patches=None):
        """The face forms of the conditions ``by_kind`` (:func:`iga.heat.conditions.face_terms`)."""
        return face_terms(self, by_kind, patches)

    def probe_matrix(self, points):
        """The sparse matrix E (N, ndof) with ``E @ u`` the temperatures at physical points (N, 3) for
        coefficients u (:func:`iga.discretisation.fields.evaluation_matrix`): probes of many states at once, and
        the ``until`` conditions of a transient solve."""
        where, params = Locator(self.model)(np.asarray(points, float), what="probe points")
        return evaluation_matrix(self, where, params)

    def mass(self, capacity=1.0):
        """The heat capacity matrix M (CSR, ndof x ndof, J/K): int rho c N_i N_j dV over the model, for the
        volumetric heat capacity ``capacity`` rho c in J/(m^3 K) (a number, a channel name or a callable of x,
        as the conductivity).  ``u @ M @ v`` is int rho c u v dV for fields with coefficients u and v; for u = v = 1
        everywhere ``M.sum()`` is the heat capacity of the whole model (J/K).  The rows are those of the
        unconstrained patch DOFs, as :meth:`assemble`'s (interface constraints act on both sides later)."""
        return self.volume.mass(ScalarField(capacity, "heat capacity", positive=True, model=self.model))

    def _needs_constraints(self) -> bool:
        """Interfaces, or patches with full-multiplicity (discontinuity) knots, need a prolongation."""
        return needs_constraints(self.model, self.spaces)

    # ------------------------------------------------------------------ solve
    def solve(self, solver: str = "auto", tol: float = 1e-10, maxiter: int | None = None, keep: bool = False):
        """Assemble, apply the conditions, solve; returns a :class:`iga.Solution`.

        ``solver``: a name from :func:`solvers.backends`; ``tol``: relative residual of iterative solvers
        (0 < tol < 1); ``maxiter``: their iteration limit; ``keep``: the solution keeps the factorisation (or AMG
        hierarchy) for its adjoints (``auto``, ``direct``, ``amg-cg``, ``cg``; memory: the factors).
        """
        if not (is_number(tol) and 0 < tol < 1):
            raise ProblemError(f"tol must be a number in (0, 1), got {show(tol)}")
        if maxiter is not None:
            count("maxiter", maxiter, 1)
        refuse_floating(self.conditions)
        if self.conductivity.of_temperature is not None:  # k(T): Newton on the unsymmetric tangent
            if solver == "petsc":
                raise ProblemError("a temperature-dependent conductivity is solved serially (Newton with a "
                                   "sparse LU); drop solver='petsc'")
            return solve_temperature_dependent(self, tol)
        world = distributed.world() if solver == "petsc" else None  # (comm, rank, size) under mpiexec
        record = SolveRecord(partition=distributed.partition(self, world[2]) if world else None)
        part = record.partition  # rank of each patch
        K, f, book = self.assemble(None if part is None else set(np.flatnonzero(part == world[1]).tolist()))
        record.timings = {**self.timings, **book["timings"]}
        if world:  # each rank integrated the source over its own patches
            book["source"] = world[0].allreduce(book["source"])
        t0 = time.perf_counter()
        rc = dd = None
        if world and self._needs_constraints():  # each rank builds the constraints its patches read
            constraints, dd, rc = rank_setup(self, world, part, book, record)
        else:
            constraints = (prolongation(self.model, self.spaces, self.offsets, self.weights)
                           if self._needs_constraints() else None)
        if dd is None:
            record.constraint_stats = dict(constraints.stats) if constraints is not None else {}
            record.components, record.idle_components = analyse_components(self, constraints,
                                                                            self.faces_by_kind(), book["source"])
            dd = project_dirichlet(self.faces, book["dirichlet"], self.ndof, constraints)
        record.timings["constraints"] = time.perf_counter() - t0
        record.constraints, record.dirichlet = (None, None) if world else (constraints, dd)  # the adjoint's too
        t0, options = time.perf_counter(), solver_options(self, solver, constraints, dd, book)
        record.timings["solver_structure"] = time.perf_counter() - t0  # Kronecker factors, multigrid levels
        if book["radiation"]:
            if world:
                raise ProblemError("radiation is solved serially; drop solver='petsc' (or the radiation) under mpiexec")
            res, record.newton = solve_radiation(self, K, f, constraints, dd, RadiationFaces.of(self, book), solver,
                                                 tol, maxiter)
            f = None  # the loads alone do not balance a radiating field (no energy identity)
        elif world:  # K handed over: the solve releases it once its reduced matrix is built
            system, K, f = [K, f], None, None
            res = distributed.solve_system(system, constraints, dd, tol, maxiter, part, world[0], self.offsets,
                                           rc=rc)
        else:
            res = solve_system(K, f, constraints, dd, solver, tol, maxiter, options, keep)
            record.again = res.again
        if rc is None:  # (a rank's own constraints counted the prescribed unknowns across the ranks)
            record.constraint_stats["prescribed"] = int(len(dd.dofs))
        record.constraint_stats["induced_rank"] = res.induced_rank
        record.timings["solve"] = res.info.setup_s + res.info.solve_s
        record.reduced_dofs = int(res.reduced)
        Gd = dd.G[res.reaction_dofs].toarray() if dd.G is not None else np.zeros((len(res.reaction_dofs), 0))
        integrals = {key: Gd[:, j] for j, key in enumerate(dd.keys)}
        return Solution(self, res.u, book, res.reaction_dofs, res.reaction, integrals, res.info,
                        loads=None if world else f, prescribed=res.prescribed, record=record)
