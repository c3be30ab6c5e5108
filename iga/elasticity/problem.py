"""Small-strain linear elasticity and thermal stress (Elber 2017, Section 3 and Fig. 12).

Units are the user's, consistently: with lengths in m, Young's modulus in
Pa, tractions and pressures in Pa, body forces in N/m^3 and expansion
coefficients in 1/K, displacements are in m, stresses in Pa and forces in N.

:class:`ElasticityProblem` uses what the heat analysis uses: the same
discretisation (:mod:`iga.discretisation.setting`: regularity proof, the tile's own
basis per patch), the same interface constraints for every displacement
component (:func:`iga.elasticity.volume.vector_constraints`), the same Dirichlet
projection per component and the same reduced solve (:mod:`iga.discretisation.system`);
the volume forms are those of :mod:`iga.elasticity.forms`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from geometry.errors import show
from solvers.indexing import complement

from iga.heat.coefficients import ScalarField, is_number
from iga.elasticity.material import resolved
from iga.discretisation.components import dof_labels
from iga.discretisation.constraints import needs_constraints, prolongation
from iga.discretisation.problem import Problem, SolveRecord
from iga.discretisation.fields import evaluation_matrix
from iga.discretisation.setting import count
from iga.elasticity.solution import ElasticSolution
from iga.elasticity.volume import ElasticVolume, vector_constraints
from iga.errors import ProblemError
from iga.discretisation.multilevel import direct_limit, elastic_kronecker_sums, owners_of
from iga.heat.forms import boundary_load
from iga.model import tag_faces
from iga.elasticity.rigid import free_modes, greville_points, refuse_net_load, rigid_modes, three_two_one
from iga.discretisation.system import solve_system
from iga.distributed.elastic import share_of, solve_elastic
from iga.distributed.solve import summed
from iga.distributed.rank_setup import together
from iga.tags import as_expression, condition_faces, mentions_rest
from iga.elasticity.data import VectorField, component_field, merge_dirichlet, pin_dofs
from iga.elasticity.supports import (Hold, PointLoad, Spring, components_of, hold_dirichlet, select_nodes,
                                     spring_matrix, stiffness_per_node)

__all__ = ["ElasticityProblem", "ElasticSystem"]

_AXES = "xyz"


@dataclass
class _Support:
    tag: str
    value: VectorField
    components: tuple


@dataclass
class _Load:
    tag: str
    kind: str  # "traction" or "pressure"
    value: object  # VectorField (traction) or ScalarField (pressure)


@dataclass
class ElasticSystem:
    """What :meth:`ElasticityProblem.solve` eliminates and solves: the stiffness ``K`` (3 ndof x 3 ndof, N/m;
    springs added) and load ``f`` (N), the ``work`` and ``applied`` loads of the assembly, the vector
    ``constraints`` (None: one unconstrained patch), the Dirichlet data ``dd`` (supports, holds, pins), the rigid
    ``modes`` at the reduced unknowns (the near-nullspace), the solver ``options``, this MPI rank's ``share``
    (None: serial), the ``record`` so far and the holds' unknowns ``hold_unknowns``."""

    K: object
    f: np.ndarray
    work: dict
    applied: dict
    constraints: object
    dd: object
    modes: np.ndarray
    options: dict
    share: object
    record: SolveRecord
    hold_unknowns: dict


