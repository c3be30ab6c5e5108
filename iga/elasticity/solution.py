"""Post-processing of a solved elastic problem: displacement, strain, stress, reactions, energy, errors."""

from __future__ import annotations

import numpy as np

from geometry.numbers import TINY
from geometry import SplineFunction
from geometry.patches.chain import patch_geometry_points

from iga.elasticity.forms import strain
from iga.elasticity.supports import POINT_MARGIN
from iga.errors import ProblemError
from iga.outputs import von_mises
from geometry.errors import show
from iga.discretisation.problem import SolveRecord
from iga.discretisation.fields import integrate_fields
from iga.discretisation.locate import Locator
from iga.discretisation.fields import field_spline, physical_gradient
from iga.discretisation.problem import ElasticInfo, WorkBalance
from iga.heat.solution import EnergyBalance, check_reference, reference_values

__all__ = ["ElasticSolution"]


class ElasticSolution:
    """Displacement field of an :class:`iga.ElasticityProblem`.

    Attributes
    ----------
    u : (3 ndof,) coefficients, component-major (x block, y block, z block)
    info : dict with DOF counts, constraints, solver diagnostics, timings and the work balance
    """

    physics = "elasticity"  # (iga.outputs asks)

    def __init__(self, problem, res, f, dd, work, applied, record=None, holds=None, springs=()):
        self.problem = problem
        self.record = SolveRecord(reduced_dofs=int(res.reduced), timings=dict(problem.timings)) \
            if record is None else record  # what the solve found (iga.discretisation.problem)
        self.u = res.u
        self._splines: dict = {}
        self.output_values: dict = {}  # outputs evaluated on this solution, by name (iga.outputs.evaluated)
        self._locator = Locator(problem.model)
        self._applied = applied
        total = np.asarray(dd.G[res.reaction_dofs].sum(axis=1)).ravel() if dd.G is not None else np.zeros(0)
        safe = np.where(total != 0, total, 1.0)
        Gd = dd.G[res.reaction_dofs].toarray() if dd.G is not None else np.zeros((len(res.reaction_dofs), 0))
        self._face_forces = {}  # (component, (patch, face)) -> support force on the body (N)
        for j, key in enumerate(dd.keys):
            self._face_forces[key] = float(np.sum(res.reaction * Gd[:, j] / safe))
        self._f = f
        self._reaction, self._prescribed = res.reaction, res.prescribed
        at = np.zeros(0, np.int64)  # each prescribed unknown's row of the reactions (a hold's are all prescribed)
        if len(res.reaction_dofs):
            at = np.full(int(np.max(res.reaction_dofs)) + 1, -1, np.int64)
            at[res.reaction_dofs] = np.arange(len(res.reaction_dofs))
        self._hold_forces = {name: np.array([float(res.reaction[at[u]].sum()) for u in unknowns])
                             for name, unknowns in (holds or {}).items()}  # hold name -> force on the body (N)
        n = problem.ndof
        self._spring_forces = {s.name: np.array([-s.stiffness[a] * float(self.u[a * n + s.dofs].sum())
                                                 for a in range(3)]) for s in springs}
        # u . K_s u: the work the springs take (the continuum's internal work is the rest of u . f)
        self._spring_work = sum(float(np.sum(s.stiffness[a] * self.u[a * n + s.dofs] ** 2))
                                for s in springs for a in range(3))
        balance, energy = self._work_and_energy()
        self.info = ElasticInfo(
            dofs=3 * problem.ndof, free_dofs=int(self.record.reduced_dofs),
            constraints=dict(self.record.constraint_stats), patches=len(problem.model.patches), solver=res.info,
            timings=dict(self.record.timings),
            work=WorkBalance(balance.external, balance.internal, energy, balance.relative_error,
                             problem.thermal_strain is not None),
            applied_N={tag: v.tolist() for tag, v in applied.items()}, body_force_N=work["body"].tolist())

    def __repr__(self) -> str:
        return (f"ElasticSolution({self.info['patches']} patches, {self.info['dofs']} DOFs, {self.info['free_dofs']} "
                f"unknowns, {self.info['solver']['method']}; strain energy {self.info['work']['strain_energy_J']:.4g} J, "
                f"work balance error {self.info['work']['relative_error']:.1e})")

    # ---------------------------------------------------------------- fields
    def to_pyvista(self, samples: int = 3, tolerance: float | None = None):
        """The sampled grid of :func:`iga.write_vtu` as a ``pyvista.UnstructuredGrid`` (displacement in m,
        stress and von Mises in Pa, the channels, patch and level), without writing a file."""
        from iga.io.grids import sample_grid
        from iga.io.sampling import displacement_fields

        return sample_grid(self.problem.model, samples, tolerance, None, self.problem, displacement_fields(self))

    def plot(self, field: str = "von_mises", screenshot=None, warp: float | None = None, title: str | None = None,
             samples: int = 3):
        """Draw ``field`` (``von_mises``, ``displacement``, ...) on the sampled grid, deformed by ``warp``
        times the displacement when given, titled with the case (patches, unknowns, work balance) and the
        field's range; ``screenshot``: a ``.png`` written off screen (returned), else the window is shown."""
        from iga.io.pictures import count, plot_field

        case = title or (f"elasticity: {count(self.info['patches'], 'patch')}, "
                         f"{count(self.info['free_dofs'], 'unknown')}"
                         + (f", displacement x {warp:g}" if warp is not None else ""))
        return plot_field(self.to_pyvista(samples), field, case, screenshot, warp)

    def displacement_spline(self, pi: int) -> SplineFunction:
        """The displacement on patch ``pi`` as a 3-component spline over the patch parameters."""
        if pi not in self._splines:
            prob = self.problem
            space, o, n = prob.spaces[pi], prob.offsets, prob.ndof
            coef = np.stack([self.u[a * n + o[pi] : a * n + o[pi + 1]].reshape(space.shape) for a in range(3)], -1)
            self._splines[pi] = field_spline(space, coef, prob.weights[pi])
        return self._splines[pi]

    def evaluate(self, pi: int, params):
        """Displacement (N, 3), its gradient (N, 3, 3) (``[n, a, k] = d u_a / d x_k``), x (N, 3) and channels at
        parameters of patch ``pi``."""
        params = np.asarray(params, float)
        U = self.displacement_spline(pi)
        val = U.evaluate(params)
        dxi = U.jacobian(params)  # (N, 3 components, 3 parameters)
        x, J, chans = patch_geometry_points(self.problem.model.patches[pi], params)
        grad = np.stack([physical_gradient(J, dxi[:, a, :], f"patch {pi}", params) for a in range(3)], 1)
        return val, grad, x, chans

    def _at_points(self, points, fn, tail=()):
        """``fn(patch, params) -> (n,) + tail`` at physical points (N, 3), located; (0,) + tail for no points."""
        points = np.asarray(points, float)
        if points.size == 0:
            return np.zeros((0,) + tuple(tail))
        where, params = self._locator(points, 1e-10)
        out = None
        for pi in np.unique(where):
            sel = where == pi
            v = fn(int(pi), params[sel])
            if out is None:
                out = np.empty((len(where),) + v.shape[1:])
            out[sel] = v
        return out

    def _stress_at(self, pi, params):
        u, grad, x, chans = self.evaluate(pi, params)
        eps = strain(grad)
        prob = self.problem
        if prob.thermal_strain is not None:
            eps = eps - (prob.thermal_strain(pi, x, params, chans))[:, None, None] * np.eye(3)
        return prob.material.moduli(x, chans, f"patch {pi}").stress(eps)

    def displacement(self, points) -> np.ndarray:
        """Displacement (N, 3) in m at physical points (N, 3)."""
        return self._at_points(points, lambda pi, p: self.displacement_spline(pi).evaluate(p), (3,))

    def strain(self, points) -> np.ndarray:
        """Total small strain sym(grad u) (N, 3, 3) at physical points; refused at a point load's point."""
        self._refuse_point_loads(points, "strain")

        return self._at_points(points, lambda pi, p: strain(self.evaluate(pi, p)[1]), (3, 3))

    def stress(self, points) -> np.ndarray:
        """Cauchy stress (N, 3, 3) in Pa at physical points (thermal strain taken off the total); refused at the
        point of a point load, where it is infinite (:mod:`iga.elasticity.supports`)."""
        self._refuse_point_loads(points, "stress")
        return self._at_points(points, self._stress_at, (3, 3))

    def _refuse_point_loads(self, points, what: str) -> None:
        loads = self.problem.point_loads
        pts = np.asarray(points, float).reshape(-1, 3) if np.size(points) else np.zeros((0, 3))
        if not loads or not len(pts):
            return
        size = max(float(np.ptp(self.problem.nodes(), axis=0).max()), TINY)
        for pl in loads:
            d = np.linalg.norm(pts - pl.point, axis=1)
            if np.any(d <= POINT_MARGIN * size):
                raise ProblemError(f"the {what} at the point of {show(pl.name)} {pl.point.tolist()} is infinite (a "
                                   f"force at a point of a 3-D body); ask for it away from the point, where it "
                                   "converges under refinement")

    def von_mises(self, points) -> np.ndarray:
        """Von Mises equivalent stress (N,) in Pa at physical points."""
        return von_mises(self.stress(points))[1]

    # ------------------------------------------------------------ reactions
    def reaction(self, tag: str) -> np.ndarray:
        """Force (3,) in N that the supports on the faces tagged ``tag`` exert on the body (the consistent
        residual of the prescribed unknowns, split among faces by their share of int N_i dA); or that the hold or
        the springs named ``tag`` exert (:meth:`iga.ElasticityProblem.hold`, :meth:`~iga.ElasticityProblem.spring`)."""
        if isinstance(tag, str) and tag in self._hold_forces:
            return self._hold_forces[tag].copy()
        if isinstance(tag, str) and tag in self._spring_forces:
            return self._spring_forces[tag].copy()
        faces = set(self.problem.tag_faces(tag))
        if not faces:
            raise ProblemError(f"tag {tag!r} has no faces in this model")
        out = np.zeros(3)
        for (a, key), v in self._face_forces.items():
            if key in faces:
                out[a] += v
        return out

    # ------------------------------------------------------------ integrals
    def integrate(self, fn) -> float:
        """Sum over the model of int fn(x, u, grad u) dV by the problem's Gauss rule; ``fn(x (N, 3), u (N, 3),
        grad (N, 3, 3)) -> (N,)`` (:func:`iga.discretisation.fields.integrate_fields`)."""
        prob = self.problem
        n, o = prob.ndof, prob.offsets
        return integrate_fields(prob, lambda i: np.stack([self.u[a * n + o[i]:a * n + o[i + 1]].reshape(
            prob.spaces[i].shape) for a in range(3)]), 3, fn)

    def gradient(self, output, wrt: str = "tiles", solver: str = "auto") -> np.ndarray:
        """The derivative of an output by Young's modulus, ``wrt="tiles"`` or ``"patches"`` (a factor on each
        one's E) or ``"channel:NAME"`` (the control values of the map's channel E reads): of the compliance
        (``iga.outputs.Compliance()``) without an extra solve (it is self-adjoint), of the von Mises norm
        (``iga.outputs.VonMisesNorm(p)``) by one adjoint solve with ``solver``
        (:func:`iga.elasticity.sensitivity.elastic_sensitivity`); of either by the shape, ``wrt="map"`` (the
        map's control points, :func:`iga.shape_sensitivity.shape_sensitivity`) or ``"parameters"`` / ``"faces"``
        (a field-graded paving's field, :func:`iga.parameter_sensitivity.parameter_sensitivity`)."""
        if wrt == "map":
            from iga.shape_sensitivity import shape_sensitivity

            return shape_sensitivity(self, output, solver)
        if wrt in ("parameters", "faces"):
            from iga.parameter_sensitivity import parameter_sensitivity

            return parameter_sensitivity(self, output, wrt, solver)
        from iga.elasticity.sensitivity import elastic_sensitivity

        return elastic_sensitivity(self, output, wrt, solver)

    def strain_energy(self) -> float:
        """Elastic strain energy (J): 1/2 int (eps - eps_th) : C : (eps - eps_th) dV, the thermal strain taken
        off (a free thermal expansion stores none), by the problem's Gauss rule."""
        return self.info["work"]["strain_energy_J"]

    def work_balance(self) -> EnergyBalance:
        """The virtual work of the solution on itself, its two sides computed independently (J).

        ``internal``: int sigma : eps(u) dV, the stresses and strains evaluated from the displacement at the Gauss
        points as post-processing does (materials, thermal strain); ``external``: the work of the loads, u . f
        less the thermal part of f (body forces, tractions and pressures, as assembled into the load vector),
        plus the supports' work r . u_D (the consistent reactions on the prescribed unknowns times their
        values).  A displacement that does not satisfy the discrete equations, or a stiffness that differs from
        the field's own stresses, shows as a relative error above round-off (relative to the larger side and
        to int eps : C : eps dV, so that a stress-free expansion, where both sides vanish, is measured
        against the energy its strain would have).  ``None`` figures after a distributed solve.
        """
        return self._work_and_energy()[0]

    def _work_and_energy(self) -> tuple[EnergyBalance, float]:
        """(the work balance, the strain energy with the thermal strain removed) from one pass over the Gauss
        points."""
        prob = self.problem
        n, o = prob.ndof, prob.offsets

        def densities(x, u, g, at):
            where = f"patches {at.patches[0]}..{at.patches[-1]}"
            mod = prob.material.moduli(x, at.chans, where)
            eps = strain(g)
            tr = np.trace(eps, axis1=1, axis2=2)
            th = at.per_patch(prob.thermal_strain) if prob.thermal_strain is not None else np.zeros(len(x))
            mech = eps - th[:, None, None] * np.eye(3)
            sig_eps = mod.product(mech, eps)
            energy = 0.5 * mod.product(mech, mech)
            thermal_load = mod.dilatation * th * tr  # C eps_th : eps(u), the thermal part of u . f
            total = mod.product(eps, eps)  # eps : C : eps, the scale
            return np.stack([sig_eps, energy, thermal_load, total], 1)

        internal, energy, thermal_load, total = integrate_fields(
            prob, lambda i: np.stack([self.u[a * n + o[i]:a * n + o[i + 1]].reshape(prob.spaces[i].shape)
                                      for a in range(3)]), 3, densities, context=True)
        if self._prescribed is None:
            return EnergyBalance(float(internal), None, None), float(energy)
        external = float(self.u @ self._f) - float(thermal_load) + float(self._reaction @ self._prescribed) \
            - self._spring_work
        scale = max(abs(internal), abs(external), abs(total), TINY)
        return EnergyBalance(float(internal), external, float(abs(internal - external) / scale)), float(energy)

    def l2_error(self, exact) -> float:
        """|| u - exact ||_L2 (m^{5/2}); ``exact(x (N, 3)) -> (N, 3)``."""
        check_reference(exact, "exact")
        return float(np.sqrt(self.integrate(
            lambda x, u, g: np.sum((u - reference_values(exact, x, (3,), "exact")) ** 2, axis=1))))

    def h1_error(self, exact_grad) -> float:
        """| u - exact |_H1 (gradient seminorm); ``exact_grad(x) -> (N, 3, 3)`` with ``[n, a, k] = d u_a/d x_k``."""
        check_reference(exact_grad, "exact_grad")
        return float(np.sqrt(self.integrate(
            lambda x, u, g: np.sum((g - reference_values(exact_grad, x, (3, 3), "exact_grad")) ** 2, axis=(1, 2)))))
