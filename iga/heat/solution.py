"""Post-processing of a solved heat problem: probes, fluxes, energy balance, errors."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.numbers import TINY
from geometry import SplineFunction

from iga.heat.coefficients import tensor_matrix, user_values
from iga.heat.radiation import RadiationFaces
from iga.errors import ProblemError
from geometry import knots as kn
from iga.discretisation.faces import chunks
from iga.discretisation.fields import field_spline, grid_contract, integrate_fields, physical_gradient
from geometry.patches.chain import patch_geometry_points
from geometry.patches.sampling import sample_axes
from iga.discretisation.locate import Locator
from iga.discretisation.problem import SolveRecord
from iga.discretisation.problem import HeatBalance, SolutionInfo


@dataclass(frozen=True)
class EnergyBalance:
    """Two independently computed sides of an energy identity and their relative difference (None where a
    distributed solve cannot compute them); see :meth:`Solution.energy_balance` and
    :meth:`iga.ElasticSolution.work_balance`."""

    internal: float | None
    external: float | None
    relative_error: float | None

    def as_dict(self) -> dict:
        return {"internal": self.internal, "external": self.external, "relative_error": self.relative_error}


class Solution:
    """Temperature field of a :class:`iga.HeatProblem`.

    Attributes
    ----------
    u : (ndof,) all coefficients (patch blocks in order)
    info : :class:`iga.discretisation.problem.SolutionInfo`: DOF counts, the solver's report (method,
        iterations, residual), timings (s), the energy balance; read by attribute or by key
    """

    #: what the outputs of :mod:`iga.outputs` and the adjoint of :mod:`iga.sensitivity` ask of a solution
    physics = "heat"
    steady = True

    def __init__(self, problem, u, book, dirichlet_dofs, reaction, dirichlet_integrals, solver_info, loads=None,
                 prescribed=None, record=None):
        self.problem = problem
        self.record = SolveRecord(reduced_dofs=len(u), timings=dict(problem.timings)) if record is None else record
        self.u = u
        self._volume = None  # the model's volume, once asked for
        self._temperature_integral = None  # int T dV, where the energy identity's pass computed it
        self.output_values: dict = {}  # outputs evaluated on this solution, by name (iga.outputs.evaluated)
        self._book = book
        self._loads = loads  # the load vector f (ndof,): source, Neumann and Robin h T_inf; None when distributed
        self._prescribed = prescribed  # the prescribed unknowns' values (reaction . prescribed: the supports' part)
        # consistent boundary fluxes: the residual K u - f on the prescribed (reduced) unknowns
        self._reaction = np.asarray(reaction, float)
        self._dirichlet_dofs = dirichlet_dofs
        self._dirichlet_integrals = dirichlet_integrals
        self._splines = {}
        self._locator = Locator(problem.model)
        # both combine figures across the ranks of a distributed solve: computed once, here, by every rank
        self.face_flows = self._face_flows()
        self._scale = self._flow_scale()
        self.info = SolutionInfo(
            dofs=problem.ndof, free_dofs=int(self.record.reduced_dofs),
            constraints=dict(self.record.constraint_stats), patches=len(problem.model.patches),
            solver=solver_info, timings=dict(self.record.timings), balance=self.balance(),
            components=_components_info(self.record), newton=list(self.record.newton))

    def __repr__(self) -> str:
        b = self.info["balance"]
        return (f"Solution({self.info['patches']} patches, {self.info['dofs']} DOFs, {self.info['free_dofs']} "
                f"unknowns, {self.info['solver']['method']}; inflow {b['inflow_W']:.4g} W, balance error "
                f"{b['relative_error']:.1e})")

    # ---------------------------------------------------------------- pictures
    def to_pyvista(self, samples: int = 3, tolerance: float | None = None):
        """The sampled grid of :func:`iga.write_vtu` as a ``pyvista.UnstructuredGrid`` (temperature in C, heat
        flux in W/m^2, the channels, patch and level), without writing a file."""
        from iga.io.grids import sample_grid
        from iga.io.sampling import temperature_fields

        return sample_grid(self.problem.model, samples, tolerance, None, self.problem, temperature_fields(self))

    def plot(self, field: str = "temperature", screenshot=None, title: str | None = None, samples: int = 3):
        """Draw ``field`` (``temperature`` or ``heat_flux``) on the sampled grid, titled with the case
        (patches, unknowns, heat in) and the field's range; ``screenshot``: a ``.png`` written off screen
        (returned), else the window is shown (:func:`iga.io.pictures.plot_field`)."""
        from iga.io.pictures import count, plot_field

        b = self.info["balance"]
        case = title or (f"heat: {count(self.info['patches'], 'patch')}, "
                         f"{count(self.info['free_dofs'], 'unknown')}, {b['inflow_W']:.4g} W in")
        return plot_field(self.to_pyvista(samples), field, case, screenshot)

    # ---------------------------------------------------------------- fields
    def temperature_spline(self, pi: int) -> SplineFunction:
        """The temperature on patch ``pi`` as a scalar spline over the patch parameters (kept for the probes
        that ask again)."""
        if pi not in self._splines:
            self._splines[pi] = self._spline(pi)
        return self._splines[pi]

    def _spline(self, pi: int) -> SplineFunction:
        space = self.problem.spaces[pi]
        o = self.problem.offsets
        coef = self.u[o[pi] : o[pi + 1]].reshape(space.shape + (1,))
        return field_spline(space, coef, self.problem.weights[pi])

    def evaluate(self, pi: int, params):
        """Temperature (N,), gradient (N, 3) in physical space, and x (N, 3) at parameters of patch ``pi``."""
        params = np.asarray(params, float)
        T = self.temperature_spline(pi)
        val = T.evaluate(params)[:, 0]
        dxi = T.jacobian(params)[:, 0, :]
        x, J, chans = patch_geometry_points(self.problem.model.patches[pi], params)
        return val, physical_gradient(J, dxi, f"patch {pi}", params), x, chans

    def conductivity_at(self, x, chans, pi, T=None):
        """Conductivity at points x (N, 3) of patch ``pi``: (N,) isotropic or (N, 6) tensor components; ``T``
        (N,) the temperature there (a temperature-dependent conductivity needs it)."""
        return self.problem.conductivity.values(x, chans, f"patch {pi}", T)

    def heat_flux(self, pi: int, params) -> np.ndarray:
        """Heat flux vector q = -K grad T (W/m^2) at parameters of patch ``pi``, (N, 3)."""
        T, grad, x, chans = self.evaluate(pi, params)
        return flux_vector(self.conductivity_at(x, chans, pi, T), grad)

    # ----------------------------------------------------------------- probes
    def locate(self, points, tol: float = 1e-10):
        """Point inversion: (patch index (N,), parameters (N, 3)) of physical points (N, 3) (:class:`iga.discretisation.locate.Locator`)."""
        return self._locator(points, tol)

    def probe(self, points) -> np.ndarray:
        """Temperature at physical points (N, 3) -> (N,)."""
        where, params = self.locate(points)
        out = np.empty(len(where))
        for pi in np.unique(where):
            sel = where == pi
            out[sel] = self.temperature_spline(int(pi)).evaluate(params[sel])[:, 0]
        return out

    # ----------------------------------------------------------------- fluxes
    def _face_flows(self) -> dict:
        """Outward heat flow (W) through every face that carries a condition."""
        prob, book = self.problem, self._book
        flows = {}
        for key, q in book["neumann"].items():
            flows[key] = flows.get(key, 0.0) - float(np.sum(q * prob.face_data(*key).dAw))
        for key, (h, Tinf) in book["robin"].items():
            fd = prob.face_data(*key)
            flows[key] = flows.get(key, 0.0) + float(np.sum(h * (fd.trace(self.u) - Tinf) * fd.dAw))
        if book.get("radiation"):  # sigma eps (T^4 - T_amb^4), outward
            faces = RadiationFaces.of(prob, book)
            for key, flow in zip(book["radiation"], faces.flows(self.u)):
                flows[key] = flows.get(key, 0.0) + flow
        dirichlet = {}
        if self._dirichlet_integrals:
            # split each prescribed unknown's reaction among the faces by their share of int N_i dA
            total = sum(self._dirichlet_integrals.values())
            safe = np.where(total != 0, total, 1.0)
            for key, integ in self._dirichlet_integrals.items():
                dirichlet[key] = -float(np.sum(self._reaction * integ / safe))
        comm = self._comm()
        if comm is not None:
            # each rank holds its own Neumann and Robin faces (disjoint): every rank gets all; a rank's reaction
            # is its rows' part, and the flows are linear in it: the ranks' Dirichlet flows add up per face
            for part in comm.allgather(flows):
                flows.update(part)
            from iga.distributed.solve import summed

            dirichlet = summed(comm, dirichlet)
        for key, v in dirichlet.items():
            flows[key] = flows.get(key, 0.0) + v
        return flows

    def _comm(self):
        """The MPI communicator of a distributed solve (:mod:`iga.distributed.solve`), None for a serial one."""
        from iga.distributed.solve import solve_world

        w = solve_world(self)
        return None if w is None else w[0]

    def flux(self, tag: str) -> float:
        """Heat flow through the faces tagged ``tag`` in W, outward positive.

        Dirichlet faces use the consistent reaction (residual) flux, Neumann
        faces the prescribed flux, Robin faces h (T - T_inf); insulated faces
        contribute nothing.
        """
        faces = set(self.problem.tag_faces(tag))
        return float(sum(self.face_flows.get(f, 0.0) for f in faces))

    def balance(self) -> HeatBalance:
        """Global energy balance: inflow + sources = outflow (W), and the relative error
        (:class:`iga.discretisation.problem.HeatBalance`; read by attribute or by key)."""
        flows = np.array(list(self.face_flows.values())) if self.face_flows else np.zeros(0)
        src = self._book["source"]
        inflow = float(-flows[flows < 0].sum()) + max(src, 0.0)
        outflow = float(flows[flows > 0].sum()) + max(-src, 0.0)
        scale = max(inflow, outflow, abs(src), self._scale, TINY)
        return HeatBalance(inflow, outflow, src, abs(inflow - outflow) / scale, scale)

    def energy_balance(self) -> "EnergyBalance":
        """The energy identity a(T, T) = l(T) + r . T_D, its two sides computed independently.

        ``internal``: int K grad T . grad T dV (the temperature's gradient and the conductivity evaluated at the
        Gauss points, as post-processing does) + sum over Robin faces of int h T^2 dA; ``external``: T . f (the
        load vector of sources, Neumann fluxes and Robin h T_inf, as assembled) + r . T_D (the consistent
        reactions on the prescribed unknowns times their values).  Both are in W K.  A solution that does not
        satisfy the discrete equations, or a stiffness that differs from the field's own energy (an assembly
        kernel, a constraint, a material read differently), shows as a relative error above round-off.  Unlike
        the heat-flow balance (:meth:`balance`), which sums the consistent flows and so measures the solve's
        residual only, this compares the field with the loads.  Serial solves only (a distributed solve keeps
        no global load vector): ``None`` figures there.
        """
        prob = self.problem
        if self._loads is None or self._prescribed is None:
            return EnergyBalance(None, None, None)

        def density(x, T, g, at):  # the field's energy, and T and 1 for the mean temperature from the same pass
            K = prob.conductivity.values(x, at.chans, f"patches {at.patches[0]}..{at.patches[-1]}", T[:, 0])
            return np.stack([-np.sum(flux_vector(K, g[:, 0]) * g[:, 0], axis=1), T[:, 0], np.ones(len(T))], 1)

        internal, self._temperature_integral, volume = integrate_fields(
            prob, lambda i: self.u[prob.offsets[i]:prob.offsets[i + 1]].reshape((1,) + prob.spaces[i].shape), 1,
            density, context=True)
        self._volume = float(volume) if self._volume is None else self._volume
        for key, (h, _) in self._book["robin"].items():
            fd = prob.face_data(*key)
            internal += float(np.sum(h * fd.trace(self.u) ** 2 * fd.dAw))
        external = float(self.u @ self._loads) + float(self._reaction @ self._prescribed)
        scale = max(abs(internal), abs(external), TINY)
        return EnergyBalance(float(internal), external, float(abs(internal - external) / scale))

    def _flow_scale(self) -> float:
        """A heat flow (W) the model could carry: k A dT / L over the faces with conditions.

        k the largest conductivity on those faces, A their area, dT the span of
        the temperature coefficients, L the size of the faces' bounding box.
        The balance error is relative to the larger of this and the measured
        flows, so a model through which no heat flows does not divide two
        round-off numbers.
        """
        prob = self.problem
        keys = [k for kind in ("neumann", "robin", "radiation", "dirichlet") for k in self._book.get(kind, {})]
        comm = self._comm()
        if comm is not None:  # the faces of this rank's patches; the figures are combined over the ranks
            mine = set(np.flatnonzero(self.record.partition == comm.Get_rank()).tolist())
            keys = [k for k in dict.fromkeys(keys) if k[0] in mine]
        k_ref, area, lo, hi, ok = 0.0, 0.0, np.full(3, np.inf), np.full(3, -np.inf), True
        if keys and len(self.u):
            fds = prob.faces(keys)
            x = np.concatenate([fd.x for fd in fds])
            try:
                k = np.concatenate(prob.field_on(prob.conductivity, fds, "any condition"))
                k_ref = float(np.abs(k).max()) if k.size else 0.0
            except ProblemError:  # a channel that only some faces carry: no scale from the conductivity
                ok = False
            area = float(sum(fd.dAw.sum() for fd in fds))
            lo, hi = x.min(axis=0), x.max(axis=0)
        if comm is not None:
            parts = comm.allgather((k_ref, area, lo, hi, ok))
            k_ref, area, ok = max(p[0] for p in parts), sum(p[1] for p in parts), all(p[4] for p in parts)
            lo, hi = np.min([p[2] for p in parts], axis=0), np.max([p[3] for p in parts], axis=0)
        size = float((hi - lo).max()) if np.all(np.isfinite(lo)) else 0.0
        dT = float(np.ptp(self.u)) if len(self.u) else 0.0
        return k_ref * area * dT / size if ok and size > 0 else 0.0

    # ------------------------------------------------------------ integrals
    def integrate(self, fn) -> float:
        """Sum over the model of int fn(x, T, grad T) dV, by the problem's Gauss rule.

        ``fn(x (N, 3), T (N,), grad (N, 3)) -> (N,)``; patches sharing a tile
        spline and a space are evaluated together (:func:`iga.discretisation.fields.integrate_fields`).
        """
        prob = self.problem
        return integrate_fields(
            prob, lambda i: self.u[prob.offsets[i]:prob.offsets[i + 1]].reshape((1,) + prob.spaces[i].shape), 1,
            lambda x, v, g: fn(x, v[:, 0], g[:, 0]))

    def volume(self) -> float:
        """Volume of the model (m^3), by the problem's Gauss rule (computed once)."""
        if self._volume is None:
            self._volume = self.integrate(lambda x, T, g: np.ones(len(T)))
        return self._volume

    def gradient(self, output, wrt: str = "tiles", solver: str = "auto") -> np.ndarray:
        """The derivative of ``output`` (one of :mod:`iga.outputs`) by the adjoint: ``wrt="tiles"`` or
        ``"patches"`` (a factor on each one's conductivity), ``"channel:NAME"`` (the control values of the
        map's channel the conductivity reads; a tuple of arrays, one per map, on a model of several maps), ``"map"`` (the map's control point coordinates, (n1, n2, n3, 3)),
        ``"parameters"`` (the control values of a field-graded paving's parameter field) or ``"faces"`` (its
        values on the cell walls); :func:`iga.sensitivity.gradient`.  A solution of
        ``solve(keep=True)`` solves the adjoint with its kept factorisation (one back-substitution)."""
        from iga.sensitivity import gradient

        return gradient(self, output, wrt, solver)

    def mean_temperature(self) -> float:
        """Volume average of the temperature: int T dV / int dV (both from one pass over the Gauss points)."""
        if self._volume is not None:  # the integral of T too where the energy identity's pass made it
            t_int = self._temperature_integral
            return (float(t_int) if t_int is not None else self.integrate(lambda x, T, g: T)) / self._volume
        prob = self.problem
        both = integrate_fields(
            prob, lambda i: self.u[prob.offsets[i]:prob.offsets[i + 1]].reshape((1,) + prob.spaces[i].shape), 1,
            lambda x, v, g: np.stack([v[:, 0], np.ones(len(v))], axis=1))
        self._volume = float(both[1])
        return float(both[0]) / self._volume

    def temperature_range(self, samples: int = 3) -> tuple[float, float]:
        """Minimum and maximum of the temperature over a sampling of every patch.

        Every Bezier element of each temperature space is sampled at
        ``samples + 1`` points per direction (its ends included), the grid of
        :func:`iga.write_vtu`.  Patches sharing a space are evaluated together, one direction at a time (sum
        factorisation); at a discontinuity knot the right-hand limit, as :meth:`SplineFunction.evaluate_grid`.
        """
        prob, o = self.problem, self.problem.offsets
        lo, hi = np.inf, -np.inf
        groups: dict = {}
        for pi, space in enumerate(prob.spaces):  # NURBS-basis patches (own weights) one by one
            groups.setdefault(space.key() if prob.weights[pi] is None else ("own", pi), []).append(pi)
        for members in groups.values():
            space = prob.spaces[members[0]]
            axes = sample_axes([d.knots for d in space.dirs], samples)
            if prob.weights[members[0]] is not None:
                v = self._spline(members[0]).evaluate_grid(axes)
                lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
                continue
            tables = [kn.basis_matrix(d.knots, d.degree, np.clip(a, d.knots[0], d.knots[-1]), 0).toarray()
                      for d, a in zip(space.dirs, axes)]
            for chunk in chunks(members, int(np.prod([len(a) for a in axes]))):
                v = grid_contract(np.stack([self.u[o[i]:o[i + 1]].reshape(space.shape) for i in chunk]), *tables)
                lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
        return lo, hi

    def l2_error(self, exact) -> float:
        """|| T - exact ||_L2 over the model; ``exact(x (N, 3)) -> (N,)``."""
        check_reference(exact, "exact")
        return float(np.sqrt(self.integrate(lambda x, T, g: (T - reference_values(exact, x, (), "exact")) ** 2)))

    def h1_error(self, exact_grad) -> float:
        """| T - exact |_H1 (gradient seminorm); ``exact_grad(x) -> (N, 3)``."""
        check_reference(exact_grad, "exact_grad")
        return float(np.sqrt(self.integrate(
            lambda x, T, g: np.sum((g - reference_values(exact_grad, x, (3,), "exact_grad")) ** 2, axis=1))))


def check_reference(fn, what: str) -> None:
    """A user's exact solution or gradient must be a callable of x (N, 3)."""
    if not callable(fn):
        raise ProblemError(f"{what} must be a callable of the points x (N, 3), got a {type(fn).__name__}")


def reference_values(fn, x: np.ndarray, tail: tuple, what: str) -> np.ndarray:
    """``fn(x)`` of a user's exact solution or gradient as an (N,) + ``tail`` float array (a number stands for
    every point), checked as :func:`iga.heat.coefficients.user_values` checks material callables."""
    return user_values(fn, x, tail, what, "the model", constant=True)


def flux_vector(K: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Heat flux -K grad T (N, 3) for conductivity K (N,) or (N, 6) tensor components and gradients (N, 3)."""
    if K.ndim == 1:
        return -K[:, None] * grad
    return -np.einsum("nij,nj->ni", tensor_matrix(K), grad)


def _components_info(record) -> dict:
    """The coupled pieces a solve found for ``Solution.info`` (:mod:`iga.discretisation.components`): the count,
    the idle ones, and the first ten with their DOFs, patches and the tags of the conditions on them."""
    return {"count": len(record.components), "idle": len(record.idle_components),
            "pieces": [c.as_dict() for c in record.components[:10]]}