class ElasticityProblem(Problem):
    """Linear elasticity of an isotropic, possibly graded material on a patch, a list of patches or a
    micro-structure (every model :class:`iga.HeatProblem` takes).

    Parameters
    ----------
    model : BSpline, list of BSpline, or a model such as ``tiling.Microstructure``
    youngs : Young's modulus E in Pa: a number, a channel name or a callable ``E(x (N, 3)) -> (N,)``; > 0
    poisson : Poisson's ratio nu in (-1, 0.5): a number, a channel name or a callable
    material : instead of youngs and poisson, an :class:`iga.CubicMaterial` (cubic symmetry about x, y, z: C11,
        C12, C44 in Pa, numbers or tabulated over a channel, e.g. a lattice's homogenised stiffness for a macro
        model: :meth:`iga.StiffnessTable.material`)
    degree_elevation, refine, quadrature_extra, degree, bases : the analysis spaces, as for
        :class:`iga.HeatProblem`

    Example: a unit cube stretched by 1e-3 along x with the sides free to slide is in uniaxial stress.

    >>> from geometry import primitives
    >>> p = ElasticityProblem(primitives.box(), youngs=200e9, poisson=0.3)
    >>> s = (p.dirichlet("umin", 0.0, components="x").dirichlet("umax", 1e-3, components="x")
    ...       .dirichlet("vmin", 0.0, components="y").dirichlet("wmin", 0.0, components="z").solve())
    >>> round(float(s.stress(np.array([[0.5, 0.5, 0.5]]))[0, 0, 0]) / 1e6, 6)  # MPa: E x strain
    200.0
    """

    def __init__(self, model, youngs=None, poisson=None, degree_elevation=0, refine: int = 0,
                 quadrature_extra: int = 0, degree=None, bases=None, material=None):
        super().__init__(model, degree_elevation, refine, quadrature_extra, degree, bases, components=3)
        self.material = resolved(youngs, poisson, material, self.model)
        #: the isotropic material's Young's modulus and Poisson's ratio (ScalarField), None for a cubic one
        self.youngs, self.poisson = self.material.fields() if self.material.kind == "isotropic" else (None, None)
        self.supports: list[_Support] = []
        self.loads: list[_Load] = []
        self.holds: list[Hold] = []  # control points held (edges, corners, selections: iga.elasticity.supports)
        self.springs: list[Spring] = []
        self.point_loads: list[PointLoad] = []
        self._nodes = None  # the DOFs' nodes (Greville images), computed on first use
        self._located = None  # the point locator, built on first use
        self.body = None
        self.thermal_strain = None
        self.rigid_hold = False

    def on(self, model) -> "ElasticityProblem":
        """This problem set up again on another ``model`` with the same patches, tags and channels (a redesigned
        map: other channel values): the same materials, supports, holds, springs and loads (holds and springs
        keep their control points: the patches and spaces are the same)."""
        quadrature_extra, degree_elevation, refine, degree = self.space_args
        new = type(self)(model, 1.0, 0.0, degree_elevation, refine, quadrature_extra, degree)
        new.material, new.youngs, new.poisson = self.material, self.youngs, self.poisson
        new.supports, new.loads, new.holds = list(self.supports), list(self.loads), list(self.holds)
        new.springs, new.point_loads = list(self.springs), list(self.point_loads)
        new.body, new.thermal_strain, new.rigid_hold = self.body, self.thermal_strain, self.rigid_hold
        return new

    # ------------------------------------------------------------ conditions
    def tag_faces(self, tag) -> list:
        """The faces of a tag or tag expression of this problem; ``rest``: every free face that no support or
        load without ``rest`` covers (:mod:`iga.tags`)."""
        if not mentions_rest(self.model, tag):
            return tag_faces(self.model, tag)
        covered = {f for c in self.supports + self.loads if not mentions_rest(self.model, c.tag)
                   for f in tag_faces(self.model, c.tag)}
        return tag_faces(self.model, tag, [f for f in self.model.tags.get("boundary", []) if f not in covered])

    def dirichlet(self, tag: str, value=0.0, components: str = "xyz") -> "ElasticityProblem":
        """Prescribed displacement (m) on ``tag``: a number (every component held to it), three numbers, or a
        callable ``u(x (N, 3)) -> (N, 3)``; only ``components`` (a string of x, y, z) are prescribed, the
        others stay free ("held vertically, free to slide" is ``components="z"``)."""
        tag = as_expression(tag)
        self.faces_of(tag, "dirichlet")
        if not (isinstance(components, str) and components and set(components) <= set(_AXES)
                and len(set(components)) == len(components)):
            raise ProblemError(f"components must be a string of distinct letters from 'xyz' (e.g. 'z' or 'xy'), got "
                               f"{show(components)}")
        field = VectorField(value, f"displacement on {show(tag)}", broadcast=True)
        self.supports.append(_Support(tag, field, tuple(_AXES.index(c) for c in components)))
        return self

    def nodes(self) -> np.ndarray:
        """The node (ndof, 3) of every scalar DOF: its patch's image of the DOF's Greville abscissae (m)."""
        if self._nodes is None:
            self._nodes = greville_points(self.model, self.spaces, self.offsets)
        return self._nodes

    def _name(self, name, kind: str, taken: list) -> str:
        if name is None:
            return f"{kind} {len(taken) + 1}"
        if not isinstance(name, str) or not name:
            raise ProblemError(f"{kind}: name must be a non-empty string, got {show(name)}")
        if name in self.model.tags or any(x.name == name for x in self.holds + self.springs + self.point_loads):
            raise ProblemError(f"{kind}: the name {show(name)} is already a tag or another support's name; choose a "
                               "new one")
        return name

    def hold(self, where, value=0.0, components: str = "xyz", name: str | None = None) -> "ElasticityProblem":
        """Hold the control points ``where`` selects (:func:`iga.elasticity.supports.select_nodes`: a patch edge
        ``("umin", "wmin")``, a corner ``("umin", "vmin", "wmin")``, a point, a box or a callable of the nodes) at
        the displacement ``value`` (m: a number, three numbers or a callable of the nodes (N, 3) -> (N, 3)) in
        ``components``.  On patch edges and corners that is a line or point support, exactly; elsewhere it holds
        control values (module notes).  ``name`` (default "hold 1", ...) names its reaction
        (:meth:`iga.ElasticSolution.reaction`)."""
        name = self._name(name, "hold", self.holds)
        comps = components_of(components, name)
        dofs = select_nodes(self, where, self.nodes(), name)
        field = VectorField(value, f"displacement of {show(name)}", broadcast=True)
        self.holds.append(Hold(name, dofs, self.nodes()[dofs], field, comps))
        return self

    def spring(self, where, stiffness, name: str | None = None) -> "ElasticityProblem":
        """Discrete springs to the ground on the control points ``where`` selects (as :meth:`hold`): ``stiffness``
        in N/m per node, a number for x, y and z or three numbers (0 leaves a component free); a support that is
        not rigid (an elastic bearing, a foundation)."""
        name = self._name(name, "spring", self.springs)
        k = stiffness_per_node(stiffness, name)
        self.springs.append(Spring(name, select_nodes(self, where, self.nodes(), name), k))
        return self

    def point_load(self, point, force, name: str | None = None) -> "ElasticityProblem":
        """A force ``force`` (three numbers, N) at the physical ``point`` (m), inside or on the model.  Its energy
        is infinite in 3-D: displacements and stresses away from the point converge under refinement, the
        values at it do not, and :meth:`iga.ElasticSolution.stress` refuses it there."""
        name = self._name(name, "point load", self.point_loads)
        try:
            x = np.asarray(point, float).reshape(3)
            F = np.asarray(force, float).reshape(3)
        except (TypeError, ValueError):
            raise ProblemError(f"{name}: point and force must be three numbers each, got {show(point)} and "
                               f"{show(force)}") from None
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(F))) or isinstance(point, str) \
                or isinstance(force, str):
            raise ProblemError(f"{name}: point and force must be three finite numbers each, got {show(point)} and "
                               f"{show(force)}")
        self._locator()(x[None], what=name)  # in the model, or refused naming it
        self.point_loads.append(PointLoad(name, x, F))
        return self

    def _locator(self):
        from iga.discretisation.locate import Locator

        if self._located is None:
            self._located = Locator(self.model)
        return self._located

    def traction(self, tag: str, t) -> "ElasticityProblem":
        """Surface traction (Pa) on ``tag``: three numbers or a callable ``t(x (N, 3)) -> (N, 3)``."""
        tag = as_expression(tag)
        self.faces_of(tag, "traction")
        self.loads.append(_Load(tag, "traction", VectorField(t, f"traction on {show(tag)}")))
        return self

    def pressure(self, tag: str, p) -> "ElasticityProblem":
        """Pressure (Pa) on ``tag``, pushing along the inward normal (traction -p n): a number or callable."""
        tag = as_expression(tag)
        self.faces_of(tag, "pressure")
        self.loads.append(_Load(tag, "pressure", ScalarField(p, f"pressure on {show(tag)}", channels=False)))
        return self

    def body_force(self, f) -> "ElasticityProblem":
        """Body force density (N/m^3): three numbers or a callable ``f(x (N, 3)) -> (N, 3)``."""
        self.body = VectorField(f, "body force")
        return self

    def thermal(self, temperature, expansion, reference=0.0) -> "ElasticityProblem":
        """Thermal strain alpha (T - T_ref) I: ``temperature`` a heat :class:`iga.Solution` on this model, a
        number or a callable of x (K or C); ``expansion`` alpha (1/K) a number, channel name or callable;
        ``reference`` T_ref, the temperature of the unstressed body."""
        from iga.elasticity.thermal import thermal_strain

        self.thermal_strain = thermal_strain(self, temperature, expansion, reference)
        return self

    def hold_rigid(self) -> "ElasticityProblem":
        """Hold the body against rigid motion only (free to expand): the 3-2-1 rule at three patch corners (where
        the spline interpolates its control point) far apart: all of A, two components of B across AB, one of
        C across the plane ABC.  Statically determinate, so a free thermal expansion stays stress free.  It holds a
        body that has no displacement condition: with one, :meth:`solve` refuses it (the pins would be supports
        too)."""
        self.rigid_hold = True
        return self

    # ------------------------------------------------------------------ solve
    def _loads(self, f: np.ndarray, supports: list, patches=None) -> tuple[dict, dict]:
        """Add the traction and pressure loads to f; returns ({tag: applied force (N, (3,))}, {tag: its moment
        about the origin (N m, (3,))}).  ``supports``: the
        :meth:`_support_faces`; a load on a component they prescribe on the same face is refused (it would only
        change the reaction there).  ``patches`` (a set): only their faces are integrated (one MPI rank's
        share)."""
        n, applied, moments = self.ndof, {}, {}  # moments about the origin (N m): hold_rigid's loads must balance
        for load in self.loads:
            keys = condition_faces(self.tag_faces(load.tag), load.tag)
            fds = self.faces(keys if patches is None else [k for k in keys if k[0] in patches])
            force = np.zeros(3)
            for fd in fds:
                if load.kind == "traction":
                    t = load.value.values(fd.x, f"patch {fd.patch} face {fd.face}")
                else:
                    t = -load.value.values(fd.x, fd.chans, f"patch {fd.patch} face {fd.face}")[:, None] * fd.normal
                _refuse_held_load(load, fd, t, supports)
                for a in range(3):
                    f[a * n : (a + 1) * n] += boundary_load([fd], [t[:, a] * fd.dAw], n)
                force += (t * fd.dAw[:, None]).sum(0)
                moments[load.tag] = moments.get(load.tag, 0.0) + (np.cross(fd.x, t) * fd.dAw[:, None]).sum(0)
            applied[load.tag] = applied.get(load.tag, 0.0) + force
        return applied, moments

    def _point_loads(self, f: np.ndarray, applied: dict, moments: dict) -> None:
        """Add the point loads to f and to ``applied`` and ``moments`` (as :meth:`_loads` gives them)."""
        n = self.ndof
        for pl in self.point_loads:  # f_i += N_i(x) F: the consistent load of a force at a point
            where, params = self._locator()(pl.point[None], what=pl.name)
            row = evaluation_matrix(self, where, params).toarray().ravel()
            for a in range(3):
                f[a * n:(a + 1) * n] += pl.force[a] * row
            applied[pl.name] = pl.force.copy()
            moments[pl.name] = np.cross(pl.point, pl.force)

    def _support_faces(self) -> list:
        """Per component, {(patch, face): (field, where)}; a component prescribed twice on one face is refused."""
        out = [{}, {}, {}]
        owner = [{}, {}, {}]
        for s in self.supports:
            for key in condition_faces(self.tag_faces(s.tag), s.tag):
                for a in s.components:
                    if key in out[a]:
                        raise ProblemError(f"patch {key[0]} face {key[1]}: displacement component {_AXES[a]} is "
                                           f"prescribed by tags {show(owner[a][key])} and {show(s.tag)}; give each "
                                           "component of a face one condition")
                    out[a][key] = (component_field(s.value, a), f"the faces tagged {show(s.tag)}")
                    owner[a][key] = s.tag
        return out

    def _solver_options(self, solver: str, constraints, dd, B) -> dict:
        """The rigid modes for AMG and PETSc's GAMG (their near-nullspace) and, for AMG, each unknown's place in
        its node (3 node + component, for aggregation by node); for one unconstrained patch with a Dirichlet side
        per component, one Kronecker sum per component (block fast diagonalization: ``fd-cg``, and ``auto``)."""
        options = {}
        if solver in ("auto", "amg-cg"):  # rigid modes, and node-major 3 x 3 blocks aggregated by node
            nred = B.shape[0] // 3
            unknowns = np.arange(3 * nred)
            options = {"near_nullspace": B, "node_slots": 3 * (unknowns % nred) + unknowns // nred}
        if solver == "petsc":  # GAMG's near-nullspace
            options = {"near_nullspace": B}
        if solver in ("auto", "fd-cg"):
            ks = None if constraints is not None else \
                elastic_kronecker_sums(self, complement(3 * self.ndof, dd.dofs))
            if ks is None and solver == "fd-cg":
                raise ProblemError("solver 'fd-cg' (block fast diagonalization) needs one unconstrained trivariate "
                                   "patch with Dirichlet conditions on whole sides, at least one for every "
                                   "displacement component; use 'amg-cg' for this problem")
            if ks is not None:
                options["kronecker"] = ks
            else:
                options.update(direct_limit(constraints, solver))
        return options

    def assemble(self, supports: list | None = None, patches=None, comm=None):
        """(K, f, book): the stiffness (3 ndof x 3 ndof CSR, component-major: unknown a ndof + i is component a
        of DOF i; N/m), the load vector (N: body force, thermal strain, tractions and pressures) and
        {"work": {"body": int f dV (N, (3,))}, "applied": {tag: resultant (N, (3,))}, "moments": {tag: moment about
        the origin (N m, (3,))}, "timings": {"assembly": s}}.  :meth:`solve` calls it with the
        :meth:`_support_faces` it resolved.  ``patches``, ``comm``: one MPI rank's patches (the others' rows
        stay empty; point loads are added on every rank) and the communicator the forces are summed over (bad
        data on one rank's patches is raised on every rank: :func:`iga.distributed.rank_setup.together`)."""
        supports = self._support_faces() if supports is None else supports
        t0 = time.perf_counter()

        def share():
            K, f, work = ElasticVolume(self.disc).assemble(self.material, self.body, self.thermal_strain, patches)
            return (K, f, work) + self._loads(f, supports, patches)

        K, f, work, applied, moments = share() if comm is None else together(comm, share)
        if comm is not None:
            work, applied, moments = summed(comm, work), summed(comm, applied), summed(comm, moments)
        self._point_loads(f, applied, moments)
        return K, f, {"work": work, "applied": applied, "moments": moments,
                      "timings": {"assembly": time.perf_counter() - t0}}

    def system(self, solver: str = "auto") -> ElasticSystem:
        """Assemble and resolve the conditions as :meth:`solve` does, before anything is eliminated: the
        :class:`ElasticSystem` a solve (or an adjoint, :func:`iga.elasticity.adjoint.elastic_adjoint`) solves.
        Refuses free rigid motions."""
        supports = self._support_faces()
        if self.rigid_hold and (any(supports) or self.holds or self.springs):
            tags = sorted({show(sup.tag) for sup in self.supports} | {show(x.name) for x in self.holds + self.springs})
            raise ProblemError(f"hold_rigid pins three corners against rigid motion only, but displacement conditions "
                               f"on {', '.join(tags)} already hold the body: the pins would add supports (and "
                               "reactions) of their own; use either the conditions or hold_rigid")
        share = share_of(self, solver)  # this MPI rank's patches under mpiexec with solver="petsc", else None
        K, f, book = self.assemble(supports, *((share.patches, share.comm) if share else ()))
        work, applied = book["work"], book["applied"]
        if self.rigid_hold:
            refuse_net_load(applied, work["body"], book["moments"])
        t1 = time.perf_counter()
        scalar = prolongation(self.model, self.spaces, self.offsets, self.weights) \
            if needs_constraints(self.model, self.spaces) \
            else None
        record = SolveRecord(constraint_stats=dict(scalar.stats) if scalar is not None else {},
                             timings={**self.timings, **book["timings"]})
        constraints = vector_constraints(scalar, self.ndof)
        dd = merge_dirichlet(self.faces, supports, self.ndof, scalar)
        points = self._nodes if self._nodes is not None else greville_points(self.model, self.spaces, self.offsets)
        held = [np.unique(np.concatenate([fd.dofs for fd in self.faces(list(sup))])) if sup
                else np.zeros(0, np.int64) for sup in supports]
        dd, hold_unknowns = hold_dirichlet(dd, self.holds, self.ndof, scalar)
        for h in self.holds:
            for a in h.components:
                held[a] = np.union1d(held[a], h.dofs)
        for spring in self.springs:  # a spring restrains its components as a hold does (for the rigid check)
            for a in np.flatnonzero(spring.stiffness > 0):
                held[a] = np.union1d(held[a], spring.dofs)
        if self.springs:
            S = spring_matrix(self.springs, self.ndof)
            K = K + (share.own_diagonal(S) if share else S)
        if self.rigid_hold:
            pins = three_two_one(self.spaces, self.offsets, points)
            dd = pin_dofs(dd, pins, self.ndof, scalar)
            held = [np.union1d(h, p) for h, p in zip(held, pins)]
        pieces, labels = dof_labels(self, None if scalar is None else scalar.P)
        free_modes(points, labels, held, pieces)
        B = rigid_modes(points)  # at the DOFs; a reduced unknown reads them at one DOF it owns
        if constraints is not None:
            B = B[owners_of(constraints.dof_master)]
        record.timings["constraints"] = time.perf_counter() - t1
        return ElasticSystem(K, f, work, applied, constraints, dd, B, self._solver_options(solver, constraints, dd, B),
                             share, record, hold_unknowns)

    def solve(self, solver: str = "auto", tol: float = 1e-10, maxiter: int | None = None) -> ElasticSolution:
        """Assemble, apply the conditions, refuse free rigid motions, solve; returns an :class:`ElasticSolution`."""
        if not (is_number(tol) and 0 < tol < 1):
            raise ProblemError(f"tol must be a number in (0, 1), got {show(tol)}")
        if maxiter is not None:
            count("maxiter", maxiter, 1)
        system = self.system(solver)
        record = system.record
        # K is consumed: the work balance reads the displacement field and the load vector, not K
        if system.share:
            record.partition = system.share.part
            res, f = solve_elastic(system.share, system.K, system.f, system.constraints, system.dd, tol, maxiter,
                                   system.modes)
        else:
            f = system.f
            res = solve_system(system.K, f, system.constraints, system.dd, solver, tol, maxiter, system.options)
        system.K = None
        record.timings["solve"] = res.info.setup_s + res.info.solve_s
        record.reduced_dofs = int(res.reduced)
        return ElasticSolution(self, res, f, system.dd, system.work, system.applied, record, system.hold_unknowns,
                               self.springs)


def _refuse_held_load(load, fd, t: np.ndarray, supports: list) -> None:
    """A traction or pressure ``t`` (N, 3) on face ``fd`` with a component that a displacement condition prescribes
    on that face raises :class:`ProblemError`: it would only change the reaction there."""
    key = (fd.patch, fd.face)
    size = float(np.abs(t).max()) if t.size else 0.0
    # beyond round-off: a pressure on a face normal to x, held in y, has normals with 1e-17 y components
    held = [a for a in range(3) if key in supports[a] and np.abs(t[:, a]).max(initial=0.0) > 1e-9 * size]
    if held:
        a = held[0]
        article = "an" if a == 0 else "a"  # an x, a y, a z
        raise ProblemError(f"the {load.kind} on {show(load.tag)} has {article} {_AXES[a]} component on patch "
                           f"{fd.patch} face {fd.face}, where the displacement condition on {supports[a][key][1]} "
                           f"prescribes {_AXES[a]}: a load on a prescribed component only changes the reaction; drop "
                           "it there or free that component (dirichlet(..., components=...))")
